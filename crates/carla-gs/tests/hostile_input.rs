//! Issue 28 (hostile input), the rows about reasoning, simulation, metrics, rendering, assets and
//! OpenDRIVE export: each hostile argument or edited file exits with code 2 naming the argument
//! or field, writes nothing, and neither panics nor aborts; a well-formed request for which no
//! case is possible exits with code 3. Scenes are small generated streets in a temporary
//! directory (S40 = `synth --frames 40 --width 32 --height 24 --cameras 1`, as in the issue).

use recon::model::SceneModel;
use recon::model_io::{write_model, ModelRecord};
use recon::sky::Sky;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn carla_gs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Exit code 2 with `needle` in the message.
fn refused(out: Output, needle: &str) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "expected a refusal naming `{needle}`: {stderr}");
    assert!(stderr.contains(needle), "expected `{needle}` in: {stderr}");
}

fn ok(out: Output) -> String {
    assert_eq!(out.status.code(), Some(0), "stderr: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// S40 in `dir/name`.
fn s40(dir: &Path, name: &str) -> PathBuf {
    let scene = dir.join(name);
    ok(carla_gs(&["synth", "--out", s(&scene), "--frames", "40", "--width", "32", "--height", "24", "--cameras", "1"]));
    scene
}

/// `scene.json` of `scene` edited by `edit`, in place.
fn edit_scene(scene: &Path, edit: impl FnOnce(&mut Value)) {
    let path = scene.join("scene.json");
    let mut j: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    edit(&mut j);
    std::fs::write(&path, serde_json::to_vec(&j).unwrap()).unwrap();
}

/// Rows 3, 9 and 20, and the note on exit codes: `reason` on S40.
#[test]
fn reason_refuses_bad_input_with_2_and_no_case_with_3() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = s40(tmp.path(), "s40");
    let plan = tmp.path().join("plan.json");
    let reason = |scene: &Path, extra: &[&str]| {
        let base = ["reason", s(scene), "--agent", "planner", "--out", s(&plan)];
        carla_gs(&[&base[..], extra].concat())
    };
    // Bad input: exit 2, nothing written.
    for t0 in ["NaN", "inf", "-5"] {
        refused(reason(&scene, &["--t0", t0, "--behavior", "sudden_cut_in"]), "t0");
        assert!(!plan.exists());
    }
    refused(reason(&scene, &["--t0", "NaN", "--behavior", "sudden_cut_in"]), "--t0 must be a finite number");
    // No case possible for a well-formed request: exit 3, the reason given, nothing written.
    let out = reason(&scene, &["--t0", "1", "--zone", "left", "--behavior", "sudden_cut_in"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(3), "{stderr}");
    assert!(stderr.contains("no case: ") && stderr.contains("never aims at zone left"), "{stderr}");
    assert!(!plan.exists());
    // Done: exit 0 with the file.
    ok(reason(&scene, &["--t0", "1", "--behavior", "sudden_cut_in"]));
    assert!(plan.exists());
    std::fs::remove_file(&plan).unwrap();
    // A lane point at 1e300 m (panicked: capacity overflow) or 1e9 m (asked for 22.6 GB).
    for (k, far) in [1e300, 1e9].into_iter().enumerate() {
        let edited = s40(tmp.path(), &format!("far-{k}"));
        edit_scene(&edited, |j| j["map"]["lanes"][0]["points"][0] = serde_json::json!([far, far, 0.0]));
        refused(reason(&edited, &["--t0", "1", "--behavior", "sudden_cut_in"]), "map.lanes[0].points[0]: coordinate");
        assert!(!plan.exists());
    }
}

/// Rows 7, 18 and 19: `simulate P --fps 1e9` or `--control-dt 1e-9` is refused up front (it ran
/// 30 s and aborted); `metrics` refuses an executed file with x = 1e300 or a step moved 5000 m
/// (it reported success from the stored validity).
#[test]
fn simulate_budget_and_metrics_of_edited_files() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = s40(tmp.path(), "s40");
    let plan = tmp.path().join("plan.json");
    ok(carla_gs(&["reason", s(&scene), "--t0", "1", "--behavior", "sudden_cut_in", "--out", s(&plan)]));
    let exec = tmp.path().join("executed.json");
    let simulate = |extra: &[&str]| {
        carla_gs(&[&["simulate", s(&plan), "--scene", s(&scene), "--out", s(&exec)][..], extra].concat())
    };
    for (flag, value) in [("--fps", "1e9"), ("--control-dt", "1e-9"), ("--fps", "NaN"), ("--control-dt", "0")] {
        let t = std::time::Instant::now();
        refused(simulate(&[flag, value]), &format!("{flag}: "));
        assert!(t.elapsed().as_secs() < 10 && !exec.exists(), "{flag} {value}");
    }
    ok(simulate(&["--fps", "24"]));
    ok(carla_gs(&["metrics", s(&exec)]));
    let good: Value = serde_json::from_slice(&std::fs::read(&exec).unwrap()).unwrap();
    let edited = tmp.path().join("edited.json");
    let metrics_of = |edit: &dyn Fn(&mut Value)| {
        let mut j = good.clone();
        edit(&mut j);
        std::fs::write(&edited, serde_json::to_vec(&j).unwrap()).unwrap();
        carla_gs(&["metrics", s(&edited), "--json"])
    };
    refused(
        metrics_of(&|j| {
            for step in j["steps"].as_array_mut().unwrap() {
                step["x"] = Value::from(1e300);
            }
        }),
        "`steps[0].x`: 1e300 m",
    );
    refused(
        metrics_of(&|j| j["steps"][30]["x"] = Value::from(j["steps"][30]["x"].as_f64().unwrap() + 5000.0)),
        "`steps[30].x`: moved",
    );
}

/// A model of S40 whose every part is one small blob (enough to render), trained on `scene`.
fn model_dir(dir: &Path, scene_dir: &Path) -> PathBuf {
    let scene = scene::load_scene(scene_dir).unwrap();
    let mut blob = splat::Gaussians::empty(0);
    blob.means.push([10.0, 0.0, 1.0]);
    blob.log_scales.push([0.0; 3]);
    blob.rotations.push([1.0, 0.0, 0.0, 0.0]);
    blob.opacity_logits.push(2.0);
    blob.sh.extend([0.3, 0.1, -0.2]);
    let model =
        SceneModel { antialiased: false, background: blob, actors: Vec::new(), sky: Sky::new(2, [0.5, 0.6, 0.8]) };
    let mut record: ModelRecord = serde_json::from_value(serde_json::json!({
        "format": "", "scene_name": scene.name, "scene_dir": scene_dir, "backend": "cpu", "iterations": 0,
        "held_out_every": 8, "scale": 1.0, "extent": 10.0, "background_file": "", "background_gaussians": 0,
        "actors": [], "sky_res": 2, "train_seconds": 0.0, "iterations_per_second": 0.0,
        "last_loss": recon::loss::LossParts::default(),
    }))
    .unwrap();
    let out = dir.join("model");
    write_model(&out, &model, &mut record, &recon::TrainConfig::default(), None).unwrap();
    out
}

/// Rows 5, 6, 15 and 16 (render side): scales that are not positive finite numbers, images past
/// the pixel budget, a NaN shift and another scene are refused before anything is drawn.
#[test]
fn render_refuses_bad_scales_sizes_shifts_and_scenes() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = s40(tmp.path(), "s40");
    let model = model_dir(tmp.path(), &scene);
    let camera = scene::load_scene(&scene).unwrap().cameras[0].name.clone();
    let png = tmp.path().join("view.png");
    let render = |scene: &Path, extra: &[&str]| {
        let base = ["render", s(&model), "--scene", s(scene), "--camera", &camera, "--frame", "0", "--out", s(&png)];
        carla_gs(&[&base[..], extra].concat())
    };
    for scale in ["0", "-2", "NaN", "inf"] {
        refused(render(&scene, &[&format!("--scale={scale}")]), "--scale: must be a positive finite");
        assert!(!png.exists(), "--scale {scale}");
    }
    refused(render(&scene, &["--scale", "2000"]), "more than the 16777216 an image may have");
    refused(render(&scene, &["--shift-m", "NaN"]), "--shift-m must be a finite number");
    let other = s40(tmp.path(), "other");
    edit_scene(&other, |j| j["name"] = "another street".into());
    refused(render(&other, &[]), "the model was trained on another scene");
    assert!(!png.exists());
    ok(render(&scene, &["--scale", "0.5", "--shift-m", "0.5"]));
    assert_eq!(image::open(&png).unwrap().width(), 16);

    // render-ply: a camera of 100000 x 100000 pixels (7.9 GB, then abort) is refused at once.
    let ply = tmp.path().join("m.ply");
    std::fs::copy(model.join("background.ply"), &ply).unwrap();
    let cam = tmp.path().join("cam.json");
    let big = splat::Camera { far: 100.0, ..splat::Camera::at_origin(100_000, 100_000, 50_000.0) };
    std::fs::write(&cam, serde_json::to_vec(&big).unwrap()).unwrap();
    let t = std::time::Instant::now();
    refused(carla_gs(&["render-ply", s(&ply), "--camera", s(&cam), "--out", s(&png)]), "10000000000 pixels");
    assert!(t.elapsed().as_secs() < 10);
}

/// Rows 17 and 21: `asset --colour NaN,0,0` and `export-xodr --lane-width 1e300`.
#[test]
fn asset_colour_and_lane_width_outside_their_ranges() {
    let tmp = tempfile::tempdir().unwrap();
    let lib = tmp.path().join("assets");
    for colour in ["NaN,0,0", "2,0,0", "-0.1,0.5,0.5"] {
        let out = carla_gs(&["asset", "--library", s(&lib), "--from-synth", "sedan", &format!("--colour={colour}")]);
        refused(out, "--colour: expected three numbers r,g,b in [0, 1]");
        assert!(!lib.exists());
    }
    let scene = s40(tmp.path(), "s40");
    let xodr = tmp.path().join("map.xodr");
    for width in ["1e300", "NaN", "0.01"] {
        let out = carla_gs(&["export-xodr", s(&scene), "--out", s(&xodr), "--lane-width", width]);
        refused(out, "--lane-width: must be from 0.5 to 20 m");
        assert!(!xodr.exists());
    }
    ok(carla_gs(&["export-xodr", s(&scene), "--out", s(&xodr), "--lane-width", "3.2"]));
}
