//! `carla-gs train`, `eval-recon` and `render` end to end on a small generated street: a run
//! killed (SIGKILL) after a checkpoint and resumed ends exactly where an uninterrupted run ends;
//! evaluation and a sideways-shifted render work from the model directory alone; bad arguments
//! name what is wrong.

use std::path::Path;
use std::process::{Command, Output};
use std::time::{Duration, Instant};

fn carla_gs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn ok(out: Output) -> String {
    assert!(out.status.success(), "stderr: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

const CONFIG: &str = "iterations = 30\nscale = 1.0\ncheckpoint_interval = 5\ncheckpoint_min_seconds = 0\nsky_res = 4\n\
[densify]\nfrom = 0.1\ninterval = 5\nuntil = 0.8\nopacity_reset_every = 0.6\n\
[init]\nmax_points = 3000\nactor_points = 200\n";

#[test]
fn killed_training_resumes_to_the_same_model_and_renders() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("scene");
    ok(carla_gs(&["synth", "--out", s(&scene), "--frames", "9", "--cameras", "2", "--width", "96", "--height", "64"]));
    let cfg = tmp.path().join("cfg.toml");
    std::fs::write(&cfg, CONFIG).unwrap();
    let whole = tmp.path().join("whole");
    ok(carla_gs(&["train", s(&scene), "--out", s(&whole), "--config", s(&cfg)]));
    // Start again and kill it hard once a checkpoint exists.
    let killed = tmp.path().join("killed");
    let mut child = Command::new(env!("CARGO_BIN_EXE_carla-gs"))
        .args(["train", s(&scene), "--out", s(&killed), "--config", s(&cfg)])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while !killed.join("checkpoint.bin").exists() && t0.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    ok(carla_gs(&["train", s(&scene), "--out", s(&killed), "--config", s(&cfg), "--resume"]));
    let a = std::fs::read(whole.join("checkpoint.bin")).unwrap();
    let b = std::fs::read(killed.join("checkpoint.bin")).unwrap();
    assert!(a == b, "resumed training state differs from the uninterrupted run");
    assert_eq!(
        std::fs::read(whole.join("background.ply")).unwrap(),
        std::fs::read(killed.join("background.ply")).unwrap()
    );

    let report = ok(carla_gs(&["eval-recon", s(&whole), s(&scene), "--json"]));
    let v: serde_json::Value = serde_json::from_str(&report).unwrap();
    assert_eq!(v["views"], 4, "frames 0 and 8 of two cameras are held out");
    assert!(v["psnr"]["mean"].as_f64().unwrap() > 10.0);
    let png = tmp.path().join("shifted.png");
    let out = ok(carla_gs(&[
        "render",
        s(&whole),
        "--scene",
        s(&scene),
        "--camera",
        "FRONT",
        "--frame",
        "3",
        "--shift-m",
        "1.0",
        "--out",
        s(&png),
    ]));
    assert!(out.contains("+1.00 m"), "{out}");
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (96, 64));

    // Bad arguments are named.
    let out =
        carla_gs(&["render", s(&whole), "--scene", s(&scene), "--camera", "REAR", "--frame", "3", "--out", s(&png)]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--camera REAR"));
    std::fs::write(&cfg, "[loss]\nnormals = 1.0\n").unwrap();
    let out = carla_gs(&["train", s(&scene), "--out", s(&tmp.path().join("x")), "--config", s(&cfg)]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("normals"));
}

/// `demo` and `train` with `--device cuda` stop with a clear error on a machine without CUDA,
/// before doing any work (skipped, with a note, where a GPU is present: there the commands would run).
#[test]
fn device_cuda_without_a_gpu_is_a_clear_error() {
    if splat_cuda::Gpu::new().is_ok() {
        println!("SKIP: a CUDA GPU is present; the no-GPU error cannot be seen here");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let none = tmp.path().join("none");
    let n = s(&none);
    for args in [vec!["demo", "--out", n, "--device", "cuda"], vec!["train", n, "--out", n, "--device", "cuda"]] {
        let out = carla_gs(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} succeeded");
        assert!(err.contains("cuda") || err.contains("CUDA"), "{args:?}: {err}");
        assert!(!none.exists(), "{args:?} wrote {n} before failing");
    }
}
