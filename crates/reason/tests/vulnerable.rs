//! Pedestrians and cyclists as adversaries: a pedestrian's `step_out` and a cyclist's swerve
//! (`sudden_cut_in`) stay within their class's limits (measured here by finite differences,
//! independently of the planner's own check) and reach the zone at the TTC; a behaviour the class
//! cannot perform is refused naming the constraint; on the shared WOMD scenes every pedestrian and
//! cyclist asked for is planned or refused with a reason.

use reason::{reason, Agent, Outcome, ReasonOptions};
use scene::glam::{DVec2, DVec3};
use scene::mobility::{CYCLIST, PEDESTRIAN};
use scene::zones::zone_rect;
use scene::{
    Behavior, Ego, EgoSizeSource, Frame, ObjectClass, Plan, Scene, Source, SourceKind, Track, TrackState, Transform3,
    Zone, ZoneLayout,
};

const EGO_SPEED: f64 = 8.0;

fn track(id: &str, class: ObjectClass, size: [f64; 3], heading: f64, at: impl Fn(f64) -> DVec2) -> Track {
    let states = (0..80)
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
    Track { id: id.into(), class, states }
}

/// 8 s at 10 Hz: the ego drives along +x at 8 m/s from x = 0; pedestrian `ped` stands on the
/// right kerb at (40, -6) facing the road; cyclist `bike` rides at 5 m/s along y = -3 from
/// x = 15; car `car` drives 20 m ahead of the ego in its lane.
fn street() -> Scene {
    let frames = (0..80)
        .map(|i| Frame {
            index: i,
            timestamp_s: i as f64 * 0.1,
            world_from_ego: Transform3::from_yaw_translation(0.0, DVec3::new(EGO_SPEED * i as f64 * 0.1, 0.0, 0.0)),
            images: vec![],
            lidar: None,
        })
        .collect();
    let h = std::f64::consts::FRAC_PI_2;
    Scene {
        format: "test".into(),
        name: "street".into(),
        source: Source { kind: SourceKind::Synthetic, files: vec![], id: "t".into() },
        ego: Ego { size_lwh: [4.5, 2.0, 1.6], size_source: EgoSizeSource::Default, track_id: None },
        cameras: vec![],
        frames,
        tracks: vec![
            track("ped", ObjectClass::Pedestrian, [0.6, 0.6, 1.7], h, |_| DVec2::new(40.0, -6.0)),
            track("bike", ObjectClass::Cyclist, [1.8, 0.6, 1.7], 0.0, |t| DVec2::new(15.0 + 5.0 * t, -3.0)),
            track("car", ObjectClass::Vehicle, [4.5, 2.0, 1.5], 0.0, |t| DVec2::new(20.0 + EGO_SPEED * t, 0.0)),
        ],
        map: None,
    }
}

fn options(b: Behavior, adversary: &str) -> ReasonOptions {
    ReasonOptions { t0: 1.0, behavior: Some(b), adversary: Some(adversary.into()), seed: 3, ..Default::default() }
}

fn plan(s: &Scene, o: &ReasonOptions) -> Plan {
    match reason(s, o, Agent::Planner).unwrap() {
        Outcome::Plan { plan, .. } => plan,
        other => panic!("expected a plan, got {other:?}"),
    }
}

fn refusal(s: &Scene, o: &ReasonOptions) -> String {
    match reason(s, o, Agent::Planner).unwrap() {
        Outcome::NoFeasible { reason } => reason,
        other => panic!("expected a refusal, got {other:?}"),
    }
}

/// Finite-difference velocities (between waypoints) and accelerations (at interior waypoints).
fn differences(p: &Plan) -> (Vec<DVec2>, Vec<(DVec2, DVec2)>) {
    let pts: Vec<DVec2> = p.waypoints.iter().map(|w| DVec2::new(w.x, w.y)).collect();
    let v: Vec<DVec2> = pts.windows(2).map(|w| (w[1] - w[0]) / p.dt_s).collect();
    let a = v.windows(2).map(|w| ((w[1] - w[0]) / p.dt_s, (w[0] + w[1]) / 2.0)).collect();
    (v, a)
}

/// The plan's last waypoint is at t0 + TTC and inside the target zone of the ego's pose then.
fn reaches_zone_at_ttc(p: &Plan, zone: Zone) {
    let last = p.waypoints.last().unwrap();
    assert!((last.t - (p.start_time_s + p.ttc_s)).abs() < 1e-9, "ends at {} not t0 + TTC", last.t);
    let ego = DVec2::new(EGO_SPEED * last.t, 0.0);
    let rect = zone_rect(zone, ZoneLayout::Adjacent, 4.5, 2.0);
    let local = DVec2::new(last.x, last.y) - ego; // the ego heads along +x
    assert!(rect.contains(local), "ends at {local:?} in the ego frame, outside the {} zone", zone.as_str());
}

#[test]
fn a_pedestrian_steps_out_within_walking_and_running_limits() {
    let s = street();
    let p = plan(&s, &options(Behavior::StepOut, "ped"));
    assert_eq!((p.adversary_track.as_str(), p.behavior, p.target_zone), ("ped", Behavior::StepOut, Zone::Front));
    let (v, a) = differences(&p);
    let top = v.iter().map(|x| x.length()).fold(0.0, f64::max);
    let acc = a.iter().map(|(x, _)| x.length()).fold(0.0, f64::max);
    assert!(top <= PEDESTRIAN.max_speed + 1e-6, "speed {top} m/s");
    assert!(acc <= PEDESTRIAN.max_accel + 1e-6, "acceleration {acc} m/s^2");
    assert!(top > 1.0, "it must actually step out (top speed {top})");
    reaches_zone_at_ttc(&p, Zone::Front);
    // A TTC too short to walk 6 m onto the road is refused, naming the limits.
    let why = refusal(&s, &ReasonOptions { ttc_s: Some(1.5), ..options(Behavior::StepOut, "ped") });
    assert!(why.contains("track ped cannot perform step_out") && why.contains("limits"), "{why}");
}

#[test]
fn a_cyclist_swerves_in_within_a_cyclists_limits() {
    let s = street();
    let p = plan(&s, &options(Behavior::SuddenCutIn, "bike"));
    assert_eq!((p.adversary_track.as_str(), p.target_zone), ("bike", Zone::Front));
    let (v, a) = differences(&p);
    let top = v.iter().map(|x| x.length()).fold(0.0, f64::max);
    assert!(top <= CYCLIST.max_speed + 1e-6, "speed {top} m/s");
    for (acc, vel) in &a {
        let dir = vel.normalize();
        let (along, across) = (acc.dot(dir), acc.perp_dot(dir).abs());
        assert!(along <= CYCLIST.max_accel + 1e-6 && -along <= CYCLIST.max_decel + 1e-6, "along {along} m/s^2");
        assert!(across <= CYCLIST.max_lat_accel + 1e-6, "lateral {across} m/s^2");
    }
    // It really swerves: from 3 m right of the ego's path to its front zone.
    assert!(p.waypoints.last().unwrap().y > -1.5, "{:?}", p.waypoints.last());
    reaches_zone_at_ttc(&p, Zone::Front);
}

#[test]
fn a_behaviour_the_class_cannot_perform_is_refused_naming_the_constraint() {
    let s = street();
    let why = refusal(&s, &options(Behavior::SuddenBraking, "ped"));
    assert_eq!(
        why,
        "track ped cannot perform sudden_braking: it is a pedestrian, and pedestrians can perform step_out only"
    );
    let why = refusal(&s, &options(Behavior::StepOut, "car"));
    assert_eq!(why, "track car cannot perform step_out: it is a vehicle, and only pedestrians can perform step_out");
    let why = refusal(&s, &options(Behavior::RearTailgating, "bike"));
    assert!(why.ends_with("cyclists can perform sudden_cut_in, side_pass, lead_swerve only"), "{why}");
    // With no adversary named, step_out finds the pedestrian and no vehicle.
    let o = ReasonOptions { adversary: None, ..options(Behavior::StepOut, "") };
    assert_eq!(plan(&s, &o).adversary_track, "ped");
    // The paper's rule baseline honours step_out with the nearest positioned pedestrian.
    let Outcome::Plan { plan: rule, .. } = reason(&s, &o, Agent::Rule).unwrap() else { panic!("rule: no plan") };
    assert_eq!(rule.adversary_track, "ped");
}

#[test]
fn shared_womd_pedestrians_and_cyclists_are_planned_or_refused_with_a_reason() {
    let Some(scenes) = ingest::shared::womd_scenes() else { return };
    for s in &scenes {
        let t0 = s.frames[0].timestamp_s + 1.0;
        let mut seen = 0;
        for t in s.tracks.iter().filter(|t| t.class.is_vulnerable()) {
            let b = if t.class == ObjectClass::Pedestrian { Behavior::StepOut } else { Behavior::SuddenCutIn };
            let o = ReasonOptions { t0, ..options(b, &t.id) };
            match reason(s, &o, Agent::Planner).unwrap() {
                Outcome::Plan { plan, .. } => {
                    let l = t.class.motion_limits().unwrap();
                    let (v, _) = differences(&plan);
                    assert!(v.iter().all(|x| x.length() <= l.max_speed + 1e-6), "{} {}", s.name, t.id);
                    println!(
                        "{} {} {}: plan, {} zone, TTC {:.1} s",
                        s.name,
                        t.class.as_str(),
                        t.id,
                        plan.target_zone.as_str(),
                        plan.ttc_s
                    );
                }
                Outcome::NoFeasible { reason } => {
                    assert!(reason.starts_with(&format!("track {} cannot perform {}: ", t.id, b.as_str())), "{reason}");
                    println!("{} {} {}: {reason}", s.name, t.class.as_str(), t.id);
                }
                Outcome::Rejected { .. } => unreachable!("the planner is not an LLM"),
            }
            seen += 1;
        }
        println!("{}: {seen} pedestrians and cyclists asked for", s.name);
    }
}

#[test]
fn an_llms_waypoints_for_a_pedestrian_are_held_to_a_pedestrians_limits() {
    use reason::reply::WaypointReply;
    use reason::validate::{parse_risk, validate_trajectory, TrajFrame, ZoneDecision};
    let s = street();
    let world = reason::world::World::new(&s, 1.0, 60.0).unwrap();
    let d = ZoneDecision {
        vehicle_id: "ped".into(),
        zone: Zone::Front,
        behavior: Behavior::StepOut,
        ttc_s: 2.0,
        risk: parse_risk("high").unwrap(),
        analysis: String::new(),
        reasoning: String::new(),
    };
    // Straight from (40, -6) to (40, 6) in 2 s at a constant 6 m/s: fine for a car, not on foot.
    let reply: Vec<WaypointReply> =
        (0..=20).map(|k| WaypointReply { t: 1.0 + k as f64 * 0.1, x: 40.0, y: -6.0 + 0.6 * k as f64 }).collect();
    let target = DVec2::new(40.0, 6.0);
    let why = validate_trajectory(&world, &d, target, &reply, 0.1, TrajFrame::World).unwrap_err();
    let text: Vec<String> = why.iter().map(|v| v.to_string()).collect();
    assert!(text.iter().any(|t| t.contains("speed reaches 6.0 m/s (a pedestrian at most 3.5)")), "{text:?}");
    // The same path in 4 s at 3 m/s passes.
    let slow: Vec<WaypointReply> =
        (0..=40).map(|k| WaypointReply { t: 1.0 + k as f64 * 0.1, x: 40.0, y: -6.0 + 0.3 * k as f64 }).collect();
    let d4 = ZoneDecision { ttc_s: 4.0, ..d };
    assert!(validate_trajectory(&world, &d4, target, &slow, 0.1, TrajFrame::World).is_ok());
}
