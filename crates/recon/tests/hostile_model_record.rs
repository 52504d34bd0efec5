//! A hostile `model.json` is refused by the one loader every command uses
//! (`recon::model_io::load_model`, and `load_model_for_scene` for commands given a scene), naming
//! the field: files outside the model folder (absolute, `..`, a symbolic link out), two entries
//! for one track, a zero, negative or NaN scale, and a model trained on another scene (another
//! name, an actor that is not a track of it, or another `scene.json` under the same name).

use recon::model::{Actor, SceneModel};
use recon::model_io::{load_model, load_model_for_scene, write_model, ModelRecord};
use recon::sky::Sky;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn tiny_gaussians() -> splat::Gaussians {
    let mut g = splat::Gaussians::empty(0);
    for i in 0..4 {
        g.means.push([i as f64 * 0.1, 0.0, 0.0]);
        g.log_scales.push([-2.0; 3]);
        g.rotations.push([1.0, 0.0, 0.0, 0.0]);
        g.opacity_logits.push(2.0);
        g.sh.extend([0.1, 0.2, 0.3]);
    }
    g
}

/// A synthetic scene in `<dir>/<name>` and a model of it in `<dir>/model`.
fn scene_and_model(dir: &Path, seed: u64, name: &str) -> (PathBuf, PathBuf) {
    let scene_dir = dir.join(name);
    let cfg = synth::SynthConfig { frames: 2, cameras: 1, width: 16, height: 12, seed, ..Default::default() };
    synth::synthesize(&cfg, &scene_dir, &mut |_, _| {}).unwrap();
    let scene = scene::load_scene(&scene_dir).unwrap();
    let actors = scene
        .tracks
        .iter()
        .take(2)
        .map(|t| Actor { track_id: t.id.clone(), size_lwh: t.median_size_lwh(), gaussians: tiny_gaussians() })
        .collect();
    let model =
        SceneModel { antialiased: false, background: tiny_gaussians(), actors, sky: Sky::new(2, [0.5, 0.6, 0.8]) };
    let mut record: ModelRecord = serde_json::from_value(serde_json::json!({
        "format": "", "scene_name": scene.name, "scene_dir": scene_dir, "backend": "cpu", "iterations": 0,
        "held_out_every": 8, "scale": 0.5, "extent": 10.0, "background_file": "", "background_gaussians": 0,
        "actors": [], "sky_res": 2, "train_seconds": 0.0, "iterations_per_second": 0.0,
        "last_loss": recon::loss::LossParts::default(),
    }))
    .unwrap();
    let out = dir.join("model");
    write_model(&out, &model, &mut record, &recon::TrainConfig::default(), None).unwrap();
    (scene_dir, out)
}

fn read(model: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(model.join("model.json")).unwrap()).unwrap()
}

fn write(model: &Path, v: &Value) {
    std::fs::write(model.join("model.json"), serde_json::to_vec_pretty(v).unwrap()).unwrap();
}

/// `model.json` edited by `edit` is refused by `load_model` with an error holding every needle.
fn refused(model: &Path, good: &Value, edit: impl Fn(&mut Value), needles: &[&str]) {
    let mut v = good.clone();
    edit(&mut v);
    write(model, &v);
    let e = load_model(model).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("model.json"), "{e}");
    for n in needles {
        assert!(e.contains(n), "expected {n:?} in: {e}");
    }
    write(model, good);
}

#[test]
fn files_outside_the_model_folder_are_refused_naming_the_field() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, model) = scene_and_model(tmp.path(), 1, "scene");
    let good = read(&model);
    load_model(&model).unwrap();
    // A readable PLY outside the model folder: before, every case below loaded it.
    let outside = tmp.path().join("elsewhere");
    std::fs::create_dir_all(&outside).unwrap();
    std::fs::copy(model.join("background.ply"), outside.join("x.ply")).unwrap();
    let abs = outside.join("x.ply").to_str().unwrap().to_string();
    for bad in [abs.as_str(), "../elsewhere/x.ply", "actors/../../elsewhere/x.ply", "./background.ply", ""] {
        let b = bad.to_string();
        refused(&model, &good, |v| v["background_file"] = b.clone().into(), &["`background_file`", "plain relative"]);
        refused(&model, &good, |v| v["actors"][1]["file"] = b.clone().into(), &["`actors[1].file`", "plain relative"]);
    }
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(&outside, model.join("out")).unwrap();
        refused(&model, &good, |v| v["background_file"] = "out/x.ply".into(), &["`background_file`", "symbolic link"]);
    }
}

#[test]
fn duplicate_tracks_and_bad_scales_are_refused_naming_the_field() {
    let tmp = tempfile::tempdir().unwrap();
    let (_, model) = scene_and_model(tmp.path(), 1, "scene");
    let good = read(&model);
    let dup = |v: &mut Value| {
        let a = v["actors"][0].clone();
        v["actors"].as_array_mut().unwrap().push(a);
    };
    refused(&model, &good, dup, &["`actors[2].track_id`", "also `actors[0].track_id`"]);
    let same_id = |v: &mut Value| v["actors"][1]["track_id"] = v["actors"][0]["track_id"].clone();
    refused(&model, &good, same_id, &["`actors[1].track_id`", "one entry per track"]);
    let same_file = |v: &mut Value| v["actors"][1]["file"] = v["actors"][0]["file"].clone();
    refused(&model, &good, same_file, &["`actors[1].file`", "also `actors[0].file`"]);
    refused(&model, &good, |v| v["actors"][0]["track_id"] = "".into(), &["`actors[0].track_id` is empty"]);
    for scale in [0.0, -0.5, 2.0, 1e300] {
        refused(&model, &good, |v| v["scale"] = scale.into(), &["`scale`", "(0, 1]"]);
    }
    // JSON has no NaN: serde_json writes a NaN as null; the text `NaN` is not JSON either.
    let mut text = String::from_utf8(std::fs::read(model.join("model.json")).unwrap()).unwrap();
    text = text.replace("\"scale\": 0.5", "\"scale\": 1e999");
    std::fs::write(model.join("model.json"), &text).unwrap();
    let e = load_model(&model).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("scale"), "{e}");
    write(&model, &good);
    refused(&model, &good, |v| v["extent"] = (-1.0).into(), &["`extent`"]);
    refused(&model, &good, |v| v["sky_res"] = 0.into(), &["`sky_res` is 0"]);
    refused(&model, &good, |v| v["actors"][0]["size_lwh"][1] = (-1.0).into(), &["`actors[0].size_lwh`"]);
    load_model(&model).unwrap();
}

#[test]
fn a_model_of_another_scene_is_refused_naming_the_field() {
    let tmp = tempfile::tempdir().unwrap();
    let (scene_dir, model) = scene_and_model(tmp.path(), 1, "scene");
    let scene = scene::load_scene(&scene_dir).unwrap();
    load_model_for_scene(&model, &scene_dir, &scene).unwrap();
    let good = read(&model);
    // Another scene altogether.
    let other_dir = tmp.path().join("other");
    let cfg = synth::SynthConfig { frames: 2, cameras: 1, width: 16, height: 12, seed: 2, ..Default::default() };
    synth::synthesize(&cfg, &other_dir, &mut |_, _| {}).unwrap();
    let other = scene::load_scene(&other_dir).unwrap();
    assert_ne!(other.name, scene.name);
    let e = load_model_for_scene(&model, &other_dir, &other).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("model.json") && e.contains("`scene_name`") && e.contains("another scene"), "{e}");
    // Same name, an actor the scene does not have.
    let mut v = good.clone();
    v["actors"][1]["track_id"] = "ghost-99".into();
    write(&model, &v);
    let e = load_model_for_scene(&model, &scene_dir, &scene).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("`actors[1].track_id` \"ghost-99\" is not a track of scene"), "{e}");
    write(&model, &good);
    // The shared checks apply here too.
    let mut v = good.clone();
    v["background_file"] = "../x.ply".into();
    write(&model, &v);
    let e = load_model_for_scene(&model, &scene_dir, &scene).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("`background_file`"), "{e}");
    write(&model, &good);
}

#[test]
fn a_model_trained_on_an_edited_scene_of_the_same_name_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let scene_dir = tmp.path().join("s");
    let cfg = synth::SynthConfig { frames: 8, cameras: 1, width: 24, height: 16, seed: 1, ..Default::default() };
    synth::synthesize(&cfg, &scene_dir, &mut |_, _| {}).unwrap();
    let model = tmp.path().join("m");
    let train_cfg = recon::TrainConfig { iterations: 2, ..Default::default() };
    let none = |_: &recon::data::View| Ok(None);
    let req = recon::session::TrainRequest {
        scene_dir: &scene_dir,
        out_dir: &model,
        cfg: train_cfg,
        resume: false,
        force: recon::out_dir::ForceMode::Refuse,
        stop_after: None,
        priors: &none,
    };
    recon::session::train(req, recon::backend::Cpu, &indicatif::ProgressBar::hidden()).unwrap();
    let scene = scene::load_scene(&scene_dir).unwrap();
    load_model_for_scene(&model, &scene_dir, &scene).unwrap();
    // Same name, another scene.json (one more space): the checkpoint's fingerprint differs.
    let file = scene_dir.join("scene.json");
    let mut text = std::fs::read(&file).unwrap();
    text.push(b'\n');
    std::fs::write(&file, &text).unwrap();
    let e = load_model_for_scene(&model, &scene_dir, &scene).map(|_| ()).unwrap_err().to_string();
    assert!(e.contains("checkpoint.bin") && e.contains("`scene_fingerprint`"), "{e}");
    // The scene-free loader still reads it (render, asset and replace do not name a scene).
    load_model(&model).unwrap();
}
