//! Every command that reads a model directory (`run`, `video`, `render`, `replace`, `asset
//! --from-model`) refuses the same hostile `model.json` with exit 2, naming the field: a
//! `background_file` outside the model folder, an actor file through `..`, two entries for one
//! track, a zero scale; and those that also read a scene (`run`, `video`, `render`) a model trained
//! on another scene. Before, only `render` and `eval-recon` refused some of these.

use recon::model::{Actor, SceneModel};
use recon::model_io::{write_model, ModelRecord};
use recon::sky::Sky;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

/// An edit of `model.json` and the field its refusal names.
type Case = (Box<dyn Fn(&mut Value)>, &'static str);

fn carla_gs(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

fn gaussians() -> splat::Gaussians {
    let mut g = splat::Gaussians::empty(0);
    for i in 0..8 {
        g.means.push([i as f64 * 0.2 - 0.8, 0.0, 0.0]);
        g.log_scales.push([-1.5; 3]);
        g.rotations.push([1.0, 0.0, 0.0, 0.0]);
        g.opacity_logits.push(3.0);
        g.sh.extend([0.3, -0.2, -0.2]);
    }
    g
}

fn scene_and_model(dir: &Path) -> (PathBuf, PathBuf) {
    let scene_dir = dir.join("scene");
    let cfg = synth::SynthConfig { frames: 4, cameras: 1, width: 32, height: 24, seed: 1, ..Default::default() };
    synth::synthesize(&cfg, &scene_dir, &mut |_, _| {}).unwrap();
    let scene = scene::load_scene(&scene_dir).unwrap();
    let actors = scene
        .tracks
        .iter()
        .map(|t| Actor { track_id: t.id.clone(), size_lwh: t.median_size_lwh(), gaussians: gaussians() })
        .collect();
    let model = SceneModel { antialiased: false, background: gaussians(), actors, sky: Sky::new(2, [0.5, 0.6, 0.8]) };
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

#[test]
fn every_model_reader_refuses_the_same_hostile_records() {
    let tmp = tempfile::tempdir().unwrap();
    let (scene_dir, model) = scene_and_model(tmp.path());
    let good: Value = serde_json::from_slice(&std::fs::read(model.join("model.json")).unwrap()).unwrap();
    let elsewhere = tmp.path().join("elsewhere.ply");
    std::fs::copy(model.join("background.ply"), &elsewhere).unwrap();
    let abs = elsewhere.to_str().unwrap().to_string();
    let cases: Vec<Case> = vec![
        (Box::new(move |v| v["background_file"] = abs.clone().into()), "`background_file`"),
        (Box::new(|v| v["actors"][0]["file"] = "../elsewhere.ply".into()), "`actors[0].file`"),
        (Box::new(|v| v["actors"][1]["track_id"] = v["actors"][0]["track_id"].clone()), "`actors[1].track_id`"),
        (Box::new(|v| v["scale"] = 0.0.into()), "`scale` is 0"),
    ];
    let p = |x: &Path| x.to_str().unwrap().to_string();
    let (s, m) = (p(&scene_dir), p(&model));
    let out = tmp.path().join("out");
    let o = p(&out);
    let lib = p(&tmp.path().join("lib"));
    let missing = p(&tmp.path().join("executed.json"));
    let png = format!("{o}.png");
    let mp4 = format!("{o}.mp4");
    let commands: Vec<Vec<&str>> = vec![
        vec!["run", &s, "--model", &m, "--out", &o],
        vec!["video", "--scene", &s, "--model", &m, "--out", &mp4, &missing],
        vec!["render", &m, "--scene", &s, "--camera", "FRONT", "--frame", "0", "--out", &png],
        vec!["replace", &m, "--track", "lead-1", "--asset", "auto", "--library", &lib, "--out", &o],
        vec!["asset", "--library", &lib, "--from-model", &m, "--track", "lead-1", "--name", "x"],
    ];
    for (edit, field) in &cases {
        let mut v = good.clone();
        edit(&mut v);
        std::fs::write(model.join("model.json"), serde_json::to_vec_pretty(&v).unwrap()).unwrap();
        for args in &commands {
            let r = carla_gs(args);
            let err = String::from_utf8_lossy(&r.stderr);
            assert_eq!(r.status.code(), Some(2), "{} with {field}: {err}", args[0]);
            assert!(err.contains("model.json") && err.contains(field), "{} with {field}: {err}", args[0]);
            assert!(!out.exists(), "{} with {field} wrote {o}", args[0]);
        }
    }
    // A model of another scene: the commands that also read a scene refuse it (`run` and `video`
    // drew it before).
    let mut v = good.clone();
    v["scene_name"] = "another street".into();
    std::fs::write(model.join("model.json"), serde_json::to_vec_pretty(&v).unwrap()).unwrap();
    for args in &commands[..3] {
        let r = carla_gs(args);
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{} with another scene's model: {err}", args[0]);
        assert!(err.contains("`scene_name`") && err.contains("another scene"), "{}: {err}", args[0]);
        assert!(!out.exists(), "{} with another scene's model wrote {o}", args[0]);
    }
}
