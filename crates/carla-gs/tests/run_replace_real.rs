//! Issue 26's placement acceptance on the real log, through the command line: on PandaSet 002 the
//! demo's braking case (the lead car 5efc9139, t0 1.5 s, seed 1, 5 s window) with the lead car
//! replaced by the nearest-sized asset of a synthetic library (`run --replace <track>=auto`) is
//! valid with zone hit and success, and the drawn car matches its box (placement profile IoU above
//! 0.8) at every check, one of them more than 3 m from its logged position. The replaced car is
//! drawn from the asset alone, so a two-iteration model is enough; unreplaced, the same check on
//! a fully trained model falls to 0.62 to 0.76 far from the log (docs/pandaset.md).

mod cli_support;

use cli_support::{carla_gs, ok, s};
use serde_json::Value;

const LEAD: &str = "5efc9139-933d-4339-b584-00054253c4ce";

#[test]
fn the_replaced_braking_lead_lands_on_its_box_far_from_the_log() {
    let Some(src) = ingest::shared::data_path("pandaset/002") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let (scene, model, lib, out) =
        (tmp.path().join("s"), tmp.path().join("m"), tmp.path().join("lib"), tmp.path().join("run"));
    ok(carla_gs(&["ingest", s(&src), "--out", s(&scene)]));
    ok(carla_gs(&["train", s(&scene), "--out", s(&model), "--iters", "2", "--scale", "0.05"]));
    for kind in ["sedan", "van", "truck"] {
        ok(carla_gs(&["asset", "--library", s(&lib), "--from-synth", kind, "--voxel", "0.12"]));
    }
    let replace = format!("{LEAD}=auto");
    let mut args = vec!["run", s(&scene), "--model", s(&model), "--behavior", "sudden_braking", "--agent", "planner"];
    args.extend(["--adversary", LEAD, "--t0", "1.5", "--seed", "1", "--horizon", "5", "--out", s(&out)]);
    args.extend(["--replace", &replace, "--asset-library", s(&lib)]);
    args.extend(["--layouts", "single:front_camera", "--fps", "1", "--scale", "0.25", "--png"]);
    ok(carla_gs(&args));
    let run: Value = serde_json::from_slice(&std::fs::read(out.join("run.json")).unwrap()).unwrap();
    let m = &run["metrics"];
    assert_eq!(m["validity"]["valid"], Value::Bool(true), "{m}");
    assert_eq!(m["zone_hit"], Value::Bool(true), "{m}");
    assert_eq!(m["success_center"], Value::Bool(true), "{m}");
    let placement = run["placement"].as_array().expect("placement checks");
    assert!(placement.len() >= 3, "{placement:?}");
    let field = |p: &Value, k: &str| p[k].as_f64().unwrap_or_else(|| panic!("{k} in {p}"));
    for p in placement {
        assert!(field(p, "profile_iou") > 0.8, "the replaced lead car misses its box: {p}");
    }
    let far = placement.iter().map(|p| field(p, "offset_from_log_m")).fold(0.0, f64::max);
    assert!(far > 3.0, "no check more than 3 m from the logged position (farthest {far} m)");
}
