//! The saved model is what training drew: the training reparametrisations (`compose::Reparam`)
//! are baked in, so every reader (`eval-recon`, `render`, the videos, asset harvesting, other
//! 3DGS viewers) draws it without knowing of them. The smoothing filter replaces each row's
//! log-scales and opacity by its filtered ones (`smoothing::bake`); a mirrored actor gets its
//! mirror image appended, row for row after its own rows (`compose::mirror_row`), and
//! `model.json` records it (`ActorRecord::mirrored`). The training state (the checkpoint) keeps
//! the unbaked model, so a resumed run continues from exactly where it stopped.

use crate::checkpoint::TrainState;
use crate::compose::mirror_row;
use crate::config::TrainConfig;
use crate::model::SceneModel;

/// The model to save from training state `st` run with `cfg`; `mirrored[a]`: actor `a` is drawn
/// with its mirror image.
pub fn baked(st: &TrainState, cfg: &TrainConfig, mirrored: &[bool]) -> SceneModel {
    let mut model = match cfg.filter_3d > 0.0 && !st.smoothing.is_empty() {
        true => crate::smoothing::bake(&st.model, &st.smoothing),
        false => st.model.clone(),
    };
    model.antialiased = cfg.antialiased;
    for (a, actor) in model.actors.iter_mut().enumerate() {
        if !mirrored.get(a).copied().unwrap_or(false) {
            continue;
        }
        let g = &mut actor.gaussians;
        let n = g.len();
        let mut sh = vec![0.0; g.coeffs() * 3];
        for i in 0..n {
            let (mean, q) = mirror_row(g, i, &mut sh);
            g.means.push(mean);
            g.rotations.push(q);
            g.log_scales.push(g.log_scales[i]);
            g.opacity_logits.push(g.opacity_logits[i]);
            g.sh.extend_from_slice(&sh);
        }
    }
    model
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::compose::{compose_with, Composed, Layers, Reparam};

    /// Drawing the baked model plainly gives the same world Gaussians (up to the order of rows
    /// within the actor's parts) as drawing the state through the reparametrisations.
    #[test]
    fn the_baked_model_draws_what_training_drew() {
        let cam = splat::Camera::at_origin(16, 16, 16.0);
        let model = SceneModel {
            antialiased: false,
            background: splat::random::random_gaussians(5, &cam, 1, 1),
            actors: vec![crate::model::Actor {
                track_id: "car".into(),
                size_lwh: [4.0, 2.0, 1.5],
                gaussians: splat::random::random_gaussians(3, &cam, 1, 2),
            }],
            sky: crate::sky::Sky::new(2, [0.5; 3]),
        };
        let smoothing: Vec<Vec<f64>> =
            model.sets().map(|g| (0..g.len()).map(|i| 0.001 * (i + 1) as f64).collect()).collect();
        let st = TrainState {
            next_iteration: 0,
            adam: crate::optim::AdamState::new(&model),
            stats: vec![],
            model,
            smoothing,
        };
        let cfg = TrainConfig { filter_3d: 0.2, antialiased: true, mirror_vehicles: true, ..Default::default() };
        let saved = baked(&st, &cfg, &[true]);
        assert!(saved.antialiased);
        assert_eq!(saved.actors[0].gaussians.len(), 6);
        let scene = scene::Scene {
            format: scene::SCENE_FORMAT.into(),
            name: "t".into(),
            source: scene::Source { kind: scene::SourceKind::Synthetic, files: vec![], id: "t".into() },
            ego: scene::Ego { size_lwh: [4.5, 2.0, 1.8], size_source: scene::EgoSizeSource::Default, track_id: None },
            cameras: vec![],
            frames: vec![],
            tracks: vec![],
            map: None,
        };
        let pose = crate::pose::BoxPose { center: [3.0, -1.0, 0.5], heading: 0.7 };
        let posed = |_: usize| Some(Some(pose));
        let rp = Reparam { mirrored: &[true], smoothing: Some(&st.smoothing) };
        let (mut a, mut b) = (Composed::default(), Composed::default());
        compose_with(&st.model, &scene, 0.0, 1, Layers::All, &posed, &rp, &mut a);
        compose_with(&saved, &scene, 0.0, 1, Layers::All, &posed, &Reparam::NONE, &mut b);
        assert_eq!(a.world.len(), b.world.len());
        let close = |x: &[f64], y: &[f64]| x.iter().zip(y).all(|(p, q)| (p - q).abs() < 1e-9);
        assert!(close(a.world.means.as_flattened(), b.world.means.as_flattened()));
        assert!(close(a.world.log_scales.as_flattened(), b.world.log_scales.as_flattened()));
        assert!(close(&a.world.opacity_logits, &b.world.opacity_logits));
        assert!(close(a.world.rotations.as_flattened(), b.world.rotations.as_flattened()));
        assert!(close(&a.world.sh, &b.world.sh));
    }
}
