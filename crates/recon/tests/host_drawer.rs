//! The host drawer of the CPU videos (`recon::host_drawer::HostDrawer`: the background composed
//! once, each actor's rows kept until its pose changes, the rasterizer's buffers reused) against
//! `recon::view::draw` (the whole scene composed anew for every view), through both CPU backends:
//! a small synthetic street with actors, its SH bands filled so the actors' SH rotations matter,
//! drawn at several times and cameras, the layers switching between views, one actor moved by an
//! override and one hidden, the same view drawn twice, and every view in turn as a video draws
//! them. Every image must be bit for bit the
//! same. `painter::Painter` on a CPU backend draws through the drawer, so it is checked too.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use recon::backend::{Backend, Cpu, CpuF32};
use recon::compose::Layers;
use recon::host_drawer::HostDrawer;
use recon::pose::BoxPose;
use recon::TrainConfig;

fn bits(d: &recon::view::Drawn) -> Vec<u64> {
    let mut v: Vec<u64> = d.rgb.iter().flatten().map(|x| x.to_bits()).collect();
    v.extend(d.alpha.iter().chain(&d.depth).map(|x| x.to_bits()));
    v.extend(d.normal.iter().flatten().map(|x| x.to_bits()));
    v
}

fn check<B: Backend>(backend: &B, model: &recon::SceneModel, scene: &scene::Scene, views: &[recon::data::View]) {
    let mut drawer = HostDrawer::<B::Context>::default();
    let painter = recon::painter::Painter::new(backend, model, scene);
    let moved = BoxPose { center: [4.0, 1.5, 0.8], heading: 0.7 };
    let overrides = |i: usize| match i {
        0 => Some(Some(moved)),
        1 => Some(None),
        _ => None,
    };
    let logged = |_: usize| None;
    let mut checked = 0;
    for v in views.iter().step_by(3) {
        for layers in [Layers::All, Layers::ActorsOnly, Layers::All, Layers::BackgroundOnly, Layers::All] {
            for poses in [&logged as &dyn Fn(usize) -> _, &overrides, &logged] {
                let want = recon::view::draw(backend, model, scene, &v.cam, v.time, layers, poses);
                let got = drawer.draw(backend, model, scene, &v.cam, v.time, layers, poses);
                assert_eq!((got.width, got.height), (want.width, want.height));
                assert!(bits(&got) == bits(&want), "frame {} {layers:?}: the drawer differs", v.frame);
                let painted = painter.draw(&v.cam, v.time, layers, poses);
                assert!(bits(&painted) == bits(&want), "frame {} {layers:?}: the painter differs", v.frame);
                checked += 1;
            }
        }
    }
    assert!(checked >= 30, "{checked} drawings checked");
    // A video: one view after another, the actors moving between them and the set in view the
    // same (the moved actors are rewritten in place).
    for v in views {
        let want = recon::view::draw(backend, model, scene, &v.cam, v.time, Layers::All, &logged);
        let got = drawer.draw(backend, model, scene, &v.cam, v.time, Layers::All, &logged);
        assert!(bits(&got) == bits(&want), "frame {} in sequence: the drawer differs", v.frame);
    }
}

#[test]
fn the_host_drawer_draws_what_view_draw_draws() {
    let dir = tempfile::tempdir().unwrap();
    let scene_dir = dir.path().join("scene");
    let sc = synth::SynthConfig { frames: 8, cameras: 2, width: 96, height: 64, seed: 7, ..Default::default() };
    synth::synthesize(&sc, &scene_dir, &mut |_, _| {}).expect("synthetic scene");
    let mut cfg = TrainConfig { scale: 1.0, sky_res: 8, ..Default::default() };
    cfg.init.max_points = 3000;
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
    check(&CpuF32, &model, &scene, &views);
    check(&Cpu, &model, &scene, &views);
}
