//! The CARLA backend through a real bridge process: the JSON-lines protocol end to end with the
//! bridge's fake server (a kinematic bicycle in CARLA's left-handed frame, so a wrong sign in any
//! frame conversion sends the adversary off its path), contacts from the sensor events and the
//! box test, `import carla` from the installed wheel, the clear error when no server answers
//! (the real client against a closed port), and the deadline on a bridge that never answers.
//! Tests that need Python or the `carla` wheel print `SKIP: ...` and pass without them.

use scene::glam::DVec2;
use scene::plan::PLAN_FORMAT;
use scene::{
    Behavior, Ego, EgoSizeSource, Frame, ObjectClass, Plan, Risk, Scene, Source, SourceKind, Track, TrackState,
    Transform3, Waypoint, Zone, ZoneLayout,
};
use sim::carla::{default_python, CarlaOptions};
use sim::{RolloutConfig, SimError};
use std::process::Command;
use std::time::Instant;

const T_FIRST: f64 = 50.0;
const GROUND: f64 = 5.0;

/// The road runs at 30 degrees from +x, far from the world origin.
fn along(s: f64, lateral: f64) -> DVec2 {
    let u = DVec2::from_angle(30f64.to_radians());
    DVec2::new(1000.0, 500.0) + u * s + u.perp() * lateral
}

fn track(id: &str, frames: &[Frame], s_of_t: impl Fn(f64) -> f64) -> Track {
    let states = frames
        .iter()
        .map(|f| {
            let p = along(s_of_t(f.timestamp_s), 3.5);
            TrackState {
                frame: f.index,
                center: p.extend(GROUND + 0.75),
                heading: 30f64.to_radians(),
                size_lwh: [4.6, 1.9, 1.5],
                velocity: None,
                valid: true,
                motion: None,
            }
        })
        .collect();
    Track { id: id.into(), class: ObjectClass::Vehicle, states }
}

/// The ego drives at 10 m/s; track 7 in the lane to its left at 12 m/s; with `obstacle`, track 9
/// is parked in that lane 80 m on.
fn scene(obstacle: bool) -> Scene {
    let frames: Vec<Frame> = (0..=80)
        .map(|i| {
            let t = T_FIRST + 0.1 * i as f64;
            let p = along(10.0 * (t - T_FIRST), 0.0);
            Frame {
                index: i,
                timestamp_s: t,
                world_from_ego: Transform3::from_yaw_translation(30f64.to_radians(), p.extend(GROUND)),
                images: Vec::new(),
                lidar: None,
            }
        })
        .collect();
    let mut tracks = vec![track("7", &frames, |t| 5.0 + 12.0 * (t - T_FIRST))];
    if obstacle {
        tracks.push(track("9", &frames, |_| 80.0));
    }
    Scene {
        format: scene::SCENE_FORMAT.into(),
        name: "carla-bridge-test".into(),
        source: Source { kind: SourceKind::Synthetic, files: Vec::new(), id: "test".into() },
        ego: Ego { size_lwh: [4.5, 2.0, 1.6], size_source: EgoSizeSource::Default, track_id: None },
        cameras: Vec::new(),
        frames,
        tracks,
        map: None,
    }
}

/// Track 7 keeps its lane and speed from t0 = 52 s to 56 s.
fn plan() -> Plan {
    let waypoints = (0..=40)
        .map(|k| {
            let t = 52.0 + 0.1 * k as f64;
            let p = along(5.0 + 12.0 * (t - T_FIRST), 3.5);
            Waypoint { t, x: p.x, y: p.y }
        })
        .collect();
    Plan {
        format: PLAN_FORMAT.into(),
        scene: "carla-bridge-test".into(),
        behavior: Behavior::SidePass,
        adversary_track: "7".into(),
        target_zone: Zone::Left,
        zone_layout: ZoneLayout::Adjacent,
        start_time_s: 52.0,
        ttc_s: 2.0,
        risk: Risk::Medium,
        agent: "test".into(),
        reasoning: "keep the lane".into(),
        dt_s: 0.1,
        waypoints,
        target: None,
        seed: None,
        path: None,
        inserted: None,
    }
}

/// `None` (after printing SKIP) when no Python runs here.
fn python_or_skip(what: &str) -> Option<std::path::PathBuf> {
    let python = default_python();
    match Command::new(&python).arg("-c").arg("import json, math, sys").output() {
        Ok(out) if out.status.success() => Some(python),
        _ => {
            println!("SKIP: {what}: no working Python at `{}` (set CARLA_GS_PYTHON)", python.display());
            None
        }
    }
}

/// `None` (after printing SKIP) when the `carla` wheel is not installed for that Python.
fn carla_python_or_skip(what: &str) -> Option<std::path::PathBuf> {
    let python = python_or_skip(what)?;
    let out = Command::new(&python).arg("-c").arg("import carla; print(carla.Client)").output().ok()?;
    if out.status.success() {
        Some(python)
    } else {
        println!(
            "SKIP: {what}: `import carla` fails for `{}` (run tools/setup.sh): {}",
            python.display(),
            String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("")
        );
        None
    }
}

fn fake(python: std::path::PathBuf) -> CarlaOptions {
    CarlaOptions { python, fake: true, ..CarlaOptions::default() }
}

#[test]
fn fake_server_rollout_tracks_the_plan_through_the_pipe() {
    let Some(python) = python_or_skip("fake-server rollout") else { return };
    let (scene, plan, cfg) = (scene(false), plan(), RolloutConfig::default());
    let ex = sim::carla::simulate(&scene, &plan, &cfg, &fake(python)).unwrap();
    ex.validate().unwrap();
    assert!(ex.backend.contains("fake server"), "{}", ex.backend);
    // From the adversary's first logged frame to the plan's end, one state per 0.05 s.
    assert_eq!(ex.steps.len(), 121);
    assert!((ex.steps[0].t - T_FIRST).abs() < 1e-9 && (ex.steps[120].t - 56.0).abs() < 1e-6);
    let max_err = ex.steps.iter().map(|s| DVec2::new(s.x - s.ref_x, s.y - s.ref_y).length()).fold(0.0, f64::max);
    assert!(max_err < 1.0, "the adversary left its reference by {max_err} m");
    let last = ex.steps.last().unwrap();
    assert!((last.heading - 30f64.to_radians()).abs() < 0.05, "heading {}", last.heading);
    assert!((last.speed - 12.0).abs() < 1.0, "speed {}", last.speed);
    // The ego replays its log at every step time.
    for (s, e) in ex.steps.iter().zip(&ex.ego_path) {
        let want = along(10.0 * (s.t - T_FIRST), 0.0);
        assert!((DVec2::new(e.x, e.y) - want).length() < 1e-6);
    }
    assert!(ex.first_contact.is_none(), "{:?}", ex.first_contact);
    assert!(ex.validity.valid, "{:?}", ex.validity);
    // The built-in physics ends within a metre of the bridge's bicycle: same plan, same control law.
    let builtin = sim::simulate(&scene, &plan, &cfg).unwrap();
    let b = builtin.steps.last().unwrap();
    let gap = DVec2::new(b.x - last.x, b.y - last.y).length();
    assert!(gap < 1.0, "built-in and fake CARLA end {gap} m apart");
}

#[test]
fn contact_with_a_replayed_actor_comes_back() {
    let Some(python) = python_or_skip("fake-server contact") else { return };
    let ex = sim::carla::simulate(&scene(true), &plan(), &RolloutConfig::default(), &fake(python)).unwrap();
    let c = ex.first_contact.as_ref().expect("the adversary runs into the parked car");
    assert_eq!(c.other, "9");
    // The front bumper (centre + 2.3 m) reaches the parked car's rear (80 - 2.3 m) at about 55.87 s.
    assert!((55.6..=56.0).contains(&c.t), "contact at {}", c.t);
    assert!(ex.validity.reasons.iter().any(|r| r.key() == "contact_with_other"), "{:?}", ex.validity);
}

#[test]
fn import_carla_from_the_installed_wheel() {
    let Some(python) = carla_python_or_skip("import carla") else { return };
    let out = Command::new(&python)
        .arg("-c")
        .arg("import carla; c = carla.Client('127.0.0.1', 2000); print(c.get_client_version())")
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let version = String::from_utf8_lossy(&out.stdout);
    assert!(version.trim().starts_with("0.9.16"), "client version {version}");
}

#[test]
fn no_server_is_a_clear_error_within_the_timeout() {
    let Some(python) = carla_python_or_skip("no-server error") else { return };
    // A port nothing listens on: bind, note it, close.
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let opts = CarlaOptions { python, port, timeout_s: 1.0, ..CarlaOptions::default() };
    let start = Instant::now();
    let e = sim::carla::simulate(&scene(false), &plan(), &RolloutConfig::default(), &opts).unwrap_err();
    let elapsed = start.elapsed().as_secs_f64();
    let msg = e.to_string();
    assert!(matches!(e, SimError::Carla(sim::carla::CarlaError::NoServer { .. })), "{msg}");
    assert!(msg.contains(&format!("127.0.0.1:{port}")) && msg.contains("1 s timeout"), "{msg}");
    assert!(elapsed < 20.0, "took {elapsed} s");
}

#[test]
fn a_bridge_that_never_answers_is_stopped_at_the_deadline() {
    let Some(python) = python_or_skip("silent bridge") else { return };
    let dir = std::env::temp_dir().join(format!("carla-gs-silent-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let script = dir.join("silent.py");
    std::fs::write(&script, "import sys, time\nsys.stdin.readline()\ntime.sleep(600)\n").unwrap();
    let opts = CarlaOptions {
        python,
        script: Some(script),
        timeout_s: 0.5,
        load_timeout_s: 0.5,
        startup_s: 1.0,
        ..CarlaOptions::default()
    };
    let start = Instant::now();
    let e = sim::carla::simulate(&scene(false), &plan(), &RolloutConfig::default(), &opts).unwrap_err().to_string();
    assert!(start.elapsed().as_secs_f64() < 10.0);
    assert!(e.contains("sent nothing for 2 s") && e.contains("load the map"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_step_too_long_for_carla_is_refused_before_starting() {
    let mut cfg = RolloutConfig::default();
    cfg.tracker.control_dt_s = 0.2;
    let opts = CarlaOptions { python: "/nonexistent/python".into(), fake: true, ..CarlaOptions::default() };
    let e = sim::carla::simulate(&scene(false), &plan(), &cfg, &opts).unwrap_err().to_string();
    assert!(e.contains("control_dt_s") && e.contains("0.1"), "{e}");
}
