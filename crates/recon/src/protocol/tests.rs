//! The protocols' choice of pairs on a hand-made drive past two cars, and what leaving pixels
//! out does to the loss.

use super::*;
use crate::loss::{view_loss, ChannelGrads, LossWeights, Rendered};
use glam::DVec3;
use scene::{Ego, EgoSizeSource, Frame, Source, SourceKind, Track, TrackState, Transform3};

/// A camera at world `(x, 0, 1.5)` looking along +x (OpenCV axes: x right = world -y).
fn view_at(frame: usize, x: f64, held_out: bool) -> View {
    let cam = splat::Camera {
        width: 480,
        height: 270,
        fx: 500.0,
        fy: 500.0,
        cx: 240.0,
        cy: 135.0,
        camera_from_world: [[0.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 1.5], [1.0, 0.0, 0.0, -x], [0.0, 0.0, 0.0, 1.0]],
        near: 0.01,
        far: 1e4,
    };
    View {
        frame,
        camera: "C".into(),
        time: frame as f64,
        image_time: frame as f64,
        cam,
        targets: Targets::default(),
        held_out,
    }
}

fn car(id: &str, centre: DVec3, heading: f64, frames: usize) -> Track {
    let state = |frame| TrackState {
        frame,
        center: centre,
        heading,
        size_lwh: [4.5, 1.8, 1.5],
        velocity: None,
        valid: true,
        motion: None,
    };
    Track { id: id.into(), class: ObjectClass::Vehicle, states: (0..frames).map(state).collect() }
}

/// The ego drives from x = 0 to x = 36 along +x in 10 frames; a car parked at x = 40 just left of
/// the lane (seen far, then near, end-on throughout), another at x = 30 across the road (seen from
/// the side), and a bus at x = 200 (never near).
fn scene(frames: usize) -> Scene {
    let frame = |i: usize| Frame {
        index: i,
        timestamp_s: i as f64,
        world_from_ego: Transform3::from_yaw_translation(0.0, DVec3::ZERO),
        images: vec![],
        lidar: None,
    };
    Scene {
        format: scene::SCENE_FORMAT.into(),
        name: "t".into(),
        source: Source { kind: SourceKind::Synthetic, files: vec![], id: "t".into() },
        ego: Ego { size_lwh: [4.5, 2.0, 1.8], size_source: EgoSizeSource::Default, track_id: None },
        // The stored camera the views are scaled from (only its size is read here).
        cameras: vec![scene::Camera {
            name: "C".into(),
            width: 480,
            height: 270,
            intrinsics: scene::Intrinsics { fx: 500.0, fy: 500.0, cx: 240.0, cy: 135.0 },
            distortion: Default::default(),
            ego_from_camera: Transform3::IDENTITY,
            rolling_shutter: Default::default(),
        }],
        frames: (0..frames).map(frame).collect(),
        tracks: vec![
            car("ahead", DVec3::new(40.0, 1.0, 0.75), 0.0, frames),
            car("across", DVec3::new(30.0, -1.0, 0.75), std::f64::consts::FRAC_PI_2, frames),
            car("far", DVec3::new(200.0, 0.0, 0.75), 0.0, frames),
        ],
        map: None,
    }
}

#[test]
fn close_up_holds_out_the_near_views_of_cars_also_seen_far() {
    let sc = scene(10);
    let views: Vec<View> = (0..10).map(|i| view_at(i, 4.0 * i as f64, i == 0)).collect();
    let seen = sightings(&sc, &views);
    // Frame 0 is held out: never a sighting.
    assert!(seen.iter().all(|s| s.frame != 0));
    let ahead: Vec<&Sighting> = seen.iter().filter(|s| s.track == "ahead").collect();
    // The camera at x = 36 is 4 m from it; at x = 4, 36 m.
    assert!(ahead.iter().any(|s| s.distance_m < NEAR_M) && ahead.iter().any(|s| s.distance_m > FAR_M));
    assert!(ahead.iter().all(|s| s.angle_deg < END_ON_DEG), "{ahead:?}");
    let p = pairs(Protocol::CloseUp, &seen);
    assert!(!p.is_empty() && p.iter().all(|s| s.distance_m < NEAR_M));
    // The far bus is never near: none of its views are held.
    assert!(p.iter().all(|s| s.track != "far"));
    // Turned: the car across the road is seen from the side; is it ever end-on? Never (it is
    // crosswise to every ray ahead), so it does not qualify, and "ahead" is never seen side-on.
    let across: Vec<&Sighting> = seen.iter().filter(|s| s.track == "across").collect();
    assert!(across.iter().any(|s| s.angle_deg > SIDE_DEG), "{across:?}");
    assert!(pairs(Protocol::Turned, &seen).iter().all(|s| s.track != "ahead"));
    assert!(pairs(Protocol::None, &seen).is_empty());
}

#[test]
fn the_selection_does_not_depend_on_the_training_scale() {
    let sc = scene(10);
    let full: Vec<View> = (0..10).map(|i| view_at(i, 4.0 * i as f64, false)).collect();
    let quarter: Vec<View> = full
        .iter()
        .map(|v| {
            let mut q = v.clone();
            q.cam.width /= 4;
            q.cam.height = 68;
            q.cam.fx /= 4.0;
            q.cam.fy = q.cam.fy * 68.0 / 270.0;
            q.cam.cx /= 4.0;
            q.cam.cy = q.cam.cy * 68.0 / 270.0;
            q
        })
        .collect();
    let key = |s: &Sighting| (s.frame, s.track.clone());
    let a: Vec<_> = pairs(Protocol::CloseUp, &sightings(&sc, &full)).iter().map(key).collect();
    let b: Vec<_> = pairs(Protocol::CloseUp, &sightings(&sc, &quarter)).iter().map(key).collect();
    assert_eq!(a, b);
}

#[test]
fn apply_empties_every_target_of_the_held_pixels() {
    let sc = scene(10);
    let mut views: Vec<View> = (0..10).map(|i| view_at(i, 4.0 * i as f64, false)).collect();
    let n = 480 * 270;
    for v in &mut views {
        v.targets = Targets {
            rgb: vec![[0.5; 3]; n],
            depth: Some(vec![10.0; n]),
            normal: Some(vec![[0.0, -1.0, 0.0]; n]),
            mask: Some(vec![true; n]),
            geo_weight: Some(vec![1.0; n]),
            ..Default::default()
        };
    }
    let chosen = apply(Protocol::CloseUp, &sc, &mut views);
    assert!(!chosen.is_empty());
    for v in &views {
        let held = chosen.iter().any(|s| s.frame == v.frame);
        assert_eq!(v.targets.keep.is_some(), held, "frame {}", v.frame);
        let Some(keep) = &v.targets.keep else { continue };
        let sk = v.targets.ssim_keep.as_ref().unwrap();
        for i in 0..n {
            if keep[i] == 0.0 {
                assert_eq!(v.targets.depth.as_ref().unwrap()[i], 0.0);
                assert_eq!(v.targets.normal.as_ref().unwrap()[i], [0.0; 3]);
                assert!(!v.targets.mask.as_ref().unwrap()[i]);
                assert_eq!(v.targets.geo_weight.as_ref().unwrap()[i], 0.0);
                assert_eq!(sk[i], 0.0);
            }
        }
        // Every window that reaches a held pixel is out, and only those.
        let (w, h) = (480usize, 270usize);
        for i in (0..n).step_by(7) {
            let (x, y) = (i % w, i / w);
            let reaches = (y.saturating_sub(5)..(y + 6).min(h))
                .any(|yy| (x.saturating_sub(5)..(x + 6).min(w)).any(|xx| keep[yy * w + xx] == 0.0));
            assert_eq!(sk[i] == 0.0, reaches, "pixel {i}");
        }
    }
}

#[test]
fn held_pixels_targets_never_reach_the_loss() {
    let (w, h) = (24usize, 18usize);
    let n = w * h;
    let wave = |i: usize, k: f64| ((i as f64 * 0.731 + k).sin() * 0.5 + 0.5) * 0.9 + 0.05;
    let rgb: Vec<[f64; 3]> = (0..n).map(|i| [wave(i, 0.0), wave(i, 1.0), wave(i, 2.0)]).collect();
    let alpha: Vec<f64> = (0..n).map(|i| wave(i, 3.0)).collect();
    let depth: Vec<f64> = (0..n).map(|i| 5.0 + wave(i, 4.0)).collect();
    let normal: Vec<[f64; 3]> = (0..n).map(|i| [wave(i, 5.0) - 0.5, 0.2, -0.8]).collect();
    let sky: Vec<[f64; 3]> = (0..n).map(|i| [wave(i, 8.0), 0.3, 0.6]).collect();
    let r = Rendered { width: w, height: h, rgb: &rgb, alpha: &alpha, depth: &depth, normal: &normal, sky: &sky };
    let targets = |k: f64| Targets {
        rgb: (0..n).map(|i| [wave(i, 0.5 + k), wave(i, 1.3), wave(i, 2.9 * k)].map(|x| x as f32)).collect(),
        depth: Some((0..n).map(|i| (5.5 + k * wave(i, 7.0)) as f32).collect()),
        normal: Some(vec![[0.0, 0.0, -1.0]; n]),
        mask: Some(vec![true; n]),
        geo_weight: Some(vec![1.0; n]),
        ..Default::default()
    };
    // A block of 6 x 5 pixels held out.
    let held: Vec<bool> = (0..n).map(|i| (8..14).contains(&(i % w)) && (6..11).contains(&(i / w))).collect();
    let run = |k: f64| {
        let mut t = targets(1.0);
        // Other target values only where held.
        let other = targets(k);
        for i in (0..n).filter(|&i| held[i]) {
            t.rgb[i] = other.rgb[i];
            t.depth.as_mut().unwrap()[i] = other.depth.as_ref().unwrap()[i];
        }
        leave_out(&mut t, &held, w, h);
        let mut g = ChannelGrads::default();
        let parts = view_loss(&r, &t, &LossWeights { ssim: 0.2, depth: 0.3, flat: 0.0, normal: 0.5, geo: 0.7 }, &mut g);
        (parts, g)
    };
    let (a, ga) = run(1.0);
    let (b, gb) = run(3.0);
    assert_eq!(a.total.to_bits(), b.total.to_bits());
    assert!(ga.rgb.iter().zip(&gb.rgb).all(|(x, y)| x == y));
    assert!(ga.depth.iter().zip(&gb.depth).all(|(x, y)| x == y));
    // The held pixels get no photometric gradient (no window centred near them counts), while
    // pixels outside still train.
    assert!(ga.rgb.iter().zip(&held).filter(|(_, h)| **h).all(|(g, _)| g.iter().all(|v| *v == 0.0)));
    assert!(ga.rgb.iter().zip(&held).filter(|(_, h)| !**h).any(|(g, _)| g.iter().any(|v| *v != 0.0)));
}
