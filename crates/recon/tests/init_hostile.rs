//! Hostile scenes at initialisation: a track whose every box has zero size (its random fill
//! points all sit at the box centre, more identical points than a k-d tree leaf holds) starts
//! with no Gaussians instead of crashing; identical points are merged before the neighbour
//! search; camera poses too far out for f64 to sample random points between are refused naming
//! `world_from_ego` instead of panicking.

use recon::data::View;
use recon::init::{gaussians_at, initialise};
use recon::TrainConfig;
use std::path::Path;

fn scene_and_views(dir: &Path) -> (scene::Scene, Vec<View>, TrainConfig) {
    let sc = synth::SynthConfig { frames: 3, cameras: 1, width: 48, height: 32, seed: 3, ..Default::default() };
    synth::synthesize(&sc, dir, &mut |_, _| {}).expect("synthetic scene");
    let cfg = TrainConfig { scale: 1.0, ..TrainConfig::default() };
    let none = |_: &View| Ok(None);
    let (scene, views) = recon::session::prepare(dir, &cfg, &none).unwrap();
    (scene, views, cfg)
}

#[test]
fn identical_points_are_merged_and_distinct_points_kept_as_they_are() {
    let cfg = TrainConfig::default().init;
    let same: Vec<_> = (0..100)
        .map(|i| (glam::DVec3::new(0.0, 0.0, if i % 2 == 0 { 0.0 } else { -0.0 }), [0.5; 3]))
        .chain([(glam::DVec3::new(f64::NAN, 0.0, 0.0), [0.5; 3]), (glam::DVec3::X, [0.2; 3])])
        .collect();
    let g = gaussians_at(&same, 0, &cfg);
    assert_eq!(g.means, vec![[0.0; 3], [1.0, 0.0, 0.0]], "one Gaussian a distinct finite point");
    let distinct: Vec<_> = (0..40).map(|i| (glam::DVec3::new(i as f64 * 0.1, 0.0, 0.0), [0.5; 3])).collect();
    assert_eq!(gaussians_at(&distinct, 0, &cfg).len(), 40);
}

#[test]
fn a_track_with_zero_size_boxes_starts_with_no_gaussians() {
    let dir = tempfile::tempdir().unwrap();
    let (mut scene, views, cfg) = scene_and_views(&dir.path().join("s"));
    let zero = 0;
    scene.tracks[zero].states.iter_mut().for_each(|s| s.size_lwh = [0.0; 3]);
    let (model, report) =
        initialise(dir.path().join("s").as_path(), &scene, &views, &cfg.init, cfg.sh_degree, cfg.sky_res, cfg.seed)
            .unwrap();
    let id = &scene.tracks[zero].id;
    let a = model.actors.iter().find(|a| &a.track_id == id).expect("the track keeps its actor");
    assert_eq!(a.gaussians.len(), 0);
    assert!(report.actors.contains(&(id.clone(), 0, 0)), "{:?}", report.actors);
    assert!(model.actors.iter().filter(|a| &a.track_id != id).all(|a| !a.gaussians.is_empty()));
}

#[test]
fn camera_poses_too_far_out_to_sample_between_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (mut scene, mut views, cfg) = scene_and_views(&dir.path().join("s"));
    scene.frames.iter_mut().for_each(|f| f.lidar = None);
    for v in &mut views {
        v.targets.depth = None;
        // The camera centre moves 1e308 m out (the rotation part is kept).
        for row in v.cam.camera_from_world.iter_mut().take(3) {
            row[3] -= 1e308 * row[0];
        }
    }
    let err =
        initialise(dir.path().join("s").as_path(), &scene, &views, &cfg.init, cfg.sh_degree, cfg.sky_res, cfg.seed)
            .map(|_| ())
            .unwrap_err()
            .to_string();
    assert!(err.contains("world_from_ego") && err.contains("random starting points"), "{err}");
}
