//! Insertion (`reason::insert`): where the log has nobody positioned for a behaviour, the planner
//! inserts a vehicle on a lane that exists there, clear of every logged road user, and marks the
//! plan; `--insert never` keeps the old answer; a city-sized map is planned on, not refused.

use reason::insert::{placements, InsertMode};
use reason::{reason, Agent, Outcome, ReasonOptions};
use scene::glam::{DVec2, DVec3};
use scene::inserted::Entry;
use scene::map::{Map, Polyline};
use scene::plan::with_inserted;
use scene::{
    Behavior, Ego, EgoSizeSource, Frame, ObjectClass, Scene, Source, SourceKind, Track, TrackState, Transform3,
};

const EGO_SPEED: f64 = 10.0;

fn track(id: &str, size: [f64; 3], heading: f64, at: impl Fn(f64) -> DVec2) -> Track {
    let states = (0..100)
        .map(|i| {
            let p = at(i as f64 * 0.1);
            TrackState {
                frame: i,
                center: DVec3::new(p.x, p.y, 0.8),
                heading,
                size_lwh: size,
                velocity: None,
                valid: true,
                motion: None,
            }
        })
        .collect();
    Track { id: id.into(), class: ObjectClass::Vehicle, states }
}

/// 10 s at 10 Hz: the ego drives along +x at 10 m/s from x = 0 on an empty road, `tracks` as
/// given, no map.
fn road(tracks: Vec<Track>) -> Scene {
    let frames = (0..100)
        .map(|i| Frame {
            index: i,
            timestamp_s: 100.0 + i as f64 * 0.1,
            world_from_ego: Transform3::from_yaw_translation(0.0, DVec3::new(EGO_SPEED * i as f64 * 0.1, 0.0, 0.0)),
            images: vec![],
            lidar: None,
        })
        .collect();
    Scene {
        format: "test".into(),
        name: "road".into(),
        source: Source { kind: SourceKind::Synthetic, files: vec![], id: "t".into() },
        ego: Ego { size_lwh: [4.5, 2.0, 1.6], size_source: EgoSizeSource::Default, track_id: None },
        cameras: vec![],
        frames,
        tracks,
        map: None,
    }
}

fn options(b: Behavior, insert: InsertMode) -> ReasonOptions {
    ReasonOptions { t0: 102.0, behavior: Some(b), insert, seed: 1, ..Default::default() }
}

#[test]
fn an_empty_road_gets_an_inserted_lead_car_that_every_stage_can_put_back() {
    let s = road(vec![]);
    let never = reason(&s, &options(Behavior::SuddenBraking, InsertMode::Never), Agent::Planner).unwrap();
    assert!(matches!(never, Outcome::NoFeasible { .. }), "{never:?}");
    let Outcome::Plan { plan, .. } =
        reason(&s, &options(Behavior::SuddenBraking, InsertMode::Fallback), Agent::Planner).unwrap()
    else {
        panic!("expected an inserted plan")
    };
    let ins = plan.inserted.as_ref().expect("marked inserted");
    assert!(plan.adversary_track.starts_with("inserted-") && plan.agent.contains("inserted"), "{plan:?}");
    assert!(plan.validate().is_ok());
    assert_eq!(ins.entry, Entry::InTraffic);
    assert_eq!(ins.poses.len(), s.frames.len(), "present from the first frame: never pops up");
    // At t0 it is ahead of the ego in its lane, at a headway.
    let k0 = 20;
    let p = ins.poses[k0];
    assert!((p.t - 102.0).abs() < 1e-9 && p.x > 20.0 + 4.5 && p.y.abs() < 0.2, "{p:?}");
    // The scene with it: a track of that id at every frame; a plan file read back means the same.
    let back: scene::Plan = serde_json::from_str(&serde_json::to_string(&plan).unwrap()).unwrap();
    let with = with_inserted(&s, &back).unwrap();
    let t = with.track(&plan.adversary_track).expect("put back");
    assert_eq!(t.states.len(), 100);
    assert!((t.states[k0].center.x - p.x).abs() < 1e-12);
    // A forged plan whose inserted id clashes with a logged track is refused, naming the field.
    let clash = road(vec![track(&plan.adversary_track, [4.5, 2.0, 1.5], 0.0, |_| DVec2::new(500.0, 50.0))]);
    assert_eq!(with_inserted(&clash, &back).unwrap_err().0, "adversary_track");
}

#[test]
fn a_logged_car_in_the_way_moves_the_inserted_one_and_a_logged_candidate_is_kept() {
    // A car parked in the ego's lane 30 m ahead of the ego at t0 for the whole log: the inserted
    // lead car may not overlap it at any frame before t0.
    let parked = track("parked", [4.5, 2.0, 1.5], 0.0, |_| DVec2::new(50.0, 0.0));
    let s = road(vec![parked]);
    let o = options(Behavior::SuddenBraking, InsertMode::Always);
    for p in placements(&s, &o) {
        for (k, pose) in p.inserted.poses.iter().enumerate().take(21) {
            let dx = (pose.x - 50.0).abs();
            assert!(dx > 4.5 + 0.5 || pose.y.abs() > 2.5, "frame {k}: {pose:?} overlaps the parked car");
        }
    }
    // A logged lead car positioned for the behaviour: fallback keeps it (no insertion).
    let lead = track("lead", [4.5, 2.0, 1.5], 0.0, |t| DVec2::new(25.0 + EGO_SPEED * t, 0.0));
    let s = road(vec![lead]);
    if let Outcome::Plan { plan, .. } =
        reason(&s, &options(Behavior::SuddenBraking, InsertMode::Fallback), Agent::Planner).unwrap()
    {
        assert_eq!(plan.adversary_track, "lead");
        assert!(plan.inserted.is_none());
    }
}

#[test]
fn lanes_beside_the_ego_come_from_the_map_or_the_traffic() {
    // No map, no traffic beside the ego: no lane to cut in from.
    let s = road(vec![]);
    assert!(placements(&s, &options(Behavior::SuddenCutIn, InsertMode::Always)).is_empty());
    // Logged traffic drove the lane to the left (y = 3.6) earlier: a lane inferred from it.
    let earlier = track("earlier", [4.5, 2.0, 1.5], 0.0, |t| DVec2::new(-80.0 + 14.0 * t, 3.6));
    let s = road(vec![earlier]);
    let found = placements(&s, &options(Behavior::SuddenCutIn, InsertMode::Always));
    assert!(!found.is_empty() && found.iter().all(|p| (p.inserted.poses[20].y - 3.6).abs() < 0.1), "left lane");
    assert!(found[0].inserted.lane.contains("logged traffic"), "{}", found[0].inserted.lane);
    // A map with a lane heading the ego's way to the right: that lane.
    let mut s = road(vec![]);
    let line =
        |y: f64, x0: f64, x1: f64| (0..=((x1 - x0) as usize)).map(|k| DVec3::new(x0 + k as f64, y, 0.0)).collect();
    s.map = Some(Map {
        lanes: vec![
            Polyline { id: 1, points: line(0.0, -100.0, 400.0) },
            Polyline { id: 2, points: line(-3.6, -100.0, 400.0) },
        ],
        ..Map::default()
    });
    let found = placements(&s, &options(Behavior::SuddenCutIn, InsertMode::Always));
    assert!(!found.is_empty() && found.iter().all(|p| (p.inserted.poses[20].y + 3.6).abs() < 0.1), "right lane");
    assert!(found[0].inserted.lane.contains("map"));
    let Outcome::Plan { plan, .. } =
        reason(&s, &options(Behavior::SuddenCutIn, InsertMode::Fallback), Agent::Planner).unwrap()
    else {
        panic!("a cut-in from the inserted car")
    };
    assert!(plan.inserted.is_some());
}

#[test]
fn the_lane_is_where_the_traffic_drove_and_a_gap_between_cars_is_found() {
    // Logged traffic drove a lane 4.7 m to the left (a wide street: not the 3.6 m grid), going
    // the ego's way: the inserted cut-in car is put in that lane.
    let earlier = track("earlier", [4.5, 2.0, 1.5], 0.0, |t| DVec2::new(-80.0 + 14.0 * t, 4.7));
    let found = placements(&road(vec![earlier]), &options(Behavior::SuddenCutIn, InsertMode::Always));
    assert!(!found.is_empty(), "a lane at 4.7 m");
    assert!(found.iter().all(|p| (p.inserted.poses[20].y - 4.7).abs() < 0.2), "{:?}", found[0].inserted.poses[20]);
    // Two cars following the ego 14 and 26 m behind in its lane (a queue): the tailgater fits
    // only in the gap between them or behind the second, never on either.
    let a = track("a", [4.5, 2.0, 1.5], 0.0, |t| DVec2::new(EGO_SPEED * t - 14.0, 0.0));
    let b = track("b", [4.5, 2.0, 1.5], 0.0, |t| DVec2::new(EGO_SPEED * t - 26.0, 0.0));
    let found = placements(&road(vec![a, b]), &options(Behavior::RearTailgating, InsertMode::Always));
    assert!(!found.is_empty(), "the queue leaves room behind it");
    for p in &found {
        let behind = 20.0 - p.inserted.poses[20].x;
        assert!(
            (behind - 14.0).abs() > 5.5 && (behind - 26.0).abs() > 5.5 && behind > 5.0,
            "{behind} m behind overlaps the queue"
        );
    }
}

/// A city's map (issue 53): a 50 km road boundary and 20,000 short lanes on a 10 km grid, the
/// ego's road among them: planned on, not refused for its size.
#[test]
fn a_city_sized_map_is_planned_on() {
    let mut s = road(vec![track("lead", [4.5, 2.0, 1.5], 0.0, |t| DVec2::new(25.0 + EGO_SPEED * t, 0.0))]);
    let mut lanes = Vec::with_capacity(20_001);
    for k in 0..20_000 {
        // 100 rows of 200 lanes of 40 m, 100 m apart, each 41 points.
        let (row, col) = ((k / 200) as f64, (k % 200) as f64);
        let (x0, y) = (-4000.0 + col * 50.0, -5000.0 + row * 100.0 + 3.6);
        lanes.push(Polyline { id: k, points: (0..=40).map(|i| DVec3::new(x0 + i as f64, y, 0.0)).collect() });
    }
    lanes.push(Polyline {
        id: 99_999,
        points: (0..=2000).map(|i| DVec3::new(-500.0 + i as f64 * 0.5, 0.0, 0.0)).collect(),
    });
    // 50 km of boundary zigzagging around the city, a point every metre.
    let boundary: Vec<DVec3> = (0..=50_000)
        .map(|i| DVec3::new(-5000.0 + (i % 10_000) as f64, -6.0 - (i / 10_000) as f64 * 2000.0, 0.0))
        .collect();
    s.map = Some(Map { lanes, road_edges: vec![Polyline { id: 1, points: boundary }], ..Map::default() });
    let out = reason(&s, &options(Behavior::SuddenBraking, InsertMode::Never), Agent::Planner).unwrap();
    match out {
        Outcome::Plan { plan, .. } => assert_eq!(plan.adversary_track, "lead"),
        other => panic!("{other:?}"),
    }
}

/// The ego waiting (at a light, in a queue) the whole log: its lane is the line along its heading
/// (was: no street at all, so "no lane with room" for every behaviour on the shared WOMD scene
/// whose ego stands still). A car behind it may come up and hit it; nothing ahead can brake into
/// a standing ego.
#[test]
fn a_standing_ego_gets_an_inserted_car_behind_it() {
    let mut s = road(vec![]);
    for f in &mut s.frames {
        f.world_from_ego = Transform3::from_yaw_translation(0.3, DVec3::new(5.0, 2.0, 0.0));
    }
    let o = options(Behavior::RearTailgating, InsertMode::Fallback);
    let all = placements(&s, &o);
    assert!(!all.is_empty(), "a place behind the standing ego");
    for p in &all {
        // Behind it, on the line along its heading (0.3 rad), clear of it.
        let q = p.inserted.poses[20];
        let rel = DVec2::new(q.x - 5.0, q.y - 2.0);
        let (along, across) = (rel.dot(DVec2::from_angle(0.3)), rel.perp_dot(DVec2::from_angle(0.3)));
        assert!(along < -(4.5 + 2.0) / 2.0 && across.abs() < 0.5, "{q:?}");
    }
    match reason(&s, &o, Agent::Planner).unwrap() {
        Outcome::Plan { plan, .. } => assert!(plan.inserted.is_some(), "{plan:?}"),
        other => panic!("expected an inserted plan behind the standing ego: {other:?}"),
    }
}

/// On a bending path a slot far along it ends up off the ego's heading line at t0, where the
/// planner would not take it as positioned: such a slot is never offered (it took one of the
/// few placements kept and then failed as "not positioned").
#[test]
fn every_placement_is_positioned_for_its_behaviour() {
    // The ego turns left on a 25 m radius at 10 m/s.
    let mut s = road(vec![]);
    for f in &mut s.frames {
        let a = (f.timestamp_s - 100.0) * 10.0 / 25.0;
        let p = DVec3::new(25.0 * a.sin(), 25.0 * (1.0 - a.cos()), 0.0);
        f.world_from_ego = Transform3::from_yaw_translation(a, p);
    }
    for b in [Behavior::SuddenBraking, Behavior::RearTailgating, Behavior::SuddenStart, Behavior::SidePass] {
        let o = options(b, InsertMode::Always);
        let world = reason::world::World::new(&s, o.t0, o.radius).unwrap();
        for p in placements(&s, &o) {
            let w = reason::world::World::new(&p.scene, o.t0, o.radius).unwrap();
            let v = w.actors().find(|v| v.id == p.id).expect("the inserted car is an actor");
            let zones = reason::behavior::candidate_zones(&world, v, b);
            assert!(zones.is_ok(), "{}: {} at {:?}: {zones:?}", b.as_str(), p.inserted.lane, v.now.p);
        }
    }
}
