//! Map-aware plans end to end on a synthetic curved two-lane road (no shared data needed): the
//! planner's cut-in follows the lanes, stays between the road edges (planned, and through the
//! simulator's `left_road` check) and ends on the target lane's centreline; the same request
//! without lanes on the map (the straight-line quintic of before) plans the adversary's box over
//! the road edge: it arrives at its target (where it stops) moving sideways, 20-odd degrees off
//! the lane.
//!
//! (On a street corner, straight then a 90 degree turn, the old quintic cuts the corner off the
//! road, but only at timings that a car following the lanes could not make within the planner's
//! acceleration limit: with lanes the planner then answers "no feasible", see docs/reasoning.md.)

use reason::{reason, Agent, Outcome, ReasonOptions};
use scene::glam::{DVec2, DVec3};
use scene::map::{Map, Polyline};
use scene::{
    Behavior, Ego, EgoSizeSource, Frame, ObjectClass, Plan, PlanPath, Scene, Source, SourceKind, Track, TrackState,
    Transform3, Zone,
};

/// A left-hand curve about the origin (counter-clockwise travel): lane centres at radii 28.2 m
/// (the left lane, the ego's) and 31.8 m (the right lane, the adversary's), road edges at 26.4 m
/// and 33.6 m.
const R_EGO: f64 = 28.2;
const R_ADV: f64 = 31.8;
const R_IN_EDGE: f64 = 26.4;
const R_OUT_EDGE: f64 = 33.6;
/// The ego creeps at 3 m/s; the adversary passes it at 9 m/s, alongside at t0 = 1 s.
const EGO_SPEED: f64 = 3.0;
const ADV_SPEED: f64 = 9.0;

/// Points every 0.5 m on the circle of radius `r` from angle -0.5 to 2.2 rad.
fn arc(r: f64) -> Vec<DVec2> {
    let (a0, a1) = (-0.5, 2.2);
    let n = ((a1 - a0) * r / 0.5).ceil() as usize;
    (0..=n).map(|k| a0 + (a1 - a0) * k as f64 / n as f64).map(|a| DVec2::new(r * a.cos(), r * a.sin())).collect()
}

/// Pose on the circle of radius `r` at arc length `s` from angle -0.3 rad (heading along travel).
fn on_circle(r: f64, s: f64) -> (DVec2, f64) {
    let a = -0.3 + s / r;
    (DVec2::new(r * a.cos(), r * a.sin()), a + std::f64::consts::FRAC_PI_2)
}

fn polyline(id: i64, pts: &[DVec2]) -> Polyline {
    Polyline { id, points: pts.iter().map(|p| DVec3::new(p.x, p.y, 0.0)).collect() }
}

fn curved_road(with_lanes: bool) -> Scene {
    let n = 71; // 7 s at 10 Hz
    let frames: Vec<Frame> = (0..n)
        .map(|i| {
            let (p, h) = on_circle(R_EGO, EGO_SPEED * i as f64 * 0.1);
            Frame {
                index: i,
                timestamp_s: i as f64 * 0.1,
                world_from_ego: Transform3::from_yaw_translation(h, DVec3::new(p.x, p.y, 0.0)),
                images: vec![],
                lidar: None,
            }
        })
        .collect();
    // Alongside at t0: the same angle as the ego.
    let s_at_t0 = EGO_SPEED * 1.0 / R_EGO * R_ADV;
    let states = (0..n)
        .map(|i| {
            let (p, h) = on_circle(R_ADV, s_at_t0 + ADV_SPEED * (i as f64 * 0.1 - 1.0));
            TrackState {
                frame: i,
                center: DVec3::new(p.x, p.y, 0.8),
                heading: h,
                size_lwh: [4.5, 2.0, 1.6],
                velocity: None,
                valid: true,
                motion: None,
            }
        })
        .collect();
    // Lanes in pieces of 20 points (10 m), each starting where the last ends (as in WOMD).
    let mut lanes = Vec::new();
    for (base, pts) in [(100, arc(R_EGO)), (200, arc(R_ADV))] {
        for (k, start) in (0..pts.len() - 1).step_by(20).enumerate() {
            lanes.push(polyline(base + k as i64, &pts[start..(start + 21).min(pts.len())]));
        }
    }
    let map = Map {
        lanes: if with_lanes { lanes } else { vec![] },
        road_edges: vec![polyline(1, &arc(R_IN_EDGE)), polyline(2, &arc(R_OUT_EDGE))],
        road_lines: vec![],
    };
    Scene {
        format: scene::SCENE_FORMAT.into(),
        name: "curved_two_lane".into(),
        source: Source { kind: SourceKind::Synthetic, files: vec![], id: "curve".into() },
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
/// edges over the waypoints, and when (negative: a corner is off the road).
fn edge_margin(plan: &Plan) -> (f64, f64) {
    let w = &plan.waypoints;
    (0..w.len())
        .map(|k| {
            let (a, b) = if k + 1 < w.len() { (k, k + 1) } else { (k - 1, k) };
            let h = DVec2::new(w[b].x - w[a].x, w[b].y - w[a].y).normalize();
            let c = DVec2::new(w[k].x, w[k].y);
            let corners =
                [(2.25, 1.0), (2.25, -1.0), (-2.25, 1.0), (-2.25, -1.0)].map(|(f, l)| c + h * f + h.perp() * l);
            let m = corners
                .iter()
                .map(|p| (p.length() - R_IN_EDGE).min(R_OUT_EDGE - p.length()))
                .fold(f64::INFINITY, f64::min);
            (m, w[k].t)
        })
        .fold((f64::INFINITY, f64::NAN), |a, b| if b.0 < a.0 { b } else { a })
}

fn reasons(scene: &Scene, plan: &Plan) -> Vec<&'static str> {
    let e = sim::simulate(scene, plan, &sim::RolloutConfig::default()).expect("simulates");
    assert!(e.validity.road_checked);
    e.validity.reasons.iter().map(|r| r.key()).collect()
}

#[test]
fn cut_in_on_a_curve_follows_the_lanes_and_stays_on_the_road() {
    let lanes = curved_road(true);
    let plan = cut_in(&lanes);
    assert_eq!(plan.path, Some(PlanPath::LaneFollowing), "{}", plan.reasoning);
    assert!((plan.ttc_s - 4.0).abs() < 1e-9);
    let last = plan.waypoints.last().unwrap();
    let end_offset = DVec2::new(last.x, last.y).length() - R_EGO;
    assert!(end_offset.abs() < 0.3, "ends {end_offset:.2} m off the ego lane's centreline");
    let (margin, t) = edge_margin(&plan);
    assert!(margin > 0.2, "the lane plan's box comes within {margin:.2} m of an edge at {t:.1} s");
    let keys = reasons(&lanes, &plan);
    assert!(!keys.contains(&"left_road"), "{keys:?}");

    // Without lanes: the straight-line quintic to a target in the same zone.
    let plain = curved_road(false);
    let straight = cut_in(&plain);
    assert_eq!(straight.path, Some(PlanPath::StraightLine));
    let (margin, t) = edge_margin(&straight);
    assert!(margin < 0.0, "the straight plan's box stays {margin:.2} m inside the edges (closest at {t:.1} s)");
}
