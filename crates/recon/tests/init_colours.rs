//! The starting Gaussians never see a held-out image. A synthetic street whose only LiDAR sweeps
//! lie on the held-out frames (as PandaSet 002's nine do under the every-8th split) starts from
//! those sweeps, with every colour taken from the training views beside them: the held-out views
//! are painted red and the training views green here, so one red start is a leak.

use recon::data::View;
use recon::TrainConfig;
use splat::sh::C0;

fn paint(views: &mut [View]) {
    for v in views {
        let c = if v.held_out { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
        v.targets.rgb.iter_mut().for_each(|p| *p = c);
    }
}

/// The starting colours (SH DC) of `g`'s Gaussians.
fn colours(g: &splat::Gaussians) -> Vec<[f64; 3]> {
    let k = g.coeffs() * 3;
    g.sh.chunks(k).map(|sh| std::array::from_fn(|c| sh[c] * C0 + 0.5)).collect()
}

#[test]
fn sweeps_on_held_out_frames_take_their_colours_from_training_views() {
    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("scene");
    let sc = synth::SynthConfig { frames: 9, cameras: 2, width: 96, height: 64, seed: 3, ..Default::default() };
    synth::synthesize(&sc, &scene_dir, &mut |_, _| {}).expect("synthetic scene");
    let cfg = TrainConfig { scale: 1.0, ..TrainConfig::default() };
    let none = |_: &View| Ok(None);
    let (mut scene, mut views) = recon::session::prepare(&scene_dir, &cfg, &none).unwrap();
    paint(&mut views);
    // Only the held-out frames (0 and 8) keep their sweeps.
    for f in &mut scene.frames {
        if !recon::data::is_held_out(f.index, cfg.held_out_every) {
            f.lidar = None;
        }
    }
    assert!(scene.frames.iter().filter(|f| f.lidar.is_some()).count() == 2, "frames 0 and 8 keep their sweeps");
    let (model, report) =
        recon::init::initialise(&scene_dir, &scene, &views, &cfg.init, cfg.sh_degree, cfg.sky_res, cfg.seed).unwrap();
    assert_eq!(report.background_source, "lidar");
    let bg = colours(&model.background);
    assert!(bg.len() > 500, "the sweeps start the background: {} Gaussians", bg.len());
    let red = bg.iter().filter(|c| c[0] > 0.5).count();
    assert_eq!(red, 0, "{red} of {} background Gaussians took a held-out view's colour", bg.len());
    assert!(bg.iter().all(|c| c[1] > 0.99 && c[0] < 0.01), "every background colour is a training view's");
    let lidar_actor_points: usize = report.actors.iter().map(|a| a.1).sum();
    assert!(lidar_actor_points > 0, "the sweeps hit the street's cars: {:?}", report.actors);
    for (a, rep) in model.actors.iter().zip(&report.actors) {
        // The sweep's points come first; random fill points are grey.
        for c in colours(&a.gaussians).iter().take(rep.1) {
            assert!(c[1] > 0.99 && c[0] < 0.01, "actor {}: a start coloured {c:?}", a.track_id);
        }
    }
}
