//! `carla-gs synth` end to end at a small size: a loadable scene with GT maps and a preview,
//! and bad settings: exit code 2, a message naming the argument, and no output directory.

use std::path::Path;
use std::process::{Command, Output};

fn carla_gs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn synth_writes_a_scene_and_preview() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("scene");
    let args =
        ["synth", "--out", s(&dir), "--frames", "5", "--width", "96", "--height", "64", "--seed", "2", "--preview"];
    let out = carla_gs(&args);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let scene = scene::load_scene(&dir).unwrap();
    assert_eq!(scene.frames.len(), 5);
    assert_eq!(scene.cameras.len(), 3);
    assert!(scene.tracks.len() >= 6);
    assert!(dir.join("preview.png").is_file());
    assert!(dir.join("gt/gt.json").is_file());
    assert_eq!(synth::gt::read_f32(&dir.join("gt/000004_FRONT.depth.f32.gz")).unwrap().len(), 96 * 64);
    // `inspect` reads it like any scene.
    assert!(carla_gs(&["inspect", s(&dir)]).status.success());
    // Again without --force: refused, the scene untouched.
    let again = carla_gs(&args);
    assert_eq!(again.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&again.stderr).contains("--force"));
    let mut forced = args.to_vec();
    forced.push("--force");
    assert!(carla_gs(&forced).status.success());
}

#[test]
fn synth_rejects_bad_settings() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("scene");
    for (flag, value) in [("--cameras", "0"), ("--cameras", "6"), ("--width", "0"), ("--frames", "0")] {
        let out = carla_gs(&["synth", "--out", s(&dir), flag, value]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains(flag), "expected {flag} in: {err}");
        assert!(!dir.exists());
    }
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0);
}
