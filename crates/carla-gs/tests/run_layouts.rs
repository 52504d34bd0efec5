//! `run` refuses a video layout the scene cannot show before it plans anything or touches `--out`
//! (exit 2, naming the scene's cameras); the default `compare:FRONT,front3` resolves to the
//! scene's own front cameras (`render::layout`, whose unit tests cover each dataset's names).

use std::path::Path;
use std::process::Command;

fn carla_gs(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn a_camera_the_scene_lacks_is_refused_before_planning() {
    let tmp = tempfile::tempdir().unwrap();
    let (scene, model, out) = (tmp.path().join("s"), tmp.path().join("m"), tmp.path().join("run"));
    let synth = ["synth", "--out", s(&scene), "--frames", "40", "--width", "32", "--height", "24", "--cameras", "1"];
    assert!(carla_gs(&synth).status.success());
    assert!(carla_gs(&["train", s(&scene), "--out", s(&model), "--iters", "2"]).status.success());
    let run = |layouts: &str| {
        carla_gs(&[
            "run",
            s(&scene),
            "--model",
            s(&model),
            "--behavior",
            "sudden_cut_in",
            "--out",
            s(&out),
            "--layouts",
            layouts,
            "--fps",
            "2",
            "--scale",
            "0.5",
        ])
    };
    let o = run("compare:FRONT,single:REAR");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("`REAR`") && err.contains("FRONT"), "{err}");
    assert!(!out.exists(), "nothing is written before the refusal");
    // The same run with layouts the scene has goes through; `front` (not the scene's name for
    // it) is its camera FRONT, and the videos are named after it.
    let o = run("compare:front,front3");
    assert_eq!(o.status.code(), Some(0), "{}", String::from_utf8_lossy(&o.stderr));
    let run: serde_json::Value = serde_json::from_slice(&std::fs::read(out.join("run.json")).unwrap()).unwrap();
    let layouts: Vec<&str> = run["videos"].as_array().unwrap().iter().map(|v| v["layout"].as_str().unwrap()).collect();
    assert_eq!(layouts, ["compare-FRONT", "front3"]);
}
