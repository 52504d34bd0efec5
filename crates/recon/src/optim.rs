//! Adam (Kingma & Ba) over every Gaussian set and the sky, with the 3DGS per-parameter learning
//! rates: means (times the scene extent, decayed exponentially to `means_final`), log-scales,
//! rotations, opacity logits, SH DC and the rest of the SH (a twentieth). Moments are stored in
//! `Gaussians`-shaped sets so densification edits them row for row with the parameters.

use crate::config::LearningRates;
use crate::model::{zeros_like, SceneModel};
use rayon::prelude::*;
use splat::Gaussians;

pub const BETA1: f64 = 0.9;
pub const BETA2: f64 = 0.999;
pub const EPS: f64 = 1e-15;

/// First and second moments of every set (background, then actors) and of the sky.
#[derive(Clone, Debug, PartialEq)]
pub struct AdamState {
    pub step: u64,
    pub m: Vec<Gaussians>,
    pub v: Vec<Gaussians>,
    pub sky_m: Vec<f64>,
    pub sky_v: Vec<f64>,
}

impl AdamState {
    pub fn new(model: &SceneModel) -> AdamState {
        AdamState {
            step: 0,
            m: model.sets().map(zeros_like).collect(),
            v: model.sets().map(zeros_like).collect(),
            sky_m: vec![0.0; model.sky.texels.len()],
            sky_v: vec![0.0; model.sky.texels.len()],
        }
    }
}

/// The mean learning rate at iteration `it` of `total`: log-linear from `means` to `means_final`.
pub fn means_lr(lr: &LearningRates, extent: f64, it: usize, total: usize) -> f64 {
    let t = (it as f64 / total.max(1) as f64).clamp(0.0, 1.0);
    extent * (lr.means.ln() * (1.0 - t) + lr.means_final.ln() * t).exp()
}

struct Step {
    bc1: f64,
    bc2: f64,
}

impl Step {
    #[inline]
    fn apply(&self, p: &mut f64, g: f64, m: &mut f64, v: &mut f64, lr: f64) {
        *m = BETA1 * *m + (1.0 - BETA1) * g;
        *v = BETA2 * *v + (1.0 - BETA2) * g * g;
        let mh = *m / self.bc1;
        let vh = *v / self.bc2;
        *p -= lr * mh / (vh.sqrt() + EPS);
    }

    /// Element-wise over the slices, in parallel chunks (each element is independent, so the
    /// result does not depend on the thread count).
    fn slice(&self, p: &mut [f64], g: &[f64], m: &mut [f64], v: &mut [f64], lr: f64) {
        self.slice_with(p, g, m, v, &|_| lr);
    }

    fn slice_with(&self, p: &mut [f64], g: &[f64], m: &mut [f64], v: &mut [f64], lr: &(dyn Fn(usize) -> f64 + Sync)) {
        const CHUNK: usize = 1 << 14;
        p.par_chunks_mut(CHUNK).zip(m.par_chunks_mut(CHUNK)).zip(v.par_chunks_mut(CHUNK)).enumerate().for_each(
            |(c, ((p, m), v))| {
                let base = c * CHUNK;
                for i in 0..p.len() {
                    self.apply(&mut p[i], g[base + i], &mut m[i], &mut v[i], lr(base + i));
                }
            },
        );
    }
}

/// One Adam step on every parameter of `model` with gradients `grads` (same shapes) and sky
/// gradient `sky_grad`. `mean_lr` is the (already scheduled) mean learning rate.
pub fn adam_step(
    model: &mut SceneModel,
    state: &mut AdamState,
    grads: &[Gaussians],
    sky_grad: &[f64],
    lr: &LearningRates,
    mean_lr: f64,
) {
    state.step += 1;
    let t = state.step as i32;
    let s = Step { bc1: 1.0 - BETA1.powi(t), bc2: 1.0 - BETA2.powi(t) };
    let sets: Vec<&mut Gaussians> = model.sets_mut().collect();
    for (((p, g), m), v) in sets.into_iter().zip(grads).zip(&mut state.m).zip(&mut state.v) {
        s.slice(
            p.means.as_flattened_mut(),
            g.means.as_flattened(),
            m.means.as_flattened_mut(),
            v.means.as_flattened_mut(),
            mean_lr,
        );
        s.slice(
            p.log_scales.as_flattened_mut(),
            g.log_scales.as_flattened(),
            m.log_scales.as_flattened_mut(),
            v.log_scales.as_flattened_mut(),
            lr.log_scales,
        );
        s.slice(
            p.rotations.as_flattened_mut(),
            g.rotations.as_flattened(),
            m.rotations.as_flattened_mut(),
            v.rotations.as_flattened_mut(),
            lr.rotations,
        );
        s.slice(&mut p.opacity_logits, &g.opacity_logits, &mut m.opacity_logits, &mut v.opacity_logits, lr.opacity);
        let k = p.coeffs() * 3;
        let rate = |j: usize| if j % k < 3 { lr.sh_dc } else { lr.sh_rest };
        s.slice_with(&mut p.sh, &g.sh, &mut m.sh, &mut v.sh, &rate);
    }
    s.slice(&mut model.sky.texels, sky_grad, &mut state.sky_m, &mut state.sky_v, lr.sky);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_step_moves_by_the_learning_rate_against_the_gradient() {
        let s = Step { bc1: 1.0 - BETA1, bc2: 1.0 - BETA2 };
        let (mut p, mut m, mut v) = (1.0, 0.0, 0.0);
        s.apply(&mut p, 3.0, &mut m, &mut v, 0.1);
        assert!((p - 0.9).abs() < 1e-12);
        let (mut p, mut m, mut v) = (1.0, 0.0, 0.0);
        s.apply(&mut p, -1e-3, &mut m, &mut v, 0.1);
        assert!((p - 1.1).abs() < 1e-9);
    }

    #[test]
    fn mean_rate_decays_from_start_to_end() {
        let lr = LearningRates::default();
        assert!((means_lr(&lr, 2.0, 0, 100) - 3.2e-4).abs() < 1e-15);
        assert!((means_lr(&lr, 2.0, 100, 100) - 3.2e-6).abs() < 1e-15);
        assert!((means_lr(&lr, 1.0, 50, 100) - 1.6e-5).abs() < 1e-12);
    }
}
