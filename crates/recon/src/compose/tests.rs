//! Composition and its gradient scatter: the scatter is the exact adjoint of the composition
//! (checked by finite differences of a linear functional of the world parameters).

use super::scatter::zero_rows;
use super::*;
use crate::model::{zeros_like, Actor, SceneModel};
use crate::sky::Sky;
use glam::DVec3;
use scene::{Ego, EgoSizeSource, Frame, ObjectClass, Source, SourceKind, Track, TrackState, Transform3};
use splat::backward::Gradients;

fn scene() -> Scene {
    let frames = (0..2)
        .map(|i| Frame {
            index: i,
            timestamp_s: i as f64,
            world_from_ego: Transform3::from_yaw_translation(0.0, DVec3::ZERO),
            images: vec![],
            lidar: None,
        })
        .collect();
    let state = |frame: usize, x: f64| TrackState {
        frame,
        center: DVec3::new(x, 2.0, 0.7),
        heading: 0.9 + frame as f64 * 0.2,
        size_lwh: [4.0, 2.0, 1.5],
        velocity: None,
        valid: true,
        motion: None,
    };
    Scene {
        format: scene::SCENE_FORMAT.into(),
        name: "t".into(),
        source: Source { kind: SourceKind::Synthetic, files: vec![], id: "t".into() },
        ego: Ego { size_lwh: [4.5, 2.0, 1.8], size_source: EgoSizeSource::Default, track_id: None },
        cameras: vec![],
        frames,
        tracks: vec![Track {
            id: "car".into(),
            class: ObjectClass::Vehicle,
            states: vec![state(0, 5.0), state(1, 7.0)],
        }],
        map: None,
    }
}

fn model() -> SceneModel {
    let cam = splat::Camera::at_origin(16, 16, 16.0);
    SceneModel {
        antialiased: false,
        background: splat::random::random_gaussians(3, &cam, 2, 1),
        actors: vec![Actor {
            track_id: "car".into(),
            size_lwh: [4.0, 2.0, 1.5],
            gaussians: splat::random::random_gaussians(4, &cam, 2, 2),
        }],
        sky: Sky::new(2, [0.5; 3]),
    }
}

fn functional(c: &Composed, gw: &Gradients) -> f64 {
    let w = &c.world;
    let mut s = 0.0;
    for i in 0..w.len() {
        for a in 0..3 {
            s += gw.means[i][a] * w.means[i][a] + gw.log_scales[i][a] * w.log_scales[i][a];
        }
        for a in 0..4 {
            s += gw.rotations[i][a] * w.rotations[i][a];
        }
        s += gw.opacity_logits[i] * w.opacity_logits[i];
    }
    s + gw.sh.iter().zip(&w.sh).map(|(a, b)| a * b).sum::<f64>()
}

/// Deterministic pseudo-random world gradients for every row of `c` (seeded by `x`).
fn world_gradients(c: &Composed, mut x: f64) -> Gradients {
    let mut gw = Gradients::default();
    gw.reset(&c.world, 0);
    let mut next = || {
        x = (x * 7.3 + 0.31) % 1.0;
        x - 0.5
    };
    gw.means.iter_mut().flatten().for_each(|v| *v = next());
    gw.log_scales.iter_mut().flatten().for_each(|v| *v = next());
    gw.rotations.iter_mut().flatten().for_each(|v| *v = next());
    gw.opacity_logits.iter_mut().for_each(|v| *v = next());
    gw.sh.iter_mut().for_each(|v| *v = next());
    gw
}

#[test]
fn scatter_is_the_adjoint_of_compose() {
    let (sc, mut m) = (scene(), model());
    let none = |_: usize| None;
    for degree in [1, 2] {
        let mut c = Composed::default();
        compose_into(&m, &sc, 0.5, degree, Layers::All, &none, &mut c);
        assert_eq!(c.world.len(), 7);
        let gw = world_gradients(&c, 0.1);
        let mut grads: Vec<_> = m.sets().map(zeros_like).collect();
        scatter_gradients(&c, &gw, &mut grads);
        let base = functional(&c, &gw);
        let h = 1e-6;
        let ag = &grads[1];
        let mut check = |analytic: f64, edit: &dyn Fn(&mut SceneModel, f64)| {
            edit(&mut m, h);
            let mut c2 = Composed::default();
            compose_into(&m, &sc, 0.5, degree, Layers::All, &none, &mut c2);
            edit(&mut m, -h);
            let fd = (functional(&c2, &gw) - base) / h;
            assert!((fd - analytic).abs() < 1e-5, "fd {fd} analytic {analytic}");
        };
        for i in 0..4 {
            for a in 0..3 {
                check(ag.means[i][a], &|m, d| m.actors[0].gaussians.means[i][a] += d);
            }
            for a in 0..4 {
                check(ag.rotations[i][a], &|m, d| m.actors[0].gaussians.rotations[i][a] += d);
            }
            for j in 0..27 {
                check(ag.sh[i * 27 + j], &|m, d| m.actors[0].gaussians.sh[i * 27 + j] += d);
            }
        }
        // Background passes straight through.
        assert_eq!(grads[0].means[1], gw.means[1]);
    }
}

#[test]
fn actors_outside_their_lifespan_are_not_drawn_unless_posed() {
    let (sc, m) = (scene(), model());
    let mut c = Composed::default();
    compose_into(&m, &sc, 5.0, 0, Layers::All, &|_| None, &mut c);
    assert_eq!(c.world.len(), 3);
    let posed = |_: usize| Some(Some(BoxPose { center: [50.0, 0.0, 0.0], heading: 0.0 }));
    compose_into(&m, &sc, 5.0, 0, Layers::ActorsOnly, &posed, &mut c);
    assert_eq!(c.world.len(), 4);
    assert!((c.world.means[0][0] - 50.0 - m.actors[0].gaussians.means[0][0]).abs() < 1e-12);
}

#[test]
fn scattering_the_drawn_rows_equals_the_dense_scatter() {
    let (sc, m) = (scene(), model());
    let mut c = Composed::default();
    compose_into(&m, &sc, 0.5, 2, Layers::All, &|_: usize| None, &mut c);
    let drawn = [0usize, 2, 3, 6];
    let mut gw = Gradients::default();
    gw.reset(&c.world, 0);
    let k = gw.sh.len() / c.world.len();
    let mut x = 0.2;
    for &wi in &drawn {
        let mut next = || {
            x = (x * 7.3 + 0.31) % 1.0;
            x - 0.5
        };
        gw.means[wi] = [next(), next(), next()];
        gw.log_scales[wi] = [next(), next(), next()];
        gw.rotations[wi] = [next(), next(), next(), next()];
        gw.opacity_logits[wi] = next();
        gw.sh[wi * k..(wi + 1) * k].iter_mut().for_each(|v| *v = next());
    }
    let mut dense: Vec<_> = m.sets().map(zeros_like).collect();
    scatter_gradients(&c, &gw, &mut dense);
    // The sparse path starts from stale rows it zeroes first.
    let mut sparse: Vec<_> = m.sets().map(zeros_like).collect();
    let rows: Vec<(usize, usize)> = drawn.iter().map(|&wi| c.set_row(wi).unwrap()).collect();
    for &(set, i) in &rows {
        sparse[set].means[i] = [9.0; 3];
        let kd = sparse[set].coeffs() * 3;
        sparse[set].sh[i * kd] = 9.0;
    }
    zero_rows(&mut sparse, &rows, 2);
    scatter_rows(&c, &gw, &mut sparse, &drawn);
    assert_eq!(sparse, dense);
    assert!(dense.iter().any(|g| g.means.iter().flatten().any(|v| *v != 0.0)));
    assert_eq!(c.set_row(c.world.len()), None);
}

#[test]
fn scatter_is_the_adjoint_of_compose_through_the_mirror_and_the_filter() {
    let (sc, mut m) = (scene(), model());
    let none = |_: usize| None;
    let f2: Vec<Vec<f64>> = m.sets().map(|g| (0..g.len()).map(|i| 0.01 + 0.005 * i as f64).collect()).collect();
    let mirrored = [true];
    let rp = Reparam { mirrored: &mirrored, smoothing: Some(&f2) };
    let degree = 2;
    let mut c = Composed::default();
    compose_with(&m, &sc, 0.5, degree, Layers::All, &none, &rp, &mut c);
    // Background 3, the actor 4, its mirror image 4.
    assert_eq!((c.world.len(), c.parts.len()), (11, 3));
    assert!(c.parts[2].mirror && c.parts[2].actor == Some(0));
    assert_eq!(c.set_row(9), Some((1, 2)), "a mirrored row belongs to its model row");
    let gw = world_gradients(&c, 0.3);
    let mut grads: Vec<_> = m.sets().map(zeros_like).collect();
    scatter_gradients(&c, &gw, &mut grads);
    let base = functional(&c, &gw);
    let h = 1e-6;
    let check = |m: &mut SceneModel, analytic: f64, edit: &dyn Fn(&mut SceneModel, f64)| {
        edit(m, h);
        let mut c2 = Composed::default();
        compose_with(m, &sc, 0.5, degree, Layers::All, &none, &rp, &mut c2);
        edit(m, -h);
        let fd = (functional(&c2, &gw) - base) / h;
        assert!((fd - analytic).abs() < 1e-5 * (1.0 + fd.abs()), "fd {fd} analytic {analytic}");
    };
    let ag = grads[1].clone();
    for i in 0..4 {
        for a in 0..3 {
            check(&mut m, ag.means[i][a], &|m, d| m.actors[0].gaussians.means[i][a] += d);
            check(&mut m, ag.log_scales[i][a], &|m, d| m.actors[0].gaussians.log_scales[i][a] += d);
        }
        check(&mut m, ag.opacity_logits[i], &|m, d| m.actors[0].gaussians.opacity_logits[i] += d);
        for a in 0..4 {
            check(&mut m, ag.rotations[i][a], &|m, d| m.actors[0].gaussians.rotations[i][a] += d);
        }
        for j in 0..27 {
            check(&mut m, ag.sh[i * 27 + j], &|m, d| m.actors[0].gaussians.sh[i * 27 + j] += d);
        }
    }
    let bg = grads[0].clone();
    for i in 0..3 {
        for a in 0..3 {
            check(&mut m, bg.log_scales[i][a], &|m, d| m.background.log_scales[i][a] += d);
        }
        check(&mut m, bg.opacity_logits[i], &|m, d| m.background.opacity_logits[i] += d);
    }
}

#[test]
fn a_mirrored_actor_looks_like_the_original_from_the_mirrored_camera() {
    // The box frame is the world here (a car at the origin, heading 0). The mirrored camera is
    // `F camera_from_world M` (M = diag(1, -1, 1) the mirror, F = diag(-1, 1, 1) flipping the image
    // so the frame stays right-handed): it sees the mirror image of what the camera sees, its
    // image flipped left-right. So the mirrored Gaussians from the camera equal the originals from
    // the mirrored camera, flipped.
    let cam = splat::Camera {
        width: 40,
        height: 30,
        fx: 30.0,
        fy: 30.0,
        cx: 20.0,
        cy: 15.0,
        // At world (-6, 3, 0.5), looking along +x (OpenCV x = -y_w, y = -z_w).
        camera_from_world: [[0.0, -1.0, 0.0, 3.0], [0.0, 0.0, -1.0, 0.5], [1.0, 0.0, 0.0, 6.0], [0.0, 0.0, 0.0, 1.0]],
        near: 0.01,
        far: 1e4,
    };
    let mirrored_cam = splat::Camera {
        camera_from_world: [[0.0, -1.0, 0.0, -3.0], [0.0, 0.0, -1.0, 0.5], [1.0, 0.0, 0.0, 6.0], [0.0, 0.0, 0.0, 1.0]],
        ..cam
    };
    let g = splat::random::random_gaussians(40, &mirrored_cam, 3, 3);
    let mut mirrored = Gaussians::empty(3);
    let mut sh = vec![0.0; g.coeffs() * 3];
    for i in 0..g.len() {
        let (mean, q) = mirror_row(&g, i, &mut sh);
        mirrored.means.push(mean);
        mirrored.rotations.push(q);
        mirrored.log_scales.push(g.log_scales[i]);
        mirrored.opacity_logits.push(g.opacity_logits[i]);
        mirrored.sh.extend_from_slice(&sh);
    }
    let opts = splat::render::RenderOptions::default();
    let feats = splat::render::Features::default();
    let a = splat::render::render(&mirrored, &cam, &feats, &opts);
    let b = splat::render::render(&g, &mirrored_cam, &feats, &opts);
    let (w, h) = (40usize, 30usize);
    let mut worst: f64 = 0.0;
    let mut lit = 0;
    for y in 0..h {
        for x in 0..w {
            let (p, q) = (a.rgb[y * w + x], b.rgb[y * w + (w - 1 - x)]);
            worst = worst.max((0..3).map(|c| (p[c] - q[c]).abs()).fold(0.0, f64::max));
            lit += usize::from(a.alpha[y * w + x] > 0.1);
        }
    }
    assert!(lit > 20, "the car covers {lit} pixels");
    assert!(worst < 1e-6, "largest difference {worst}");
}
