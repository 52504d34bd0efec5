//! Fuzzing finds about the Execute stage's inputs: a `simulate --config` with absurd vehicle,
//! actuation or tracker values (negative mass, no gears, a 1e9 m wheelbase that made the rollout
//! crawl for minutes, a 1e6 rad steering limit) or 20,000 resampling rates (528 MB written), and
//! executed files edited to absurd box sizes, periods or resampled series that `metrics` scored
//! "valid". Each exits with code 2 naming the field, quickly, and writes nothing.

mod cli_support;

use cli_support::{carla_gs, ok, refused, s};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// A small synthetic street and a cut-in plan on it: (scene, plan).
fn scene_and_plan(dir: &Path) -> (PathBuf, PathBuf) {
    let scene = dir.join("s40");
    ok(carla_gs(&["synth", "--out", s(&scene), "--frames", "40", "--width", "32", "--height", "24", "--cameras", "1"]));
    let plan = dir.join("plan.json");
    ok(carla_gs(&["reason", s(&scene), "--t0", "1", "--behavior", "sudden_cut_in", "--out", s(&plan)]));
    (scene, plan)
}

#[test]
fn absurd_rollout_configurations_are_refused_on_load() {
    let tmp = tempfile::tempdir().unwrap();
    let (scene, plan) = scene_and_plan(tmp.path());
    let exec = tmp.path().join("executed.json");
    let config = tmp.path().join("config.json");
    let default = serde_json::to_value(sim::RolloutConfig::default()).unwrap();
    let simulate = |edit: &dyn Fn(&mut Value)| {
        let mut c = default.clone();
        edit(&mut c);
        std::fs::write(&config, serde_json::to_vec(&c).unwrap()).unwrap();
        let start = Instant::now();
        let out = carla_gs(&["simulate", s(&plan), "--scene", s(&scene), "--out", s(&exec), "--config", s(&config)]);
        assert!(start.elapsed() < Duration::from_secs(20), "took {:?}", start.elapsed());
        out
    };
    type Edit = fn(&mut Value);
    let cases: [(Edit, &[&str]); 8] = [
        (|c| c["vehicle"]["m"] = (-5.0).into(), &["config.json", "`vehicle.m`", "kg"]),
        (|c| c["vehicle"]["m"] = 0.0.into(), &["`vehicle.m`"]),
        (|c| c["actuation"]["gear_ratios"] = Value::Array(vec![]), &["`actuation.gear_ratios`", "1 to 32 gears"]),
        (|c| c["vehicle"]["a"] = 1e9.into(), &["`vehicle.a`", "0.05 to 15 m"]),
        (|c| c["actuation"]["max_steer_angle"] = 1e6.into(), &["`actuation.max_steer_angle`", "rad"]),
        (|c| c["vehicle"]["steering"]["max"] = 1e6.into(), &["`vehicle.steering.max`"]),
        (|c| c["tracker"]["lateral"]["k_p"] = (-1e300).into(), &["`tracker.lateral.k_p`", "0 to 100"]),
        (
            |c| c["resample_hz"] = (0..20_000).map(|i| Value::from(10.0 + i as f64 * 1e-3)).collect(),
            &["`resample_hz`", "20000 rates, at most 8"],
        ),
    ];
    for (edit, needles) in cases {
        refused(simulate(&edit), needles);
        assert!(!exec.exists(), "{needles:?}");
    }
    // The defaults, written out, load and run.
    ok(simulate(&|_| {}));
    assert!(exec.exists());
    std::fs::remove_file(&exec).unwrap();
    // A file that holds the most rates, and one more from `--fps`: the settings are named, not the plan.
    let mut c = default.clone();
    c["resample_hz"] = (0..8).map(|i| Value::from(10.0 + i as f64)).collect();
    std::fs::write(&config, serde_json::to_vec(&c).unwrap()).unwrap();
    let args = ["simulate", s(&plan), "--scene", s(&scene), "--out", s(&exec), "--config", s(&config), "--fps", "24"];
    let out = carla_gs(&args);
    refused(out.clone(), &["config.json with --control-dt/--fps", "`resample_hz`", "at most 8"]);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("cannot execute the plan"));
    assert!(!exec.exists());
}

#[test]
fn absurd_executed_files_are_refused_by_every_reader() {
    let tmp = tempfile::tempdir().unwrap();
    let (scene, plan) = scene_and_plan(tmp.path());
    let exec = tmp.path().join("executed.json");
    ok(carla_gs(&["simulate", s(&plan), "--scene", s(&scene), "--out", s(&exec), "--fps", "24"]));
    ok(carla_gs(&["metrics", s(&exec)]));
    let good: Value = serde_json::from_slice(&std::fs::read(&exec).unwrap()).unwrap();
    let edited = tmp.path().join("edited.json");
    type Edit = fn(&mut Value);
    let cases: [(Edit, &[&str]); 9] = [
        (|e| e["adversary"]["size_lwh"] = serde_json::json!([1e6, 1e6, 1e6]), &["`adversary.size_lwh[0]`"]),
        (|e| e["ego"]["size_lwh"][1] = 0.0.into(), &["`ego.size_lwh[1]`", "got 0"]),
        (|e| e["adversary"]["size_lwh"][2] = (-1.5).into(), &["`adversary.size_lwh[2]`"]),
        (|e| e["control_dt_s"] = 1e-300.into(), &["`control_dt_s`", "1e-300"]),
        (|e| e["physics_dt_s"] = 1e-300.into(), &["`physics_dt_s`"]),
        (|e| e["steps"][3]["ref_y"] = 1e300.into(), &["`steps[3].ref_y`", "1e300"]),
        (|e| e["resampled"][1]["rate_hz"] = 1e9.into(), &["`resampled[1].rate_hz`"]),
        (
            |e| {
                let t = e["resampled"][0]["adversary"][1]["t"].clone();
                e["resampled"][0]["adversary"][2]["t"] = t.clone();
                e["resampled"][0]["ego"][2]["t"] = t;
            },
            &["`resampled[0].adversary[2].t`", "increase strictly"],
        ),
        (|e| e["resampled"][0]["ego"][4]["x"] = 1e300.into(), &["`resampled[0].ego[4].x`"]),
    ];
    for (edit, needles) in cases {
        let mut j = good.clone();
        edit(&mut j);
        std::fs::write(&edited, serde_json::to_vec(&j).unwrap()).unwrap();
        refused(carla_gs(&["metrics", s(&edited)]), needles);
        // The same check in the library every reader goes through.
        let e = scene::executed::load_executed(&edited).unwrap_err().to_string();
        assert!(e.contains("edited.json") && e.contains(needles[0].trim_matches('`')), "{e}");
    }
}
