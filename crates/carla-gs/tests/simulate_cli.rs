//! `carla-gs simulate` and `metrics` end to end on the shared real WOMD scene, and bad plans:
//! each gets exit code 2, a message naming the field, and no output file.

use scene::plan::{Plan, PLAN_FORMAT};
use scene::{Behavior, Risk, Waypoint, Zone, ZoneLayout};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn carla_gs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Ingests the moving-ego WOMD scenario into `dir/scene`; `None` (skip) without shared data.
fn scene_dir(dir: &Path) -> Option<PathBuf> {
    let input = ingest::shared::waymo_file("womd_scenario_input.tfrecord")?;
    let out = dir.join("scene");
    assert!(carla_gs(&["ingest", s(&input), "--out", s(&out)]).status.success());
    Some(out)
}

/// A plan for the first vehicle that moves at least 10 m in [t0, t0 + 3 s]: its logged path
/// with a smooth 2 m lateral shift (a lane-change-like reference).
fn plan_for(scene: &scene::Scene) -> Plan {
    let t0 = scene.frames[20].timestamp_s;
    let t1 = t0 + 3.0;
    for tr in scene
        .tracks
        .iter()
        .filter(|t| t.class == scene::ObjectClass::Vehicle && Some(&t.id) != scene.ego.track_id.as_ref())
    {
        let (Some(a), Some(b)) = (scene.track_pose_at(tr, t0), scene.track_pose_at(tr, t1)) else { continue };
        if a.position().distance(b.position()) < 10.0 {
            continue;
        }
        let waypoints = (0..=30)
            .map(|k| {
                let t = t0 + k as f64 * 0.1;
                let p = scene.track_pose_at(tr, t).unwrap();
                let shift = 2.0 * (0.5 - 0.5 * (std::f64::consts::PI * k as f64 / 30.0).cos());
                Waypoint { t, x: p.x - shift * p.heading.sin(), y: p.y + shift * p.heading.cos() }
            })
            .collect();
        return Plan {
            format: PLAN_FORMAT.into(),
            scene: scene.name.clone(),
            behavior: Behavior::SuddenCutIn,
            adversary_track: tr.id.clone(),
            target_zone: Zone::Front,
            zone_layout: ZoneLayout::Adjacent,
            start_time_s: t0,
            ttc_s: 3.0,
            risk: Risk::Medium,
            agent: "test".into(),
            reasoning: "logged path with a 2 m lateral shift".into(),
            dt_s: 0.1,
            waypoints,
            target: None,
            seed: None,
            path: None,
            inserted: None,
        };
    }
    panic!("no moving vehicle in the scene");
}

#[test]
fn simulate_and_measure_a_real_scene() {
    let tmp = tempfile::tempdir().unwrap();
    let Some(dir) = scene_dir(tmp.path()) else { return };
    let scene = scene::load_scene(&dir).unwrap();
    let plan = plan_for(&scene);
    let plan_path = tmp.path().join("scenario.json");
    std::fs::write(&plan_path, serde_json::to_vec_pretty(&plan).unwrap()).unwrap();
    let exec_path = tmp.path().join("executed.json");
    let out = carla_gs(&["simulate", s(&plan_path), "--scene", s(&dir), "--out", s(&exec_path), "--fps", "24"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let executed = scene::executed::load_executed(&exec_path).unwrap();
    // PID from frame 0: the rollout starts at the adversary's first logged state, before t0.
    assert!(executed.steps[0].t < plan.start_time_s);
    assert!((executed.steps.last().unwrap().t - plan.end_time_s()).abs() < 1e-9);
    assert_eq!(executed.resampled.iter().map(|r| r.rate_hz).collect::<Vec<_>>(), vec![10.0, 24.0]);
    // The executed path follows the shifted reference closely inside the plan interval.
    let worst = executed
        .steps
        .iter()
        .filter(|s| s.t >= plan.start_time_s)
        .map(|s| (s.x - s.ref_x).hypot(s.y - s.ref_y))
        .fold(0.0, f64::max);
    assert!(worst < 2.0, "worst tracking error {worst} m");
    let m = carla_gs(&["metrics", s(&exec_path), "--json"]);
    assert!(m.status.success(), "{}", String::from_utf8_lossy(&m.stderr));
    let j: Value = serde_json::from_slice(&m.stdout).unwrap();
    assert_eq!(j["samples"], 31);
    for k in ["min_ttc_center_s", "min_ttc_box_s", "min_distance_m"] {
        assert!(j[k].as_f64().unwrap() >= 0.0, "{k}");
    }
    assert!(j["min_ttc_box_s"].as_f64().unwrap() <= j["min_ttc_center_s"].as_f64().unwrap() + 1e-9);
    assert!(j["comfort_executed"]["a_lat_p95"].as_f64().is_some());
    assert!(carla_gs(&["metrics", s(&exec_path)]).status.success());
}

#[test]
fn bad_plans_are_refused_with_the_reason() {
    let tmp = tempfile::tempdir().unwrap();
    let Some(dir) = scene_dir(tmp.path()) else { return };
    let scene = scene::load_scene(&dir).unwrap();
    let good = serde_json::to_value(plan_for(&scene)).unwrap();
    type Edit = fn(&mut Value);
    let cases: [(&str, Edit, &str); 7] = [
        ("unknown track", |j| j["adversary_track"] = "no-such-car".into(), "track `no-such-car` is not in the scene"),
        ("time not increasing", |j| j["waypoints"][5]["t"] = j["waypoints"][4]["t"].clone(), "waypoints[5].t"),
        ("absurd coordinate", |j| j["waypoints"][3]["x"] = Value::from(f64::MAX), "`waypoints[3]`: implies"),
        (
            "detached start",
            |j| j["waypoints"][0]["x"] = Value::from(j["waypoints"][0]["x"].as_f64().unwrap() + 9.0),
            "m from track",
        ),
        (
            "start outside the scene",
            |j| {
                let shift = 100.0;
                j["start_time_s"] = Value::from(j["start_time_s"].as_f64().unwrap() + shift);
                for w in j["waypoints"].as_array_mut().unwrap() {
                    w["t"] = Value::from(w["t"].as_f64().unwrap() + shift);
                }
            },
            "outside the scene's time span",
        ),
        ("wrong type", |j| j["ttc_s"] = "soon".into(), "ttc_s"),
        ("unknown behaviour", |j| j["behavior"] = "teleport".into(), "behavior"),
    ];
    for (what, edit, needle) in cases {
        let mut j = good.clone();
        edit(&mut j);
        let plan_path = tmp.path().join("bad.json");
        std::fs::write(&plan_path, serde_json::to_vec(&j).unwrap()).unwrap();
        let out_path = tmp.path().join("executed.json");
        let out = carla_gs(&["simulate", s(&plan_path), "--scene", s(&dir), "--out", s(&out_path)]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{what}: {err}");
        assert!(err.contains(needle), "{what}: expected `{needle}` in: {err}");
        assert!(!out_path.exists(), "{what}: output written");
    }
    // NaN is not JSON: the parser names the position.
    let text = serde_json::to_string(&good).unwrap().replacen("\"x\":", "\"x\":NaN,\"_\":", 1);
    let plan_path = tmp.path().join("nan.json");
    std::fs::write(&plan_path, text).unwrap();
    let out = carla_gs(&["simulate", s(&plan_path), "--scene", s(&dir), "--out", s(&tmp.path().join("e.json"))]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("waypoints[0]"), "{}", String::from_utf8_lossy(&out.stderr));
}
