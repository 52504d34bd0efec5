//! A tiny synthetic street, a model whose actors are boxes of opaque Gaussians (so the tests
//! measure the loop, not training), and one real corner case per showcased behaviour made on it
//! by the planner and the physics (as the demo makes them).
#![allow(dead_code)]

use cases::spec::{AgentName, T0Spec};
use pipeline::case::{select_case, CaseRequest, T0Choice};
use recon::model::{Actor, SceneModel};
use recon::sky::Sky;
use scene::{Behavior, Executed, Scene};
use splat::Gaussians;
use std::path::Path;

pub fn box_of_gaussians(size: [f64; 3], colour: [f64; 3]) -> Gaussians {
    let n = 6;
    let mut g = Gaussians::empty(0);
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let f = |a: usize, s: f64| (a as f64 + 0.5) / n as f64 * s - s / 2.0;
                g.means.push([f(i, size[0]), f(j, size[1]), f(k, size[2])]);
                g.log_scales.push(std::array::from_fn(|a| (size[a] / n as f64 * 0.4).ln()));
                g.rotations.push([1.0, 0.0, 0.0, 0.0]);
                g.opacity_logits.push(6.0);
                g.sh.extend(colour.map(|c| (c - 0.5) / 0.282_094_791_773_878_14));
            }
        }
    }
    g
}

pub fn synth_scene(dir: &Path) -> Scene {
    let cfg =
        synth::SynthConfig { frames: 80, cameras: 3, width: 96, height: 64, seed: 4, force: true, preview: false };
    synth::synthesize(&cfg, dir, &mut |_, _| {}).expect("synthesize");
    scene::load_scene(dir).expect("load scene")
}

/// Boxes for the actors and a few ground tiles, so the views are not only sky.
pub fn box_model(scene: &Scene) -> SceneModel {
    let actors = scene
        .tracks
        .iter()
        .map(|t| {
            let size = t.median_size_lwh();
            Actor { track_id: t.id.clone(), size_lwh: size, gaussians: box_of_gaussians(size, [0.8, 0.2, 0.2]) }
        })
        .collect();
    let mut background = box_of_gaussians([60.0, 12.0, 0.2], [0.35, 0.35, 0.35]);
    let p0 = scene.frames[0].world_from_ego.translation();
    for m in &mut background.means {
        m[0] += p0.x + 20.0;
        m[1] += p0.y;
        m[2] += p0.z - 0.1;
    }
    SceneModel { antialiased: false, background, actors, sky: Sky::new(4, [0.5, 0.6, 0.8]) }
}

/// The case of `behavior` on `scene`, as the demo searches it (t0 every 0.5 s).
pub fn case(scene: &Scene, behavior: Behavior) -> Option<Executed> {
    let req = CaseRequest {
        behavior,
        agent: AgentName::Planner,
        adversary: None,
        zone: None,
        ttc_s: None,
        insert: Default::default(),
        seed: 0,
        seeds_per_t0: 1,
        refine_rounds: 0,
        window: pipeline::case::rendered_window(),
        fallback_window: Some(cases::window::Window::default()),
    };
    select_case(scene, &req, &T0Choice::Search(T0Spec::Every(0.5)), None).chosen.map(|(_, e, _)| e)
}

pub const SHOWCASED: [Behavior; 3] = [Behavior::SuddenBraking, Behavior::SuddenCutIn, Behavior::OpposingDrift];

pub fn front3(scene: &Scene) -> Vec<String> {
    drive::cameras::resolve(scene, "front3").unwrap()
}
