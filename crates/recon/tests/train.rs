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

/// The same with the 2D and 3D filters and mirrored vehicles: the filter's variances are part of
/// the checkpoint, so the resumed run still ends bit for bit where the uninterrupted one does, and
/// the saved model holds the filter and both halves of every vehicle.
#[test]
fn resume_with_the_filters_and_mirrors_matches_an_uninterrupted_run() {
    let dir = tempfile::tempdir().unwrap();
    let scene = synth_scene(dir.path());
    let cfg = TrainConfig { antialiased: true, filter_3d: 0.2, mirror_vehicles: true, ..small_config() };
    let whole = run(&scene, &dir.path().join("whole"), &cfg, false, None);
    let parts = dir.path().join("parts");
    run(&scene, &parts, &cfg, false, Some(13));
    let second = run(&scene, &parts, &cfg, true, None);
    assert_eq!(second.last_loss, whole.last_loss, "resumed run must reach the same loss");
    let a = recon::checkpoint::load(&dir.path().join("whole/checkpoint.bin")).unwrap();
    let b = recon::checkpoint::load(&parts.join("checkpoint.bin")).unwrap();
    assert!(!a.smoothing.is_empty() && a.smoothing.iter().flatten().all(|v| *v > 0.0), "every row has a filter");
    assert_eq!(a, b, "resumed state differs from the uninterrupted one");
    // The saved model: drawn antialiased, every vehicle's PLY holding its mirror image after its
    // own rows, every row's scales at least the filter's.
    let (model, record) = recon::model_io::load_model(&parts).unwrap();
    assert!(model.antialiased && record.antialiased);
    let scene_data = scene::load_scene(&scene).unwrap();
    for ((saved, raw), rec) in model.actors.iter().zip(&b.model.actors).zip(&record.actors) {
        let vehicle = scene_data.track(&raw.track_id).is_some_and(|t| t.class == scene::ObjectClass::Vehicle);
        assert_eq!(rec.mirrored, vehicle);
        let n = raw.gaussians.len();
        assert_eq!(saved.gaussians.len(), if vehicle { 2 * n } else { n });
        if vehicle && n > 0 {
            let (m, q) = (saved.gaussians.means[n], raw.gaussians.means[0]);
            assert!((m[1] + q[1]).abs() < 1e-6 && (m[0] - q[0]).abs() < 1e-6, "row 0's mirror image is row n");
        }
    }
    let f2 = &b.smoothing[0];
    for (i, s) in model.background.log_scales.iter().enumerate() {
        assert!(s.iter().all(|l| (2.0 * l).exp() >= f2[i] * (1.0 - 1e-4)), "row {i} is no finer than its filter");
    }
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
