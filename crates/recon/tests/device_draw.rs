//! The device drawer of the videos (`recon::device::DeviceDrawer`: the model kept on the GPU,
//! composed there) against `recon::view::draw` through the same GPU rasterizer (composed on the
//! host in f64): a small synthetic street with actors, its SH bands filled so the actors' SH
//! rotations matter, drawn at several times and cameras, every layer, one actor moved by an
//! override and one hidden. The two composed actors differ by f32 rounding, and where two
//! Gaussians lie at nearly one depth (discs started on one LiDAR surface) that rounding may sort
//! them the other way: so the pixels where colour or alpha differ by more than 1e-4 may be at most
//! 3 times as many as where the host's own drawing changes when every actor moves by 2e-6 m (and
//! at least 0.1 % of the pixels are allowed). An actor of another SH degree is refused, for the
//! caller to draw on the host. Needs an NVIDIA GPU; elsewhere it prints why it skipped. Run on the
//! GPU machine (`device_draw` executable).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use recon::backend_cuda::Cuda;
use recon::compose::Layers;
use recon::device::DeviceDrawer;
use recon::pose::BoxPose;
use recon::TrainConfig;
use std::sync::Arc;

/// Colour and alpha of a drawing, one pixel a row.
fn pixels(d: &recon::view::Drawn) -> Vec<[f64; 4]> {
    d.rgb.iter().zip(&d.alpha).map(|(c, a)| [c[0], c[1], c[2], *a]).collect()
}

/// Pixels of `a` and `b` differing by more than 1e-4 in a channel, and the largest difference.
fn differing(a: &recon::view::Drawn, b: &recon::view::Drawn) -> (usize, f64) {
    let d: Vec<f64> =
        pixels(a).iter().zip(pixels(b)).map(|(p, q)| (0..4).map(|c| (p[c] - q[c]).abs()).fold(0.0, f64::max)).collect();
    (d.iter().filter(|x| **x > 1e-4).count(), d.iter().copied().fold(0.0, f64::max))
}

#[test]
fn the_device_drawer_draws_what_view_draw_draws() {
    let gpu = match splat_cuda::Gpu::new() {
        Ok(g) => Arc::new(g),
        Err(e) => {
            println!("SKIP the device drawer test: {e}");
            return;
        }
    };
    println!("device: {}", gpu.describe());
    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("scene");
    let sc = synth::SynthConfig { frames: 8, cameras: 2, width: 150, height: 90, seed: 7, ..Default::default() };
    synth::synthesize(&sc, &scene_dir, &mut |_, _| {}).expect("synthetic scene");
    let mut cfg = TrainConfig { scale: 1.0, sky_res: 8, ..Default::default() };
    cfg.init.max_points = 4000;
    cfg.init.actor_points = 300;
    let none = |_: &recon::data::View| Ok(None);
    let (scene, views) = recon::session::prepare(&scene_dir, &cfg, &none).unwrap();
    let (mut model, _) =
        recon::init::initialise(&scene_dir, &scene, &views, &cfg.init, cfg.sh_degree, cfg.sky_res, cfg.seed).unwrap();
    assert!(model.actors.len() >= 2, "the street has actors to move and hide");
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for g in model.sets_mut() {
        g.sh.iter_mut().for_each(|v| *v += rng.random_range(-0.3..0.3));
        g.opacity_logits.iter_mut().for_each(|v| *v = rng.random_range(-2.0..2.0));
    }
    let backend = Cuda::new().expect("the CUDA backend");
    let mut drawer = DeviceDrawer::new(gpu.clone(), &model).expect("the drawer");
    let moved = BoxPose { center: [4.0, 1.5, 0.8], heading: 0.7 };
    let overrides = |i: usize| match i {
        0 => Some(Some(moved)),
        1 => Some(None),
        _ => None,
    };
    let logged = |_: usize| None;
    let mut checked = 0;
    for v in views.iter().step_by(3) {
        for layers in [Layers::All, Layers::ActorsOnly, Layers::BackgroundOnly] {
            for (name, poses) in [("logged", &logged as &dyn Fn(usize) -> _), ("overridden", &overrides)] {
                let host = recon::view::draw(&backend, &model, &scene, &v.cam, v.time, layers, poses);
                let dev = drawer.draw(&model, &scene, &v.cam, v.time, layers, poses).unwrap();
                assert_eq!((dev.width, dev.height), (host.width, host.height));
                // The host's own sensitivity: every drawn actor 2e-6 m along x.
                let jitter = |i: usize| {
                    let p = poses(i).unwrap_or_else(|| recon::compose::actor_pose(&model, &scene, i, v.time));
                    Some(p.map(|p| BoxPose { center: [p.center[0] + 2e-6, p.center[1], p.center[2]], ..p }))
                };
                let moved = recon::view::draw(&backend, &model, &scene, &v.cam, v.time, layers, &jitter);
                let (n_dev, max_dev) = differing(&dev, &host);
                let (n_self, max_self) = differing(&moved, &host);
                let allowed = (3 * n_self).max(host.rgb.len() / 1000);
                println!(
                    "frame {} {} {layers:?} {name}: {n_dev} px differ (max {max_dev:.2e}); the host moved 2e-6 m: \
                     {n_self} (max {max_self:.2e}); allowed {allowed}",
                    v.frame, v.camera
                );
                assert!(
                    n_dev <= allowed,
                    "frame {} {layers:?} {name}: {n_dev} pixels differ, {allowed} allowed",
                    v.frame
                );
                checked += 1;
            }
        }
    }
    assert!(checked >= 12, "{checked} drawings compared");
    // An actor of another SH degree (a replaced one, say) is refused, not drawn wrong.
    let mut mixed = model.clone();
    let a = &mut mixed.actors[0].gaussians;
    let k0 = splat::sh::sh_coeffs(0) * 3;
    let kc = a.coeffs() * 3;
    a.sh = a.sh.chunks(kc).flat_map(|row| row[..k0].to_vec()).collect();
    a.sh_degree = 0;
    let e = DeviceDrawer::new(gpu, &mixed).err().expect("a mixed-degree model is refused").to_string();
    assert!(e.contains("SH degree"), "{e}");
}
