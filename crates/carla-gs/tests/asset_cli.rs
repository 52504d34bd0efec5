//! `carla-gs asset` and `carla-gs replace`: a library is filled from the three sources (a
//! synthetic vehicle, an actor of a model, a user's y-up PLY), `replace --asset auto` writes a
//! new model directory with the actor swapped for the real asset (never the track's own) and the
//! alignment report, and bad requests exit 2 naming what is wrong.

use recon::model::{Actor, SceneModel};
use recon::model_io::{load_model, write_model, ModelRecord};
use recon::sky::Sky;
use std::path::Path;
use std::process::Command;

fn carla_gs(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

/// Opaque Gaussians on a grid filling a box of `size`, with a bump at the front (+x) so the
/// shape is not symmetric.
fn box_gaussians(size: [f64; 3]) -> splat::Gaussians {
    let mut g = splat::Gaussians::empty(0);
    let n = 8;
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let f = |a: usize, s: f64| (a as f64 + 0.5) / n as f64 * s - s / 2.0;
                let (x, y, z) = (f(i, size[0]), f(j, size[1]), f(k, size[2]));
                if x > 0.2 * size[0] && z > 0.1 * size[2] {
                    continue;
                }
                g.means.push([x, y, z]);
                g.log_scales.push([(size[0] / 20.0).ln(); 3]);
                g.rotations.push([1.0, 0.0, 0.0, 0.0]);
                g.opacity_logits.push(4.0);
                g.sh.extend([0.3, -0.2, -0.2]);
            }
        }
    }
    g
}

fn model_dir(dir: &Path) -> std::path::PathBuf {
    let scene_dir = dir.join("scene");
    let cfg = synth::SynthConfig { frames: 2, cameras: 1, width: 16, height: 12, seed: 1, ..Default::default() };
    synth::synthesize(&cfg, &scene_dir, &mut |_, _| {}).unwrap();
    let scene = scene::load_scene(&scene_dir).unwrap();
    let actors = scene
        .tracks
        .iter()
        .map(|t| {
            let size = t.median_size_lwh();
            Actor { track_id: t.id.clone(), size_lwh: size, gaussians: box_gaussians(size) }
        })
        .collect();
    let model = SceneModel {
        antialiased: false,
        background: box_gaussians([1.0; 3]),
        actors,
        sky: Sky::new(2, [0.5, 0.6, 0.8]),
    };
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

#[test]
fn library_sources_and_replace_auto() {
    let dir = tempfile::tempdir().unwrap();
    let model = model_dir(dir.path());
    let lib = dir.path().join("assets");
    let p = |x: &Path| x.to_str().unwrap().to_string();
    let ok = |out: std::process::Output| {
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stdout).to_string()
    };
    ok(carla_gs(&["asset", "--library", &p(&lib), "--from-synth", "van", "--voxel", "0.2"]));
    ok(carla_gs(&["asset", "--library", &p(&lib), "--from-model", &p(&model), "--track", "lead-1", "--name", "lead"]));
    // A user's PLY exported y-up: 4 m along x, 1 m along y (its up), 2 m along z.
    let mut g = box_gaussians([4.0, 1.0, 2.0]);
    g.means.iter_mut().for_each(|m| m[1] += 7.0);
    let ply = dir.path().join("yup.ply");
    splat::ply::write_ply(&ply, &g).unwrap();
    ok(carla_gs(&["asset", "--library", &p(&lib), "--ply", &p(&ply), "--up", "y"]));
    let index: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(lib.join("index.json")).unwrap()).unwrap();
    let names: Vec<&str> = index["assets"].as_array().unwrap().iter().map(|a| a["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["synth-van", "lead", "yup"]);
    let yup = &index["assets"][2];
    assert_eq!(yup["up"], "y");
    // Turned to z up: the 1 m along y became the height, the 2 m along z the width.
    assert!((yup["size_lwh"][2].as_f64().unwrap() - 0.875).abs() < 0.01, "{yup}");
    assert!((yup["size_lwh"][1].as_f64().unwrap() - 1.75).abs() < 0.01, "{yup}");
    assert_eq!(index["assets"][0]["source"]["kind"], "synth");
    // The same name again is refused.
    let again = carla_gs(&["asset", "--library", &p(&lib), "--ply", &p(&ply), "--up", "y"]);
    assert_eq!(again.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&again.stderr).contains("asset `yup`"));

    let out = dir.path().join("replaced");
    let text = ok(carla_gs(&[
        "replace",
        &p(&model),
        "--track",
        "parked-8",
        "--asset",
        "auto",
        "--library",
        &p(&lib),
        "--out",
        &p(&out),
    ]));
    assert!(text.contains("candidate") && text.contains("Chamfer"), "{text}");
    // `auto` takes the real asset (another actor of a model) over the synthetic van and the
    // user's PLY, and says why.
    assert!(text.contains("auto: `lead`, the real vehicle asset nearest"), "{text}");
    let (before, _) = load_model(&model).unwrap();
    let (after, _) = load_model(&out).unwrap();
    assert_eq!(before.actors.len(), after.actors.len());
    let i = after.actors.iter().position(|a| a.track_id == "parked-8").unwrap();
    let lead = before.actors.iter().find(|a| a.track_id == "lead-1").unwrap();
    assert_ne!(after.actors[i].gaussians.means, before.actors[i].gaussians.means);
    assert_eq!(after.actors[i].gaussians.len(), lead.gaussians.len(), "the lead car's Gaussians");
    let reps: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("replacements.json")).unwrap()).unwrap();
    assert_eq!(reps[0]["alignment"]["candidates"].as_array().unwrap().len(), 4);
    assert_eq!(reps[0]["auto"]["asset"], "lead");
    assert_eq!(reps[0]["auto"]["real"], true);
    // Never the track's own asset: `lead-1` replaced by `auto` falls back to the synthetic van
    // (the user's PLY is of the same tier and farther in size).
    let own = dir.path().join("replaced-own");
    let text = ok(carla_gs(&[
        "replace",
        &p(&model),
        "--track",
        "lead-1",
        "--asset",
        "auto",
        "--library",
        &p(&lib),
        "--out",
        &p(&own),
    ]));
    assert!(text.contains("auto: `synth-van`, no real vehicle asset"), "{text}");
    assert!(!out.join("checkpoint.bin").exists());

    let same = carla_gs(&[
        "replace",
        &p(&model),
        "--track",
        "lead-1",
        "--asset",
        "lead",
        "--library",
        &p(&lib),
        "--out",
        &p(&model),
    ]);
    assert_eq!(same.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&same.stderr).contains("is the input model directory"));
    let missing = carla_gs(&[
        "replace",
        &p(&model),
        "--track",
        "nobody",
        "--asset",
        "lead",
        "--library",
        &p(&lib),
        "--out",
        &p(&out.with_extension("missing")),
    ]);
    assert_eq!(missing.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&missing.stderr).contains("nobody"));
    assert!(!out.with_extension("missing").exists(), "a failed replace left its --out");
}
