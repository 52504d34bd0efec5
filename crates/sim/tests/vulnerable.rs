//! Pedestrians and cyclists execute by their own models (`sim::vru`), not a car's: a pedestrian
//! stepping out tracks its plan within walking/running limits, one asked to sprint at 8 m/s
//! cannot (it stays at its top speed and the rollout is flagged), and a cyclist's swerve stays
//! within a cyclist's speed, braking and lateral-acceleration limits. Limits are measured here
//! on the executed positions by finite differences.

use scene::glam::{DVec2, DVec3};
use scene::mobility::{CYCLIST, PEDESTRIAN};
use scene::plan::PLAN_FORMAT;
use scene::{
    Behavior, Ego, EgoSizeSource, Executed, Frame, ObjectClass, Plan, Risk, Scene, Source, SourceKind, Track,
    TrackState, Transform3, Waypoint, Zone, ZoneLayout,
};
use sim::{simulate, RolloutConfig};

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

/// 8 s at 10 Hz: the ego drives along +x at 8 m/s; pedestrian `ped` stands at (40, -6) facing
/// the road; cyclist `bike` rides at 5 m/s along y = -3 from x = 15.
fn street() -> Scene {
    let frames = (0..80)
        .map(|i| Frame {
            index: i,
            timestamp_s: i as f64 * 0.1,
            world_from_ego: Transform3::from_yaw_translation(0.0, DVec3::new(8.0 * i as f64 * 0.1, 0.0, 0.0)),
            images: vec![],
            lidar: None,
        })
        .collect();
    Scene {
        format: "test".into(),
        name: "street".into(),
        source: Source { kind: SourceKind::Synthetic, files: vec![], id: "t".into() },
        ego: Ego { size_lwh: [4.5, 2.0, 1.6], size_source: EgoSizeSource::Default, track_id: None },
        cameras: vec![],
        frames,
        tracks: vec![
            track("ped", ObjectClass::Pedestrian, [0.6, 0.6, 1.7], std::f64::consts::FRAC_PI_2, |_| {
                DVec2::new(40.0, -6.0)
            }),
            track("bike", ObjectClass::Cyclist, [1.8, 0.6, 1.7], 0.0, |t| DVec2::new(15.0 + 5.0 * t, -3.0)),
        ],
        map: None,
    }
}

/// Minimum-jerk 0 -> 1.
fn min_jerk(u: f64) -> f64 {
    let u = u.clamp(0.0, 1.0);
    u * u * u * (10.0 - 15.0 * u + 6.0 * u * u)
}

fn plan(adversary: &str, behavior: Behavior, ttc: f64, at: impl Fn(f64) -> DVec2) -> Plan {
    let t0 = 1.0;
    let n = (ttc / 0.1).round() as usize;
    let waypoints: Vec<Waypoint> = (0..=n)
        .map(|k| {
            let s = k as f64 * 0.1;
            let p = at(s);
            Waypoint { t: t0 + s, x: p.x, y: p.y }
        })
        .collect();
    let end = waypoints.last().unwrap();
    Plan {
        format: PLAN_FORMAT.into(),
        scene: "street".into(),
        behavior,
        adversary_track: adversary.into(),
        target_zone: Zone::Front,
        zone_layout: ZoneLayout::Adjacent,
        start_time_s: t0,
        ttc_s: ttc,
        risk: Risk::High,
        agent: "test".into(),
        reasoning: String::new(),
        dt_s: 0.1,
        target: Some([end.x, end.y]),
        seed: None,
        path: None,
        inserted: None,
        waypoints,
    }
}

/// Executed speeds and accelerations from positions at the control period.
fn kinematics(e: &Executed) -> (Vec<DVec2>, Vec<(DVec2, DVec2)>) {
    let dt = e.control_dt_s;
    let p: Vec<DVec2> = e.steps.iter().map(|s| DVec2::new(s.x, s.y)).collect();
    let v: Vec<DVec2> = p.windows(2).map(|w| (w[1] - w[0]) / dt).collect();
    let a = v.windows(2).map(|w| ((w[1] - w[0]) / dt, (w[0] + w[1]) / 2.0)).collect();
    (v, a)
}

#[test]
fn a_pedestrian_steps_out_within_its_limits() {
    let s = street();
    // 3.5 m onto the road in 3 s: peak 2.2 m/s and 2.2 m/s^2.
    let p = plan("ped", Behavior::StepOut, 3.0, |t| DVec2::new(40.0, -6.0 + 3.5 * min_jerk(t / 3.0)));
    let e = simulate(&s, &p, &RolloutConfig::default()).unwrap();
    assert!(e.backend.contains("pedestrian point mass"), "{}", e.backend);
    let (v, a) = kinematics(&e);
    let top = v.iter().map(|x| x.length()).fold(0.0, f64::max);
    let acc = a.iter().map(|(x, _)| x.length()).fold(0.0, f64::max);
    assert!(top <= PEDESTRIAN.max_speed + 1e-6 && acc <= PEDESTRIAN.max_accel + 1e-6, "{top} m/s, {acc} m/s^2");
    assert!(e.validity.valid && e.validity.max_tracking_error_m < 0.3, "{:?}", e.validity);
    let last = e.steps.last().unwrap();
    assert!(DVec2::new(last.x, last.y).distance(DVec2::new(40.0, -2.5)) < 0.3, "ends at ({}, {})", last.x, last.y);
}

#[test]
fn a_pedestrian_cannot_sprint_like_a_car() {
    let s = street();
    // 24 m in 3 s (8 m/s on average): no pedestrian can; it runs at its top speed and falls behind.
    let p = plan("ped", Behavior::StepOut, 3.0, |t| DVec2::new(40.0, -6.0 + 24.0 * min_jerk(t / 3.0)));
    let e = simulate(&s, &p, &RolloutConfig::default()).unwrap();
    let (v, _) = kinematics(&e);
    let top = v.iter().map(|x| x.length()).fold(0.0, f64::max);
    assert!(top <= PEDESTRIAN.max_speed + 1e-6 && top > PEDESTRIAN.max_speed - 0.1, "top speed {top}");
    assert!(!e.validity.valid, "a plan it cannot follow must be flagged: {:?}", e.validity);
    assert_eq!(e.validity.reasons[0].key(), "tracking_diverged");
}

#[test]
fn a_cyclist_swerves_within_a_cyclists_limits() {
    let s = street();
    // Keeps 5 m/s and swerves 3 m left into the ego's lane over 3 s.
    let p = plan("bike", Behavior::SuddenCutIn, 3.0, |t| DVec2::new(20.0 + 5.0 * t, -3.0 + 3.0 * min_jerk(t / 3.0)));
    let e = simulate(&s, &p, &RolloutConfig::default()).unwrap();
    assert!(e.backend.contains("cyclist kinematic single track"), "{}", e.backend);
    let (v, a) = kinematics(&e);
    assert!(v.iter().all(|x| x.length() <= CYCLIST.max_speed + 1e-6));
    for (acc, vel) in a.iter().filter(|(_, vel)| vel.length() > 0.5) {
        let dir = vel.normalize();
        let (along, across) = (acc.dot(dir), acc.perp_dot(dir).abs());
        assert!(along <= CYCLIST.max_accel + 0.05 && -along <= CYCLIST.max_decel + 0.05, "along {along}");
        assert!(across <= CYCLIST.max_lat_accel + 0.05, "lateral {across}");
    }
    // It rides along its heading (no sideways slide) and ends in the ego's lane.
    for st in e.steps.iter().skip(1) {
        assert!(st.speed >= 0.0);
    }
    let last = e.steps.last().unwrap();
    assert!(last.y > -0.5 && e.validity.max_tracking_error_m < 0.5, "ends at y {}: {:?}", last.y, e.validity);
}

/// Fuzzing: an adversary whose logged box no reader of the executed format accepts (0 m, or a
/// scene ego of 1e6 m) is refused before the rollout instead of writing a file that cannot be
/// read back.
#[test]
fn boxes_the_executed_format_refuses_are_refused_before_the_rollout() {
    let p = plan("ped", Behavior::StepOut, 3.0, |t| DVec2::new(40.0, -6.0 + 3.5 * min_jerk(t / 3.0)));
    let mut s = street();
    for st in &mut s.tracks[0].states {
        st.size_lwh = [0.0, 0.0, 0.0];
    }
    let e = simulate(&s, &p, &RolloutConfig::default()).unwrap_err().to_string();
    assert!(e.contains("`adversary_track`") && e.contains("from 0.05 to 60 m"), "{e}");
    let mut s = street();
    s.ego.size_lwh = [1e6, 2.0, 1.6];
    let e = simulate(&s, &p, &RolloutConfig::default()).unwrap_err().to_string();
    assert!(e.contains("ego.size_lwh") && e.contains("from 0.05 to 60 m"), "{e}");
}
