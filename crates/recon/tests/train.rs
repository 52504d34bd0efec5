//! Training on a small synthetic street (generated here, so no shared data is needed): the loss
//! falls, a run stopped at a checkpoint and resumed ends bit-for-bit where an uninterrupted run
//! does, the model directory reads back, and a damaged checkpoint is refused by name.

use indicatif::ProgressBar;
use recon::backend::Cpu;
use recon::out_dir::ForceMode;
use recon::session::{train, TrainRequest};
use recon::TrainConfig;
use std::path::Path;

fn synth_scene(dir: &Path) -> std::path::PathBuf {
    let out = dir.join("scene");
    let cfg = synth::SynthConfig { frames: 9, cameras: 2, width: 96, height: 64, seed: 3, ..Default::default() };
    synth::synthesize(&cfg, &out, &mut |_, _| {}).expect("synthetic scene");
    out
}

fn small_config() -> TrainConfig {
    let mut cfg = TrainConfig {
        iterations: 24,
        scale: 1.0,
        checkpoint_interval: 8,
        checkpoint_min_seconds: 0.0,
        sh_degree_interval: 8,
        ..Default::default()
    };
    cfg.densify.from = 0.15;
    cfg.densify.interval = 5;
    cfg.densify.until = 0.8;
    cfg.densify.opacity_reset_every = 0.6;
    cfg.init.max_points = 3000;
    cfg.init.actor_points = 200;
    cfg.sky_res = 4;
    cfg
}

fn run(
    scene: &Path,
    out: &Path,
    cfg: &TrainConfig,
    resume: bool,
    stop_after: Option<usize>,
) -> recon::session::TrainSummary {
    let none = |_: &recon::data::View| Ok(None);
    let req = TrainRequest {
        scene_dir: scene,
        out_dir: out,
        cfg: cfg.clone(),
        resume,
        force: ForceMode::Refuse,
        stop_after,
        priors: &none,
    };
    train(req, Cpu, &ProgressBar::hidden()).expect("training runs")
}

#[test]
fn resume_matches_an_uninterrupted_run_and_damage_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let scene = synth_scene(dir.path());
    let cfg = small_config();
    let whole = run(&scene, &dir.path().join("whole"), &cfg, false, None);
    assert_eq!(whole.iterations_done, 24);
    let parts = dir.path().join("parts");
    let first = run(&scene, &parts, &cfg, false, Some(13));
    assert_eq!(first.iterations_done, 13);
    let second = run(&scene, &parts, &cfg, true, None);
    assert_eq!(second.iterations_done, 24);
    assert_eq!(second.last_loss, whole.last_loss, "resumed run must reach the same loss");
    let a = recon::checkpoint::load(&dir.path().join("whole/checkpoint.bin")).unwrap();
    let b = recon::checkpoint::load(&parts.join("checkpoint.bin")).unwrap();
    assert_eq!(a, b, "resumed state differs from the uninterrupted one");
    // The model directory reads back with every actor.
    let (model, record) = recon::model_io::load_model(&parts).unwrap();
    assert_eq!(model.actors.len(), record.actors.len());
    assert_eq!(record.iterations, 24);
    assert!(model.background.len() > 100);
    // A different setting is refused on resume.
    let mut other = cfg.clone();
    other.seed = 9;
    let none = |_: &recon::data::View| Ok(None);
    let req = TrainRequest {
        scene_dir: &scene,
        out_dir: &parts,
        cfg: other,
        resume: true,
        force: ForceMode::Refuse,
        stop_after: None,
        priors: &none,
    };
    let err = train(req, Cpu, &ProgressBar::hidden()).expect_err("config mismatch refused").to_string();
    assert!(err.contains("config.toml"), "{err}");
    // A damaged checkpoint is refused by name.
    let ck = parts.join("checkpoint.bin");
    let mut bytes = std::fs::read(&ck).unwrap();
    let n = bytes.len();
    bytes.truncate(n - 100);
    std::fs::write(&ck, &bytes).unwrap();
    let req = TrainRequest {
        scene_dir: &scene,
        out_dir: &parts,
        cfg: cfg.clone(),
        resume: true,
        force: ForceMode::Refuse,
        stop_after: None,
        priors: &none,
    };
    let err = train(req, Cpu, &ProgressBar::hidden()).expect_err("damaged checkpoint refused").to_string();
    assert!(err.contains("checkpoint.bin") && err.contains("corrupt"), "{err}");
}

#[test]
fn training_lowers_the_photometric_loss() {
    let dir = tempfile::tempdir().unwrap();
    let scene = synth_scene(dir.path());
    let mut cfg = small_config();
    cfg.iterations = 1;
    let start = run(&scene, &dir.path().join("a"), &cfg, false, None);
    cfg.iterations = 60;
    let end = run(&scene, &dir.path().join("b"), &cfg, false, None);
    assert!(end.recent_psnr > start.recent_psnr + 2.0, "PSNR {} -> {}", start.recent_psnr, end.recent_psnr);
}
