//! Issue 56, "a user's files lost or mixed": `demo --out` on a person's folder replaced its
//! `scene/`, deleted `report_files/` and overwrote `report.html` and `demo.json`; and `demo
//! --input .` in a scene folder wrote its default `demo-out` inside the input, copying the scene
//! into itself ~167 levels deep. Now a demo's `--out` must be new, empty or a demo's own (with or
//! without `--force`), and no command with an input directory and an `--out` directory writes
//! inside, onto or around an input. Each refusal is exit 2 naming the folder, and the person's
//! files are listed unchanged after.

mod cli_support;
use cli_support::{carla_gs, dot_entries_beside, killed_after, listing, ok, refused, s};
use std::path::{Path, PathBuf};

fn synth(t: &Path) -> PathBuf {
    let scene = t.join("scene");
    let args = ["synth", "--out", s(&scene), "--frames", "40", "--width", "32", "--height", "24", "--cameras", "1"];
    ok(carla_gs(&args));
    scene
}

#[test]
fn demo_never_replaces_a_persons_folder() {
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("project");
    std::fs::create_dir_all(out.join("scene")).unwrap();
    std::fs::write(out.join("scene/field-notes.txt"), b"mine").unwrap();
    std::fs::create_dir_all(out.join("report_files")).unwrap();
    std::fs::write(out.join("report_files/figure.png"), b"mine").unwrap();
    std::fs::write(out.join("report.html"), b"<p>my report</p>").unwrap();
    std::fs::write(out.join("demo.json"), br#"{"my": "settings"}"#).unwrap();
    let before = listing(t.path());
    for extra in [&[][..], &["--force"]] {
        let args = [&["demo", "--out", s(&out), "--iters", "1"][..], extra].concat();
        refused(carla_gs(&args), &[s(&out), "not a demo output", "demo.json"]);
        assert_eq!(listing(t.path()), before, "{extra:?}");
    }
}

#[test]
fn a_demo_killed_part_way_is_still_ours() {
    // As a demo killed while training leaves it: the marker written first, a stage or two.
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("demo-out");
    std::fs::create_dir_all(out.join("model")).unwrap();
    std::fs::write(out.join("demo.json"), br#"{"format": "carla-gs-demo/1", "complete": false}"#).unwrap();
    // The --out check passes (with or without --force); the missing --input is what is refused.
    let missing = t.path().join("no-such-log");
    for extra in [&[][..], &["--force"]] {
        let args = [&["demo", "--out", s(&out), "--input", s(&missing)][..], extra].concat();
        let r = carla_gs(&args);
        let err = String::from_utf8_lossy(&r.stderr).into_owned();
        refused(r, &["--input", "not a folder"]);
        assert!(!err.contains("not a demo output"), "{err}");
    }
}

#[test]
fn demo_out_inside_its_input_is_refused() {
    let t = tempfile::tempdir().unwrap();
    let scene = synth(t.path());
    let before = listing(t.path());
    // `demo --input .` in the scene folder: the default `demo-out` is inside it.
    let r = std::process::Command::new(env!("CARGO_BIN_EXE_carla-gs"))
        .args(["demo", "--input", ".", "--iters", "1"])
        .current_dir(&scene)
        .output()
        .unwrap();
    refused(r, &["demo-out", "inside the input directory"]);
    assert_eq!(listing(t.path()), before);
    for (out, why) in
        [(scene.join("d/e"), "inside the input"), (scene.clone(), "is an input"), (t.path().into(), "holds the input")]
    {
        refused(carla_gs(&["demo", "--input", s(&scene), "--out", s(&out), "--iters", "1"]), &[s(&out), why]);
        assert_eq!(listing(t.path()), before, "{}", out.display());
    }
}

#[test]
fn no_command_writes_its_out_inside_its_input() {
    let t = tempfile::tempdir().unwrap();
    let scene = synth(t.path());
    let model = t.path().join("model");
    std::fs::create_dir(&model).unwrap();
    let inside = scene.join("out");
    let run_out = model.join("r");
    let before = listing(t.path());
    let (episode, replaced) = (scene.join("episode"), model.join("replaced"));
    let drive = ["drive", s(&model), "--model", s(&model), "--scene", s(&scene), "--policy", "log", "--out"];
    let commands: [&[&str]; 9] = [
        &[&drive[..], &[s(&episode)]].concat(),
        &["eval-drive", s(&model), "--scene", s(&scene), "--out", s(&episode)],
        &["replace", s(&model), "--track", "t", "--asset", "a", "--out", s(&replaced), "--force"],
        &["ingest", s(&scene), "--out", s(&inside), "--force"],
        &["train", s(&scene), "--out", s(&inside), "--iters", "1"],
        &["ablate", s(&scene), "--out", s(&inside), "--iters", "1"],
        &["eval-cases", s(&scene), "--agents", "planner", "--t0", "1", "--out", s(&inside)],
        &["run", s(&scene), "--model", s(&model), "--behavior", "sudden_braking", "--out", s(&run_out)],
        &["bench-cases", "--data", s(&scene), "--out", s(&inside)],
    ];
    for args in commands {
        refused(carla_gs(args), &["--out", "inside the input directory"]);
        assert_eq!(listing(t.path()), before, "{args:?}");
    }
    // Replacing an --out that holds the input would delete it.
    refused(carla_gs(&["ablate", s(&scene), "--out", s(t.path()), "--force"]), &["holds the input"]);
    assert_eq!(listing(t.path()), before);
}

/// `demo --force` over a finished demo: killed at several points it leaves the finished demo as
/// it was (the new one is built beside it); let finish, it replaces it whole, leaving nothing
/// beside it.
#[test]
fn demo_force_builds_beside_the_old_demo_and_swaps_it_in_whole() {
    let t = tempfile::tempdir().unwrap();
    // A real log is trained at a quarter of its cameras' size: 96x64 keeps 24x16.
    let scene = t.path().join("scene");
    let args = ["synth", "--out", s(&scene), "--frames", "30", "--width", "96", "--height", "64", "--cameras", "1"];
    ok(carla_gs(&args));
    let out = t.path().join("demo-out");
    let args = |force: bool| {
        let mut v = vec!["demo", "--input", s(&scene), "--out", s(&out), "--iters", "1", "--no-auto-replace"];
        v.extend(force.then_some("--force"));
        v
    };
    ok(carla_gs(&args(false)));
    let demo_json = std::fs::read_to_string(out.join("demo.json")).unwrap();
    // The finished demo's result (the marker written as it starts says `"complete": false`).
    let finished = |j: &str| j.contains("carla-gs-demo/1") && j.contains("\"cases\"") && !j.contains("\"complete\"");
    assert!(finished(&demo_json), "{demo_json}");
    let before = listing(&out);
    for ms in [300u64, 2500] {
        if killed_after(&args(true), ms) {
            // It finished first: replaced whole; the old listing no longer applies.
            break;
        }
        assert_eq!(listing(&out), before, "demo --force killed after {ms} ms changed the finished demo");
    }
    // Let finish: the old demo's files are gone with it (replaced whole), nothing is left beside.
    std::fs::write(out.join("left-by-the-old-demo.txt"), b"old").unwrap();
    ok(carla_gs(&args(true)));
    assert!(!out.join("left-by-the-old-demo.txt").exists(), "--force replaces the old demo whole");
    let demo_json = std::fs::read_to_string(out.join("demo.json")).unwrap();
    assert!(finished(&demo_json), "{demo_json}");
    assert!(out.join("report.html").is_file());
    assert_eq!(dot_entries_beside(&out), Vec::<String>::new(), "staging left beside --out");
}
