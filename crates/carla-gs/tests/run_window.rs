//! `run` without `--horizon` searches as `demo` does: the plan's own end first, and only if no
//! attempt succeeds there, the tables' 5 s window. On PandaSet 002 the braking lead's plan ends
//! before the logged ego closes in, so `--horizon plan` finds no success and the default finds
//! one over 5 s; `run.json` names the chosen case's window and every attempt's.

mod cli_support;

use cli_support::{carla_gs, ok, s};
use serde_json::Value;

#[test]
fn run_falls_back_to_the_tables_window_only_without_horizon() {
    let Some(src) = ingest::shared::data_path("pandaset/002") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let (scene, model) = (tmp.path().join("s"), tmp.path().join("m"));
    ok(carla_gs(&["ingest", s(&src), "--out", s(&scene)]));
    ok(carla_gs(&["train", s(&scene), "--out", s(&model), "--iters", "2", "--scale", "0.05"]));
    let run = |out: &str, extra: &[&str]| -> Value {
        let out = tmp.path().join(out);
        let mut args = vec!["run", s(&scene), "--model", s(&model), "--behavior", "sudden_braking", "--out", s(&out)];
        args.extend(["--layouts", "single:front_camera", "--fps", "1", "--scale", "0.05", "--png"]);
        args.extend(extra);
        ok(carla_gs(&args));
        serde_json::from_slice(&std::fs::read(out.join("run.json")).unwrap()).unwrap()
    };
    let success = |r: &Value| r["metrics"]["success_center"] == Value::Bool(true);
    let plan = run("plan", &["--horizon", "plan"]);
    assert!(!success(&plan), "a braking case succeeded over the plan's own end");
    assert!(plan["attempts"].as_array().unwrap().iter().all(|a| a["window"]["horizon"] == "plan"));
    let default = run("default", &[]);
    assert!(success(&default), "{}", default["metrics"]);
    assert_eq!(default["window"]["horizon"]["seconds"], 5.0);
    let attempts = default["attempts"].as_array().unwrap();
    let n = plan["attempts"].as_array().unwrap().len();
    assert!(attempts.len() > n && attempts[..n].iter().all(|a| a["window"]["horizon"] == "plan"));
}
