//! Composition and its gradient scatter: the scatter is the exact adjoint of the composition
//! (checked by finite differences of a linear functional of the world parameters).

use super::*;
use crate::model::{zeros_like, Actor, SceneModel};
use crate::sky::Sky;
use glam::DVec3;
use scene::{Ego, EgoSizeSource, Frame, ObjectClass, Source, SourceKind, Track, TrackState, Transform3};

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

#[test]
fn scatter_is_the_adjoint_of_compose() {
    let (sc, mut m) = (scene(), model());
    let none = |_: usize| None;
    for degree in [1, 2] {
        let mut c = Composed::default();
        compose_into(&m, &sc, 0.5, degree, Layers::All, &none, &mut c);
        assert_eq!(c.world.len(), 7);
        let mut gw = Gradients::default();
        gw.reset(&c.world, 0);
        let mut x = 0.1;
        let mut next = || {
            x = (x * 7.3 + 0.31) % 1.0;
            x - 0.5
        };
        gw.means.iter_mut().flatten().for_each(|v| *v = next());
        gw.log_scales.iter_mut().flatten().for_each(|v| *v = next());
        gw.rotations.iter_mut().flatten().for_each(|v| *v = next());
        gw.opacity_logits.iter_mut().for_each(|v| *v = next());
        gw.sh.iter_mut().for_each(|v| *v = next());
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
