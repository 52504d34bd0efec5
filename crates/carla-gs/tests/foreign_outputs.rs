//! Fuzzing findings H4, M3b-d, M5, M14: a command never deletes or overwrites what is not its own
//! output, nor its own inputs, and says so before any work (exit 2, naming the path); `run` with
//! no case exits 3 with `run.json` saying why. S = `synth --frames 40 --width 32 --height 24
//! --cameras 1`, M = `train S --iters 2`, E = `simulate` of a `reason` plan, in a temporary directory.

use std::ffi::OsStr;
use std::path::Path;
use std::process::{Command, Output};

fn carla_gs<A: AsRef<OsStr>>(args: &[A]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[track_caller]
fn code(o: &Output, want: i32, needles: &[&str]) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(want), "{err}");
    for n in needles {
        assert!(err.contains(n), "expected `{n}` in: {err}");
    }
}

#[test]
fn foreign_files_and_inputs_are_never_replaced() {
    let tmp = tempfile::tempdir().unwrap();
    let d = tmp.path();
    let (scene, model, plan, exec) = (d.join("S"), d.join("M"), d.join("plan.json"), d.join("exec.json"));
    let synth = ["synth", "--out", s(&scene), "--frames", "40", "--width", "32", "--height", "24", "--cameras", "1"];
    code(&carla_gs(&synth), 0, &[]);
    code(&carla_gs(&["train", s(&scene), "--out", s(&model), "--iters", "2"]), 0, &[]);
    let reason = ["reason", s(&scene), "--t0", "1", "--behavior", "sudden_cut_in", "--agent", "planner"];
    code(&carla_gs(&[&reason[..], &["--out", s(&plan)]].concat()), 0, &[]);
    let simulate = ["simulate", s(&plan), "--scene", s(&scene)];
    code(&carla_gs(&[&simulate[..], &["--out", s(&exec)]].concat()), 0, &[]);
    let notes = d.join("notes.txt");
    std::fs::write(&notes, b"a person's notes").unwrap();

    // H4: a frames directory with anything but our frames is refused, with or without --force.
    let frames = d.join("X_frames");
    std::fs::create_dir(&frames).unwrap();
    std::fs::write(frames.join("IMPORTANT.txt"), b"keep").unwrap();
    let video = ["video", s(&exec), "--scene", s(&scene), "--model", s(&model), "--layouts", "single:FRONT"];
    let video = |extra: &[&str]| carla_gs(&[&video[..], extra].concat());
    let x = d.join("X.mp4");
    for force in [&[][..], &["--force"][..]] {
        code(&video(&[&["--png", "--out", s(&x)][..], force].concat()), 2, &["X_frames", "IMPORTANT.txt"]);
        assert_eq!(std::fs::read(frames.join("IMPORTANT.txt")).unwrap(), b"keep");
    }
    // A file that is not an MP4 needs --force; an input never; our own frames are replaced.
    code(&video(&["--out", s(&notes)]), 2, &["notes.txt", "--force"]);
    code(&video(&["--force", "--out", s(&exec)]), 2, &["exec.json", "input"]);
    code(&video(&["--force", "--png", "--out", s(&scene.join("scene.json"))]), 2, &["input"]);
    let y = d.join("Y.mp4");
    code(&video(&["--png", "--out", s(&y)]), 0, &[]);
    code(&video(&["--png", "--out", s(&y)]), 0, &[]);
    // M14: a directory at --out is refused before ffmpeg starts, and no temporary file is left.
    let dir = d.join("D.mp4");
    std::fs::create_dir(&dir).unwrap();
    code(&video(&["--out", s(&dir)]), 2, &["D.mp4", "directory"]);
    assert!(!d.join(".D.mp4.tmp").exists());

    // M3b-d: own inputs are refused even with --force; foreign files without it.
    let render = ["render", s(&model), "--scene", s(&scene), "--camera", "FRONT", "--frame", "0"];
    let scene_json = std::fs::read(scene.join("scene.json")).unwrap();
    code(&carla_gs(&[&render[..], &["--force", "--out", s(&scene.join("scene.json"))]].concat()), 2, &["input"]);
    assert_eq!(std::fs::read(scene.join("scene.json")).unwrap(), scene_json);
    code(&carla_gs(&[&render[..], &["--out", s(&notes)]].concat()), 2, &["notes.txt", "--force"]);
    code(&carla_gs(&[&simulate[..], &["--force", "--out", s(&plan)]].concat()), 2, &["plan.json", "input"]);
    code(&carla_gs(&[&simulate[..], &["--out", s(&notes)]].concat()), 2, &["notes.txt"]);
    code(&carla_gs(&[&reason[..], &["--out", s(&exec)]].concat()), 2, &["exec.json"]);
    code(&carla_gs(&["export-xodr", s(&scene), "--out", s(&notes)]), 2, &["notes.txt"]);
    assert_eq!(std::fs::read(&notes).unwrap(), b"a person's notes");
    // Our own previous outputs are still replaced as before.
    code(&carla_gs(&[&reason[..], &["--out", s(&plan)]].concat()), 0, &[]);
    code(&carla_gs(&[&simulate[..], &["--out", s(&exec)]].concat()), 0, &[]);

    // M5: run with no case exits 3 and run.json lists why; M6: an out-of-range --ttc is no case.
    let run = ["run", s(&scene), "--model", s(&model), "--behavior", "sudden_cut_in", "--t0", "1"];
    let out = d.join("run");
    let args = [&run[..], &["--adversary", "no-such-track", "--out", s(&out), "--fps", "2"]].concat();
    code(&carla_gs(&args), 3, &["no case", "run.json"]);
    let summary: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("run.json")).unwrap()).unwrap();
    assert!(summary["attempts"][0]["detail"].as_str().unwrap_or("").contains("no-such-track"), "{summary}");
    assert!(summary["no_case"].is_string(), "{summary}");
    let out2 = d.join("run2");
    code(&carla_gs(&[&run[..], &["--ttc", "1e9", "--out", s(&out2)]].concat()), 3, &["--ttc"]);
    code(
        &carla_gs(&[
            "run",
            s(&scene),
            "--model",
            s(&model),
            "--behavior",
            "sudden_cut_in",
            "--t0",
            "NaN",
            "--out",
            s(&out2),
        ]),
        2,
        &["--t0"],
    );
    assert!(!out2.exists());
}
