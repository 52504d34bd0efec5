//! Acceptance of vehicle replacement on a synthetic scene: a briefly trained model's actor is
//! replaced by an asset made from the synthetic vehicle's ground-truth geometry
//! (`synth_asset`, turntable surfels), handed over in a foreign frame (turned 2 rad, scaled by
//! 0.5 in x and 0.7 elsewhere) so the alignment has to recover it. From a novel view beside the
//! vehicle the replaced actor must cover the ground truth's pixels (mask IoU > 0.9) and be
//! closer to it (PSNR over the vehicle's mask) than the original reconstruction.

use indicatif::ProgressBar;
use pipeline::replace_check::{beside, score_actor};
use recon::backend::Cpu;
use recon::session::{train, TrainRequest};
use recon::TrainConfig;
use render::asset::align::AlignOptions;
use render::asset::covariance::{diag, mat_mul, transform, yaw_matrix};

const TRACK: &str = "lead-1";

#[test]
fn replaced_actor_lands_in_place_and_beats_the_reconstruction_from_a_novel_view() {
    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("scene");
    let synth_cfg = synth::SynthConfig { frames: 9, cameras: 2, width: 96, height: 64, seed: 3, ..Default::default() };
    synth::synthesize(&synth_cfg, &scene_dir, &mut |_, _| {}).expect("synthetic scene");
    let mut cfg = TrainConfig {
        iterations: 60,
        scale: 1.0,
        checkpoint_interval: 0,
        sh_degree_interval: 10,
        ..Default::default()
    };
    cfg.densify.from = 0.15;
    cfg.densify.interval = 5;
    cfg.densify.until = 0.8;
    cfg.densify.opacity_reset_every = 0.6;
    cfg.init.max_points = 3000;
    cfg.init.actor_points = 300;
    cfg.sky_res = 4;
    let model_dir = dir.path().join("model");
    let none = |_: &recon::data::View| Ok(None);
    let req = TrainRequest {
        scene_dir: &scene_dir,
        out_dir: &model_dir,
        cfg,
        resume: false,
        force: recon::out_dir::ForceMode::Refuse,
        stop_after: None,
        priors: &none,
    };
    train(req, Cpu, &ProgressBar::hidden()).expect("training runs");
    let (model, _) = recon::model_io::load_model(&model_dir).unwrap();
    let scene = scene::load_scene(&scene_dir).unwrap();
    let seq = synth::Sequence::new(&synth_cfg).unwrap();
    let k = seq.vehicles.iter().position(|v| v.track_id == TRACK).expect("the track exists");

    // The asset: the vehicle's own geometry, in a foreign frame.
    let truth = pipeline::synth_asset::vehicle_asset(&seq.vehicles[k], 0.06).unwrap();
    let foreign = mat_mul(&yaw_matrix(2.0), &diag([0.5, 0.7, 0.7]));
    let asset = transform(&truth, &foreign, [3.0, -1.0, 0.2], &yaw_matrix(2.0));
    let mut replaced = model.clone();
    let rep = render::asset::replace::replace_actor(&mut replaced, TRACK, "synth", &asset, &AlignOptions::default())
        .expect("replacement");
    let c = rep.alignment.chosen();
    for o in &rep.alignment.candidates {
        eprintln!(
            "candidate {:7} yaw {:8.3} deg scale {:.4?} extent error {:.4} m Chamfer {:.4} m score {:.4}",
            o.name,
            o.yaw.to_degrees(),
            o.scale,
            o.extent_error_m,
            o.chamfer_m,
            o.score
        );
    }
    eprintln!("chosen {} (box points: {}, actor Gaussians {})", c.name, rep.box_points, rep.gaussians_before);
    // The foreign frame is undone: yaw -2 rad, scale (2, 1/0.7, 1/0.7).
    let yaw_err = render::asset::align::wrap(c.yaw + 2.0).abs().to_degrees();
    assert!(yaw_err < 1.0, "yaw off by {yaw_err} deg");
    for (s, want) in c.scale.iter().zip([2.0, 1.0 / 0.7, 1.0 / 0.7]) {
        assert!((s / want - 1.0).abs() < 0.02, "scale {:?}", c.scale);
    }

    let view = beside(&seq, k, 4, 7.0, 192, 144);
    let (before, _) = score_actor(&Cpu, &model, &scene, &seq, TRACK, &view).unwrap();
    let (after, _) = score_actor(&Cpu, &replaced, &scene, &seq, TRACK, &view).unwrap();
    eprintln!("before {before:?}\nafter  {after:?}");
    assert!(after.gt_pixels > 500, "the novel view must see the vehicle: {after:?}");
    assert!(after.iou > 0.9, "replaced actor's mask IoU {}", after.iou);
    assert!(after.psnr_db > before.psnr_db, "replacement {} dB vs original {} dB", after.psnr_db, before.psnr_db);
}
