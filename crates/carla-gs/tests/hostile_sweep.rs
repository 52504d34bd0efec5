//! Issue 56 (a hostile-input sweep on the binary), items B-D: sizes, counts and rates read from
//! arguments and files are checked before anything is allocated or run, FIFOs are refused rather
//! than read forever, a plan that can only fail is refused when it is made, and a run with
//! nothing to evaluate says why. Each command here finishes in well under a second; a command
//! that hangs is killed after [`LIMIT`] and fails its test.

mod cli_support;
use cli_support::{ok, refused, s};
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

const LIMIT: Duration = Duration::from_secs(60);

/// Runs carla-gs with `args`, killing it past [`LIMIT`] (a hang fails the test, not CI).
fn run(args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_carla-gs"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > LIMIT {
            child.kill().unwrap();
            panic!("carla-gs {args:?} still running after {LIMIT:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

fn mkfifo(p: &Path) {
    assert!(Command::new("mkfifo").arg(p).status().unwrap().success());
}

/// A synthetic scene of `frames` frames (10 Hz).
fn synth(t: &Path, name: &str, frames: &str) -> std::path::PathBuf {
    let scene = t.join(name);
    ok(run(&["synth", "--out", s(&scene), "--frames", frames, "--cameras", "1", "--width", "32", "--height", "24"]));
    scene
}

#[test]
fn t0_lists_are_checked_before_they_are_built() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = synth(tmp.path(), "s", "60");
    let out = tmp.path().join("ev");
    let eval =
        |t0: &str| run(&["eval-cases", s(&scene), "--agents", "planner", "--t0", t0, "--no-plots", "--out", s(&out)]);
    // 4.4 GB of t0 values for a 6 s log was an abort.
    refused(eval("every:1e-9s"), &["every:1e-9s", "at least 0.1 s"]);
    refused(run(&["bench-cases", "--sources", "womd", "--t0", "every:1e-9s", "--out", s(&out)]), &["at least 0.1 s"]);
    // A t0 past every scene's end was counted as one failed attempt.
    refused(
        eval("1e30"),
        &["--t0 1000000000000000000000000000000", "past the end of every scene", "`synth-seed0`, is 5.9 s long"],
    );
    // A log too short for any t0: exit 3 with the reason, no tables (was exit 0, empty tables).
    let short = synth(tmp.path(), "short", "33");
    let r = run(&["eval-cases", s(&short), "--agents", "planner", "--t0", "every:1s", "--no-plots", "--out", s(&out)]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(3), "{err}");
    assert!(err.contains("nothing to evaluate") && err.contains("3.2 s long"), "{err}");
    assert!(!out.join("table1.md").exists());
}

#[test]
fn bench_splat_sizes_and_iterations_are_checked() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("b.json");
    let bench = |cases: &str, iters: &str| run(&["bench-splat", "--cases", cases, "--iters", iters, "--out", s(&out)]);
    refused(bench("100000000000x8x8", "1"), &["`100000000000x8x8`", "Gaussians; at most"]);
    refused(bench("10x100000x100000", "1"), &["`10x100000x100000`", "a 100000x100000 image"]);
    refused(bench("10x0x8", "1"), &["a 0x8 image"]);
    // The median of no timing was a panic.
    refused(bench("10x8x8", "0"), &["--iters 0: expected 1 to"]);
    ok(bench("10x8x8", "1"));
}

#[test]
fn fifos_are_refused_not_read_forever() {
    let tmp = tempfile::tempdir().unwrap();
    let manifest = tmp.path().join("m.toml");
    mkfifo(&manifest);
    refused(run(&["batch", "plan", s(&manifest), "--out", s(&tmp.path().join("p"))]), &["m.toml", "FIFO"]);
    let scene = synth(tmp.path(), "s", "10");
    mkfifo(&scene.join("notes.fifo"));
    refused(run(&["demo", "--input", s(&scene), "--out", s(&tmp.path().join("demo"))]), &["notes.fifo", "FIFO"]);
}

#[test]
fn run_seeds_and_refinement_rounds_are_bounded() {
    let a = ["run", "scene", "--model", "model", "--behavior", "sudden_braking", "--out", "x"];
    let with = |extra: &[&str]| run(&[&a[..], extra].concat());
    refused(with(&["--seeds-per-t0", "100000"]), &["--seeds-per-t0 100000: expected 1 to 100"]);
    refused(with(&["--seeds-per-t0", "0"]), &["--seeds-per-t0 0"]);
    refused(with(&["--refine-rounds", "1000000"]), &["--refine-rounds 1000000: expected 0 to 100"]);
}

#[test]
fn batch_plans_that_can_only_fail_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    std::fs::create_dir(t.join("scene")).unwrap();
    let log = "[[log]]\nname = \"a\"\nscene = \"scene\"\n";
    for (i, (text, needles)) in [
        (format!("{log}[eval_cases]\nt0 = \"every:0s\"\n"), &["[eval_cases] t0", "every:0s"][..]),
        (format!("{log}[eval_cases]\nhorizon = \"-1\"\n"), &["[eval_cases] horizon"]),
        (format!("{log}[eval_cases]\nagents = \"planer\"\n"), &["[eval_cases] agents", "planer"]),
        (format!("{log}[train]\niters = 1000000000000\n"), &["[train] iters = 1000000000000"]),
        (format!("{log}[train]\nscale = nan\n"), &["[train] scale = NaN"]),
        (format!("{log}[eval_cases]\nargs = [\"--out\", \"elsewhere\"]\n"), &["[eval_cases] args", "--out"]),
        ("[[log]]\nname = \"a\"\ninput = \"x.tfrecord\"\nformat = \"tiff\"\n[eval_cases]\n".into(), &["format `tiff`"]),
        (
            "[[log]]\nname = \"a\"\ninput = \"missing.tfrecord\"\n[eval_cases]\n".into(),
            &["missing.tfrecord does not exist"],
        ),
    ]
    .into_iter()
    .enumerate()
    {
        let m = t.join(format!("m{i}.toml"));
        std::fs::write(&m, &text).unwrap();
        let out = t.join(format!("plan{i}"));
        let mut all = vec![format!("m{i}.toml")];
        all.extend(needles.iter().map(|n| n.to_string()));
        let all: Vec<&str> = all.iter().map(String::as_str).collect();
        refused(run(&["batch", "plan", s(&m), "--out", s(&out)]), &all);
        assert!(!out.join("plan.json").exists(), "{text}");
    }
    // The same manifest with sane values makes a plan.
    std::fs::write(t.join("good.toml"), format!("{log}[eval_cases]\nt0 = \"every:1s\"\n")).unwrap();
    ok(run(&["batch", "plan", s(&t.join("good.toml")), "--out", s(&t.join("good"))]));
}

#[test]
fn a_plan_node_running_batch_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    std::fs::create_dir(t.join("scene")).unwrap();
    std::fs::write(t.join("m.toml"), "[[log]]\nname = \"a\"\nscene = \"scene\"\n[eval_cases]\n").unwrap();
    let out = t.join("p");
    ok(run(&["batch", "plan", s(&t.join("m.toml")), "--out", s(&out)]));
    let plan_file = out.join("plan.json");
    let mut plan: serde_json::Value = serde_json::from_slice(&std::fs::read(&plan_file).unwrap()).unwrap();
    // The tables node made to run `batch exec` on itself recursed without bound.
    let node = plan["nodes"].as_array_mut().unwrap().iter_mut().find(|n| n["id"] == "tables").unwrap();
    node["args"] = serde_json::json!(["batch", "exec", s(&plan_file), "tables"]);
    node["deps"] = serde_json::json!([]);
    std::fs::write(&plan_file, serde_json::to_vec_pretty(&plan).unwrap()).unwrap();
    refused(run(&["batch", "exec", s(&plan_file), "tables"]), &["tables", "runs `carla-gs batch`"]);
}

#[test]
fn bench_cases_names_a_kitti_window_longer_than_the_sequence() {
    if !Path::new("../../../shared/data/kitti/poses/00.txt").exists() {
        println!("SKIP: ../shared/data/kitti is absent");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("b");
    let r = run(&[
        "bench-cases",
        "--data",
        "../../../shared/data",
        "--sources",
        "kitti",
        "--kitti-window-s",
        "1e30",
        "--out",
        s(&out),
    ]);
    // Was "two scenes are named ...".
    refused(r, &["--kitti-window-s 1000000000000000000000000000000", "longer than KITTI sequence 00"]);
}

#[test]
fn reason_refuses_a_dt_simulate_would_refuse() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = synth(tmp.path(), "s", "60");
    let out = tmp.path().join("plan.json");
    for dt in ["3", "10", "1e30", "0"] {
        // 3 and 10 wrote plans `simulate` refused; 1e30 was a panic.
        let r = run(&["reason", s(&scene), "--t0", "1", "--behavior", "sudden_braking", "--dt", dt, "--out", s(&out)]);
        refused(r, &["--dt ", "expected a waypoint spacing from 0.01 to 1 s"]);
        assert!(!out.exists());
    }
}

/// An ASCII 3DGS PLY of three Gaussians, the middle one's values replaced by `middle`.
fn asset_ply(path: &Path, middle: &str) {
    let props = ["x", "y", "z", "f_dc_0", "f_dc_1", "f_dc_2", "opacity", "scale_0", "scale_1", "scale_2"];
    let mut text = String::from("ply\nformat ascii 1.0\nelement vertex 3\n");
    for p in props.iter().chain(&["rot_0", "rot_1", "rot_2", "rot_3"]) {
        text += &format!("property float {p}\n");
    }
    text += "end_header\n0 0 0 0.5 0.5 0.5 1 -2 -2 -2 1 0 0 0\n";
    text += &format!("{middle}\n0 1 0.5 0.5 0.5 0.5 1 -2 -2 -2 1 0 0 0\n");
    std::fs::write(path, text).unwrap();
}

#[test]
fn an_absurd_asset_is_refused_and_ply_errors_name_the_file_once() {
    let tmp = tempfile::tempdir().unwrap();
    let lib = tmp.path().join("lib");
    let add = |name: &str, middle: &str| {
        let ply = tmp.path().join(name);
        asset_ply(&ply, middle);
        run(&["asset", "--library", s(&lib), "--ply", s(&ply)])
    };
    ok(add("good.ply", "1 0 0 0.5 0.5 0.5 1 -2 -2 -2 1 0 0 0"));
    // Drawn as nothing, its case reported valid, before.
    refused(
        add("huge.ply", "1 0 0 0.5 0.5 0.5 1 87 -2 -2 1 0 0 0"),
        &["huge.ply: vertex 1: property `scale_0`: log-scale 87"],
    );
    refused(add("flat.ply", "1 0 0 0.5 0.5 0.5 1 -2 -2 -2 0 0 0 0"), &["flat.ply: vertex 1", "quaternion is zero"]);
    let bad = tmp.path().join("bad.ply");
    std::fs::write(&bad, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n").unwrap();
    let r = run(&["asset", "--library", s(&lib), "--ply", s(&bad)]);
    let err = String::from_utf8_lossy(&r.stderr).into_owned();
    refused(r, &["no `y` property"]);
    assert_eq!(err.matches("bad.ply").count(), 1, "{err}");
}

#[test]
fn demo_names_a_bad_scene_json_by_the_input() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = synth(tmp.path(), "s", "10");
    let file = scene.join("scene.json");
    let text = std::fs::read_to_string(&file).unwrap();
    std::fs::write(&file, text.replacen("\"frames\"", "\"frames_gone\"", 1)).unwrap();
    let r = run(&["demo", "--input", s(&scene), "--out", s(&tmp.path().join("demo"))]);
    let err = String::from_utf8_lossy(&r.stderr).into_owned();
    refused(r, &[&format!("{}: at `.`: missing field `frames`", file.display())]);
    // The staging folder sits in the demo's output folder.
    assert!(!err.contains("demo/"), "{err}");
}
