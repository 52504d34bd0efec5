//! Adam (Kingma & Ba) over every Gaussian set and the sky, with the 3DGS per-parameter learning
//! rates: means (times the scene extent, decayed exponentially to `means_final`), log-scales,
//! rotations, opacity logits, SH DC and the rest of the SH (a twentieth). Moments are stored in
//! `Gaussians`-shaped sets so densification edits them row for row with the parameters.
//! The SH bands the schedule has not drawn yet are skipped (zero gradients and moments: Adam
//! would leave them as they are), which gives the same bits at a fraction of the work.

use crate::config::LearningRates;
use crate::model::{zeros_like, SceneModel};
use rayon::prelude::*;
use splat::sh::sh_coeffs;
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
    fn slice(&self, p: &mut [f64], g: &[f64], m: &mut [f64], v: &mut [f64], lr: f64, rows: Rows) {
        self.slice_with(p, g, m, v, &|_| lr, rows);
    }

    /// As `slice`, over rows of `p.len() / rows.n` elements, of which the first `rows.used`.
    fn slice_with(
        &self,
        p: &mut [f64],
        g: &[f64],
        m: &mut [f64],
        v: &mut [f64],
        lr: &(dyn Fn(usize) -> f64 + Sync),
        rows: Rows,
    ) {
        const ROWS: usize = 1 << 11;
        let Some(width) = p.len().checked_div(rows.n).filter(|w| *w > 0) else { return };
        let (chunk, used) = (ROWS * width, rows.used.min(width));
        p.par_chunks_mut(chunk).zip(m.par_chunks_mut(chunk)).zip(v.par_chunks_mut(chunk)).enumerate().for_each(
            |(c, ((p, m), v))| {
                let base = c * chunk;
                for r in 0..p.len() / width {
                    for i in r * width..r * width + used {
                        self.apply(&mut p[i], g[base + i], &mut m[i], &mut v[i], lr(base + i));
                    }
                }
            },
        );
    }
}

/// The rows of one parameter array an Adam step updates: `n` rows, and of each row the first
/// `used` elements (the rest are SH coefficients of bands the schedule has not drawn yet: their
/// gradients and both moments are zero, so Adam would leave them as they are; skipping them gives
/// the same bits).
#[derive(Clone, Copy)]
struct Rows {
    n: usize,
    used: usize,
}

/// One Adam step on every parameter of `model` with gradients `grads` (same shapes) and sky
/// gradient `sky_grad`. `mean_lr` is the (already scheduled) mean learning rate; `sh_degree` the
/// highest SH degree drawn so far (the SH schedule only grows): higher bands have never had a
/// gradient and are left out of the work, not out of the result.
pub fn adam_step(
    model: &mut SceneModel,
    state: &mut AdamState,
    grads: &[Gaussians],
    sky_grad: &[f64],
    lr: &LearningRates,
    mean_lr: f64,
    sh_degree: usize,
) {
    state.step += 1;
    let t = state.step as i32;
    let s = Step { bc1: 1.0 - BETA1.powi(t), bc2: 1.0 - BETA2.powi(t) };
    let sets: Vec<&mut Gaussians> = model.sets_mut().collect();
    for (((p, g), m), v) in sets.into_iter().zip(grads).zip(&mut state.m).zip(&mut state.v) {
        let rows = Rows { n: p.len(), used: usize::MAX };
        s.slice(
            p.means.as_flattened_mut(),
            g.means.as_flattened(),
            m.means.as_flattened_mut(),
            v.means.as_flattened_mut(),
            mean_lr,
            rows,
        );
        s.slice(
            p.log_scales.as_flattened_mut(),
            g.log_scales.as_flattened(),
            m.log_scales.as_flattened_mut(),
            v.log_scales.as_flattened_mut(),
            lr.log_scales,
            rows,
        );
        s.slice(
            p.rotations.as_flattened_mut(),
            g.rotations.as_flattened(),
            m.rotations.as_flattened_mut(),
            v.rotations.as_flattened_mut(),
            lr.rotations,
            rows,
        );
        s.slice(
            &mut p.opacity_logits,
            &g.opacity_logits,
            &mut m.opacity_logits,
            &mut v.opacity_logits,
            lr.opacity,
            rows,
        );
        let k = p.coeffs() * 3;
        let rate = |j: usize| if j % k < 3 { lr.sh_dc } else { lr.sh_rest };
        let sh = Rows { used: sh_coeffs(sh_degree.min(p.sh_degree)) * 3, ..rows };
        s.slice_with(&mut p.sh, &g.sh, &mut m.sh, &mut v.sh, &rate, sh);
    }
    let sky = Rows { n: model.sky.texels.len(), used: usize::MAX };
    s.slice(&mut model.sky.texels, sky_grad, &mut state.sky_m, &mut state.sky_v, lr.sky, sky);
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

    /// A two-set model (5000 rows: more than one parallel chunk) of SH degree 3 with values
    /// from `f`.
    fn model(f: &mut dyn FnMut() -> f64) -> SceneModel {
        let set = |n: usize, f: &mut dyn FnMut() -> f64| Gaussians {
            means: (0..n).map(|_| [f(), f(), f()]).collect(),
            log_scales: (0..n).map(|_| [f(), f(), f()]).collect(),
            rotations: (0..n).map(|_| [f(), f(), f(), f()]).collect(),
            opacity_logits: (0..n).map(|_| f()).collect(),
            sh_degree: 3,
            sh: (0..n * 48).map(|_| f()).collect(),
        };
        let actor = crate::model::Actor { track_id: "a".into(), size_lwh: [4.0, 2.0, 1.5], gaussians: set(7, f) };
        SceneModel { background: set(5000, f), actors: vec![actor], sky: crate::sky::Sky::new(2, [0.5; 3]) }
    }

    fn flat(m: &SceneModel) -> Vec<f64> {
        m.sets()
            .flat_map(|g| {
                let mut v = g.means.as_flattened().to_vec();
                v.extend(g.log_scales.as_flattened());
                v.extend(g.rotations.as_flattened());
                v.extend(&g.opacity_logits);
                v.extend(&g.sh);
                v
            })
            .chain(m.sky.texels.iter().copied())
            .collect()
    }

    #[test]
    fn unscheduled_sh_bands_are_skipped_without_changing_a_bit() {
        let mut x = 0.3;
        let mut next = move || {
            x = (x * 7.3 + 0.31) % 1.0;
            x - 0.5
        };
        let m0 = model(&mut next);
        let mut grads: Vec<Gaussians> = m0.sets().map(crate::model::zeros_like).collect();
        let sky_grad: Vec<f64> = (0..m0.sky.texels.len()).map(|_| next()).collect();
        let lr = LearningRates::default();
        for degree in 0..=3 {
            // Gradients only on the bands drawn at `degree`, as the trainer's scatter gives.
            let used = sh_coeffs(degree) * 3;
            for g in &mut grads {
                for (j, v) in g.sh.iter_mut().enumerate() {
                    *v = if j % 48 < used { next() } else { 0.0 };
                }
                g.means.iter_mut().flatten().for_each(|v| *v = next());
                g.opacity_logits.iter_mut().for_each(|v| *v = next());
            }
            let (mut a, mut b) = (m0.clone(), m0.clone());
            let (mut sa, mut sb) = (AdamState::new(&a), AdamState::new(&b));
            for _ in 0..3 {
                adam_step(&mut a, &mut sa, &grads, &sky_grad, &lr, 1e-3, degree);
                adam_step(&mut b, &mut sb, &grads, &sky_grad, &lr, 1e-3, 3);
            }
            let (fa, fb) = (flat(&a), flat(&b));
            assert!(fa.iter().zip(&fb).all(|(x, y)| x.to_bits() == y.to_bits()), "degree {degree}");
            assert!(fa.iter().zip(&flat(&m0)).any(|(x, y)| x != y), "the step moved something");
            assert_eq!(sa, sb, "degree {degree}: moments");
        }
    }

    #[test]
    fn mean_rate_decays_from_start_to_end() {
        let lr = LearningRates::default();
        assert!((means_lr(&lr, 2.0, 0, 100) - 3.2e-4).abs() < 1e-15);
        assert!((means_lr(&lr, 2.0, 100, 100) - 3.2e-6).abs() < 1e-15);
        assert!((means_lr(&lr, 1.0, 50, 100) - 1.6e-5).abs() < 1e-12);
    }
}
