//! A small synthetic street for the perturbation tests: a straight two-lane road along +x with an
//! oncoming lane and a parking strip, the ego at 10 m/s in lane 0, a lead car, a car in the left
//! lane, a parked car at the right kerb, a pedestrian, and the ego's own track (as WOMD has).

use scene::glam::DVec3;
use scene::model::DEFAULT_EGO_SIZE_LWH;
use scene::{
    Ego, EgoSizeSource, Frame, Map, ObjectClass, Polyline, Scene, Source, SourceKind, Track, TrackState, Transform3,
    SCENE_FORMAT,
};

pub const DT: f64 = 0.1;
pub const FRAMES: usize = 81;

fn line(id: i64, y: f64, x0: f64, x1: f64) -> Polyline {
    let n = 60;
    Polyline { id, points: (0..=n).map(|k| DVec3::new(x0 + (x1 - x0) * k as f64 / n as f64, y, 0.0)).collect() }
}

fn track(id: &str, class: ObjectClass, size: [f64; 3], at: impl Fn(f64) -> (DVec3, f64, DVec3)) -> Track {
    let states = (0..FRAMES)
        .map(|k| {
            let (center, heading, v) = at(k as f64 * DT);
            TrackState { frame: k, center, heading, size_lwh: size, velocity: Some(v), valid: true, motion: None }
        })
        .collect();
    Track { id: id.into(), class, states }
}

pub fn street() -> Scene {
    let ego = |t: f64| (DVec3::new(10.0 * t, 0.0, 0.0), 0.0, DVec3::new(10.0, 0.0, 0.0));
    let frames = (0..FRAMES)
        .map(|k| {
            let (p, h, _) = ego(k as f64 * DT);
            Frame {
                index: k,
                timestamp_s: 100.0 + k as f64 * DT,
                world_from_ego: Transform3::from_yaw_translation(h, p),
                images: vec![],
                lidar: None,
            }
        })
        .collect();
    let car = [4.6, 1.9, 1.6];
    let tracks = vec![
        track("sdc", ObjectClass::Vehicle, DEFAULT_EGO_SIZE_LWH, ego),
        track("lead", ObjectClass::Vehicle, car, |t| {
            (DVec3::new(20.0 + 9.0 * t + 0.2 * t * t, 0.0, 0.0), 0.0, DVec3::new(9.0 + 0.4 * t, 0.0, 0.0))
        }),
        track("left", ObjectClass::Vehicle, car, |t| {
            (DVec3::new(5.0 + 11.0 * t, 3.6, 0.0), 0.0, DVec3::new(11.0, 0.0, 0.0))
        }),
        track("oncoming", ObjectClass::Vehicle, car, |t| {
            (DVec3::new(120.0 - 10.0 * t, 7.2, 0.0), std::f64::consts::PI, DVec3::new(-10.0, 0.0, 0.0))
        }),
        track("kerb", ObjectClass::Vehicle, car, |_| (DVec3::new(40.0, -3.4, 0.0), 0.0, DVec3::ZERO)),
        track("walker", ObjectClass::Pedestrian, [0.6, 0.6, 1.7], |t| {
            (DVec3::new(60.0, -6.0 + 0.5 * t, 0.0), std::f64::consts::FRAC_PI_2, DVec3::new(0.0, 0.5, 0.0))
        }),
    ];
    let map = Map {
        lanes: vec![line(1, 0.0, -20.0, 140.0), line(2, 3.6, -20.0, 140.0), line(3, 7.2, 140.0, -20.0)],
        road_edges: vec![line(10, -4.5, -20.0, 140.0), line(11, 9.0, -20.0, 140.0)],
        road_lines: vec![line(20, 1.8, -20.0, 140.0), line(21, 5.4, -20.0, 140.0)],
    };
    Scene {
        format: SCENE_FORMAT.into(),
        name: "street".into(),
        source: Source { kind: SourceKind::Synthetic, files: vec![], id: "street".into() },
        ego: Ego { size_lwh: DEFAULT_EGO_SIZE_LWH, size_source: EgoSizeSource::Track, track_id: Some("sdc".into()) },
        cameras: vec![],
        frames,
        tracks,
        map: Some(map),
    }
}
