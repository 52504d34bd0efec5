//! Map-aware plans end to end on a synthetic curved two-lane road (no shared data needed): the
//! planner's cut-in follows the lanes, stays between the road edges through the simulator's
//! `left_road` check and ends on the target lane's centreline; the same request without lanes on
//! the map (the straight-line quintic of before) cuts across the inside of the curve and leaves
//! the road.

use reason::{reason, Agent, Outcome, ReasonOptions};
use scene::glam::{DVec2, DVec3};
use scene::map::{Map, Polyline};
use scene::{
    Behavior, Ego, EgoSizeSource, Frame, ObjectClass, Plan, PlanPath, Scene, Source, SourceKind, Track, TrackState,
    Transform3, Zone,
};

/// Left-hand curve about the origin (counter-clockwise travel): lane centres at radii 28.2 m
/// (left lane, the ego's) and 31.8 m (right lane, the adversary's), road edges at 26.4 and 33.6 m.
const R_LEFT: f64 = 28.2;
const R_RIGHT: f64 = 31.8;
const R_IN_EDGE: f64 = 26.4;
const R_OUT_EDGE: f64 = 33.6;
const SPEED: f64 = 10.0;

fn arc(id: i64, r: f64, a0: f64, a1: f64, step: f64) -> Polyline {
    let n = ((a1 - a0) * r / step).ceil() as usize;
    let points = (0..=n)
        .map(|k| a0 + (a1 - a0) * k as f64 / n as f64)
        .map(|a| DVec3::new(r * a.cos(), r * a.sin(), 0.0))
        .collect();
    Polyline { id, points }
}

/// Pose on the circle of radius `r` at arc length `s` from angle -0.3 rad (heading along travel).
fn on_circle(r: f64, s: f64) -> (DVec2, f64) {
    let a = -0.3 + s / r;
    (DVec2::new(r * a.cos(), r * a.sin()), a + std::f64::consts::FRAC_PI_2)
}

fn curved_road(with_lanes: bool) -> Scene {
    let n = 71; // 7 s at 10 Hz
    let frames: Vec<Frame> = (0..n)
        .map(|i| {
            let (p, h) = on_circle(R_LEFT, SPEED * i as f64 * 0.1);
            Frame {
                index: i,
                timestamp_s: i as f64 * 0.1,
                world_from_ego: Transform3::from_yaw_translation(h, DVec3::new(p.x, p.y, 0.0)),
                images: vec![],
                lidar: None,
            }
        })
        .collect();
    // The adversary drives the right lane 8 m ahead of the ego at the ego's speed.
    let states = (0..n)
        .map(|i| {
            let (p, h) = on_circle(R_RIGHT, 8.0 + SPEED * i as f64 * 0.1);
            TrackState {
                frame: i,
                center: DVec3::new(p.x, p.y, 0.8),
                heading: h,
                size_lwh: [4.5, 2.0, 1.6],
                velocity: None,
                valid: true,
            }
        })
        .collect();
    // Lanes in 10 m pieces, like WOMD's short lane polylines; edges as long polylines.
    let mut lanes = Vec::new();
    for (base, r) in [(100, R_LEFT), (200, R_RIGHT)] {
        let pieces = 12;
        let (a0, a1) = (-0.5, 2.2);
        for k in 0..pieces {
            let (b0, b1) = (a0 + (a1 - a0) * k as f64 / pieces as f64, a0 + (a1 - a0) * (k + 1) as f64 / pieces as f64);
            lanes.push(arc(base + k as i64, r, b0, b1, 0.5));
        }
    }
    let map = Map {
        lanes: if with_lanes { lanes } else { vec![] },
        road_edges: vec![arc(1, R_IN_EDGE, -0.5, 2.2, 0.5), arc(2, R_OUT_EDGE, -0.5, 2.2, 0.5)],
        road_lines: vec![],
    };
    Scene {
        format: scene::SCENE_FORMAT.into(),
        name: "curved_two_lane".into(),
        source: Source { kind: SourceKind::Synthetic, files: vec![], id: "curved".into() },
        ego: Ego { size_lwh: [4.5, 2.0, 1.6], size_source: EgoSizeSource::Default, track_id: None },
        cameras: vec![],
        frames,
        tracks: vec![Track { id: "adv".into(), class: ObjectClass::Vehicle, states }],
        map: Some(map),
    }
}

fn cut_in(scene: &Scene) -> Plan {
    let o = ReasonOptions {
        t0: 1.0,
        behavior: Some(Behavior::SuddenCutIn),
        adversary: Some("adv".into()),
        zone: Some(Zone::Front),
        ttc_s: Some(4.0),
        seed: 5,
        ..ReasonOptions::default()
    };
    match reason(scene, &o, Agent::Planner).expect("reason runs") {
        Outcome::Plan { plan, .. } => plan,
        other => panic!("no plan: {other:?}"),
    }
}

/// Smallest margin (m) between the adversary's box (heading along its motion) and the road
/// edges, over the waypoints (negative: the box crosses an edge).
fn edge_margin(plan: &Plan) -> f64 {
    let w = &plan.waypoints;
    (0..w.len())
        .map(|k| {
            let (a, b) = if k + 1 < w.len() { (k, k + 1) } else { (k - 1, k) };
            let h = DVec2::new(w[b].x - w[a].x, w[b].y - w[a].y).normalize();
            let c = DVec2::new(w[k].x, w[k].y);
            let corners =
                [(2.25, 1.0), (2.25, -1.0), (-2.25, 1.0), (-2.25, -1.0)].map(|(f, l)| c + h * f + h.perp() * l);
            corners.iter().map(|p| (p.length() - R_IN_EDGE).min(R_OUT_EDGE - p.length())).fold(f64::INFINITY, f64::min)
        })
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn cut_in_on_a_curve_follows_the_lanes_and_stays_on_the_road() {
    let lanes = curved_road(true);
    let plan = cut_in(&lanes);
    assert_eq!(plan.path, Some(PlanPath::LaneFollowing), "{}", plan.reasoning);
    assert!((plan.ttc_s - 4.0).abs() < 1e-9);
    let last = plan.waypoints.last().unwrap();
    let end = DVec2::new(last.x, last.y);
    assert!((end.length() - R_LEFT).abs() < 0.3, "ends {:.2} m off the ego lane's centreline", end.length() - R_LEFT);
    let margin = edge_margin(&plan);
    assert!(margin > 0.2, "lane plan's box comes within {margin:.2} m of an edge");
    // The simulator's road check agrees.
    let e = sim::simulate(&lanes, &plan, &sim::RolloutConfig::default()).expect("simulates");
    let keys: Vec<&str> = e.validity.reasons.iter().map(|r| r.key()).collect();
    assert!(e.validity.road_checked && !keys.contains(&"left_road"), "{keys:?}");

    // Without lanes: the straight-line quintic to the same kind of target cuts the corner.
    let plain = curved_road(false);
    let straight = cut_in(&plain);
    assert_eq!(straight.path, Some(PlanPath::StraightLine));
    let margin = edge_margin(&straight);
    assert!(margin < 0.0, "straight plan stays {margin:.2} m inside the edges");
    let e = sim::simulate(&plain, &straight, &sim::RolloutConfig::default()).expect("simulates");
    let keys: Vec<&str> = e.validity.reasons.iter().map(|r| r.key()).collect();
    assert!(keys.contains(&"left_road"), "{keys:?}");
}
