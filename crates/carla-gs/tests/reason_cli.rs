//! `carla-gs reason` with the user's constraints on the shared WOMD scene (stationary ego,
//! t0 = 2 s): an impossible request names the constraint, a possible one plans that vehicle in
//! that zone at that TTC (on the dt grid), a bad flag is an error naming the flag. Outputs go to a
//! temporary directory.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn carla_gs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The stationary-ego WOMD scenario ingested into `tmp`.
fn scene_dir(tmp: &Path) -> Option<PathBuf> {
    for name in ["motion_data_one_scenario.tfrecord", "womd_scenario_input.tfrecord"] {
        let input = ingest::shared::waymo_file(name)?;
        let dir = tmp.join(name);
        let out = carla_gs(&["ingest", s(&input), "--out", s(&dir)]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        if scene::load_scene(&dir).unwrap().name == "637f20cafde22ff8" {
            return Some(dir);
        }
    }
    panic!("the stationary-ego scenario is in neither shared file")
}

#[test]
fn reason_with_adversary_zone_and_ttc() {
    let tmp = tempfile::tempdir().unwrap();
    let Some(dir) = scene_dir(tmp.path()) else { return };
    let plan_path = tmp.path().join("plan.json");
    let base = ["reason", s(&dir), "--t0", "2", "--out", s(&plan_path), "--adversary", "1588"];
    let run = |extra: &[&str]| {
        let out = carla_gs(&[&base[..], extra].concat());
        (
            out.status.success(),
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    // No case possible: exit code 3 (not 0, not 2), the reason on stderr, no file.
    let out = carla_gs(&[&base[..], &["--zone", "left", "--behavior", "sudden_cut_in"]].concat());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(
        stderr.contains(
            "no case: no feasible adversary for this behaviour at t0 = 2.00 s: track 1588 cannot perform \
             sudden_cut_in into zone left: sudden_cut_in never aims at zone left"
        ),
        "{stderr}"
    );
    assert!(!plan_path.exists());
    let (ok, stdout, stderr) = run(&["--zone", "left", "--behavior", "side_pass", "--ttc", "3.04"]);
    assert!(ok && stdout.contains("vehicle 1588 -> left zone, side_pass, TTC 3.00 s"), "{stdout}{stderr}");
    let plan: scene::Plan = scene::format::read_json(&plan_path).unwrap();
    assert_eq!((plan.adversary_track.as_str(), plan.target_zone), ("1588", scene::Zone::Left));
    let (ok, _, stderr) = run(&["--zone", "up", "--behavior", "side_pass"]);
    assert!(!ok && stderr.contains("--zone"), "{stderr}");
    let (ok, _, stderr) = run(&["--ttc=-1", "--behavior", "side_pass"]);
    assert!(!ok && stderr.contains("--ttc"), "{stderr}");
}

/// A pedestrian as the adversary: planned for `step_out` (and by `auto`), refused for a vehicle
/// behaviour with the constraint named; a vehicle asked to step out is refused too.
#[test]
fn reason_with_a_pedestrian_adversary() {
    let tmp = tempfile::tempdir().unwrap();
    let Some(dir) = scene_dir(tmp.path()) else { return };
    let plan_path = tmp.path().join("ped.json");
    let reason =
        |extra: &[&str]| carla_gs(&[&["reason", s(&dir), "--t0", "1", "--out", s(&plan_path)][..], extra].concat());
    let run = |extra: &[&str]| {
        let out = reason(extra);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    // Refusals are "no case possible": exit code 3 with the reason on stderr.
    let no_case = |extra: &[&str]| {
        let out = reason(extra);
        let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
        assert_eq!(out.status.code(), Some(3), "{stderr}");
        stderr
    };
    let stderr = no_case(&["--adversary", "2313", "--behavior", "sudden_braking"]);
    assert!(
        stderr.contains(
            "track 2313 cannot perform sudden_braking: it is a pedestrian, and pedestrians can perform step_out only"
        ),
        "{stderr}"
    );
    assert!(!plan_path.exists());
    let stderr = no_case(&["--adversary", "1588", "--behavior", "step_out"]);
    assert!(stderr.contains("it is a vehicle, and only pedestrians can perform step_out"), "{stderr}");
    let stdout = run(&["--adversary", "2313"]);
    assert!(stdout.contains("planner: pedestrian 2313 -> front zone, step_out"), "{stdout}");
    let plan: scene::Plan = scene::format::read_json(&plan_path).unwrap();
    assert_eq!((plan.adversary_track.as_str(), plan.behavior), ("2313", scene::Behavior::StepOut));
}
