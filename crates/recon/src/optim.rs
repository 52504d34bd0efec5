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

    /// One learning rate over equal-length slices: no per-element call, so the loop vectorises
    /// (IEEE square root and division round the same in vector and scalar form: the same bits).
    #[inline(always)]
    fn run(&self, p: &mut [f64], g: &[f64], m: &mut [f64], v: &mut [f64], lr: f64) {
        let n = p.len();
        let (g, m, v) = (&g[..n], &mut m[..n], &mut v[..n]);
        for i in 0..n {
            self.apply(&mut p[i], g[i], &mut m[i], &mut v[i], lr);
        }
    }

    /// Every row of a chunk: at once when one segment spans the row, whole short rows with a rate
    /// per column, else segment by segment.
    #[inline(always)]
    fn chunk(&self, p: &mut [f64], g: &[f64], m: &mut [f64], v: &mut [f64], rows: &Rows) {
        let w = rows.width;
        if let Some(rates) = &rows.rates {
            let rates = &rates[..w];
            let rows =
                p.chunks_exact_mut(w).zip(g.chunks_exact(w)).zip(m.chunks_exact_mut(w)).zip(v.chunks_exact_mut(w));
            for (((p, g), m), v) in rows {
                for j in 0..w {
                    self.apply(&mut p[j], g[j], &mut m[j], &mut v[j], rates[j]);
                }
            }
            return;
        }
        match rows.segments {
            ((0, end, lr), None) if end == w => self.run(p, g, m, v, lr),
            (first, second) => {
                for r in 0..p.len() / w {
                    for (a, b, lr) in std::iter::once(first).chain(second) {
                        let (a, b) = (r * w + a, r * w + b);
                        self.run(&mut p[a..b], &g[a..b], &mut m[a..b], &mut v[a..b], lr);
                    }
                }
            }
        }
    }

    /// `chunk` built for AVX2 where the CPU has it (4 lanes of f64), else for the baseline.
    fn chunk_dispatch(&self, p: &mut [f64], g: &[f64], m: &mut [f64], v: &mut [f64], rows: &Rows) {
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx2")]
            unsafe fn avx2(s: &Step, p: &mut [f64], g: &[f64], m: &mut [f64], v: &mut [f64], rows: &Rows) {
                s.chunk(p, g, m, v, rows)
            }
            if std::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU supports AVX2 (checked at run time just above).
                return unsafe { avx2(self, p, g, m, v, rows) };
            }
        }
        self.chunk(p, g, m, v, rows)
    }

    /// Element-wise over the rows, in parallel chunks of rows (each element is independent, so
    /// the result does not depend on the thread count).
    fn slice(&self, p: &mut [f64], g: &[f64], m: &mut [f64], v: &mut [f64], rows: Rows) {
        const ROWS: usize = 1 << 11;
        if rows.width == 0 || p.is_empty() {
            return;
        }
        let chunk = ROWS * rows.width;
        p.par_chunks_mut(chunk)
            .zip(m.par_chunks_mut(chunk))
            .zip(v.par_chunks_mut(chunk))
            .enumerate()
            .for_each(|(c, ((p, m), v))| self.chunk_dispatch(p, &g[c * chunk..c * chunk + p.len()], m, v, &rows));
    }
}

/// How Adam walks one parameter array: rows of `width` elements, and in each row one or two
/// segments `(start, end, learning rate)`. An SH row has its DC coefficients at one rate and the
/// rest at another, and ends at the bands the schedule has drawn: the coefficients of the bands
/// not drawn yet have zero gradients and both moments zero, so Adam would leave them as they
/// are; skipping them gives the same bits.
///
/// Rows of at most [`SHORT`] values (an SH row of degree 1 or less) go whole instead, with a rate
/// per column (`rates`): a band not drawn yet is left as it is by the step itself (a zero
/// gradient and zero moments move nothing, to the bit), and a few scalar values at a stride of
/// the row are slower than the whole row in vector form (stop 50: the DC coefficients, 3 of each
/// row of 12, were most of Adam's time).
#[derive(Clone, Copy)]
struct Rows {
    width: usize,
    segments: (Segment, Option<Segment>),
    rates: Option<[f64; SHORT]>,
}

/// The longest row Adam takes whole with a rate per column.
const SHORT: usize = 12;

/// `(start, end, learning rate)` within a row.
type Segment = (usize, usize, f64);

impl Rows {
    /// Whole rows of `width` at rate `lr`.
    fn whole(width: usize, lr: f64) -> Rows {
        Rows { width, segments: ((0, width, lr), None), rates: None }
    }
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
        s.slice(
            p.means.as_flattened_mut(),
            g.means.as_flattened(),
            m.means.as_flattened_mut(),
            v.means.as_flattened_mut(),
            Rows::whole(3, mean_lr),
        );
        s.slice(
            p.log_scales.as_flattened_mut(),
            g.log_scales.as_flattened(),
            m.log_scales.as_flattened_mut(),
            v.log_scales.as_flattened_mut(),
            Rows::whole(3, lr.log_scales),
        );
        s.slice(
            p.rotations.as_flattened_mut(),
            g.rotations.as_flattened(),
            m.rotations.as_flattened_mut(),
            v.rotations.as_flattened_mut(),
            Rows::whole(4, lr.rotations),
        );
        s.slice(
            &mut p.opacity_logits,
            &g.opacity_logits,
            &mut m.opacity_logits,
            &mut v.opacity_logits,
            Rows::whole(1, lr.opacity),
        );
        // DC (3 values) at `sh_dc`, the drawn higher bands at `sh_rest`.
        let (k, used) = (p.coeffs() * 3, sh_coeffs(sh_degree.min(p.sh_degree)) * 3);
        let rest = (used > 3).then_some((3, used, lr.sh_rest));
        let rates = (k > 3 && k <= SHORT).then(|| std::array::from_fn(|j| if j < 3 { lr.sh_dc } else { lr.sh_rest }));
        let sh = Rows { width: k, segments: ((0, 3.min(k), lr.sh_dc), rest), rates };
        s.slice(&mut p.sh, &g.sh, &mut m.sh, &mut v.sh, sh);
    }
    s.slice(&mut model.sky.texels, sky_grad, &mut state.sky_m, &mut state.sky_v, Rows::whole(1, lr.sky));
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

    /// A two-set model (5000 rows: more than one parallel chunk) of SH degree `degree` with
    /// values from `f`.
    fn model(degree: usize, f: &mut dyn FnMut() -> f64) -> SceneModel {
        let k = sh_coeffs(degree) * 3;
        let set = |n: usize, f: &mut dyn FnMut() -> f64| Gaussians {
            means: (0..n).map(|_| [f(), f(), f()]).collect(),
            log_scales: (0..n).map(|_| [f(), f(), f()]).collect(),
            rotations: (0..n).map(|_| [f(), f(), f(), f()]).collect(),
            opacity_logits: (0..n).map(|_| f()).collect(),
            sh_degree: degree,
            sh: (0..n * k).map(|_| f()).collect(),
        };
        let actor = crate::model::Actor { track_id: "a".into(), size_lwh: [4.0, 2.0, 1.5], gaussians: set(7, f) };
        SceneModel {
            antialiased: false,
            background: set(5000, f),
            actors: vec![actor],
            sky: crate::sky::Sky::new(2, [0.5; 3]),
        }
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

    /// Degree 3 (SH rows of 48: the bands not drawn are skipped) and degree 1 (rows of 12: taken
    /// whole with a rate per column).
    #[test]
    fn unscheduled_sh_bands_are_skipped_without_changing_a_bit() {
        for stored in [3, 1] {
            unscheduled_bands(stored);
        }
    }

    fn unscheduled_bands(stored: usize) {
        let mut x = 0.3;
        let mut next = move || {
            x = (x * 7.3 + 0.31) % 1.0;
            x - 0.5
        };
        let m0 = model(stored, &mut next);
        let k = sh_coeffs(stored) * 3;
        let mut grads: Vec<Gaussians> = m0.sets().map(crate::model::zeros_like).collect();
        let sky_grad: Vec<f64> = (0..m0.sky.texels.len()).map(|_| next()).collect();
        let lr = LearningRates::default();
        for degree in 0..=stored {
            // Gradients only on the bands drawn at `degree`, as the trainer's scatter gives.
            let used = sh_coeffs(degree) * 3;
            for g in &mut grads {
                for (j, v) in g.sh.iter_mut().enumerate() {
                    *v = if j % k < used { next() } else { 0.0 };
                }
                g.means.iter_mut().flatten().for_each(|v| *v = next());
                g.opacity_logits.iter_mut().for_each(|v| *v = next());
            }
            let (mut a, mut b) = (m0.clone(), m0.clone());
            let (mut sa, mut sb) = (AdamState::new(&a), AdamState::new(&b));
            for _ in 0..3 {
                adam_step(&mut a, &mut sa, &grads, &sky_grad, &lr, 1e-3, degree);
                adam_step(&mut b, &mut sb, &grads, &sky_grad, &lr, 1e-3, stored);
            }
            let (fa, fb) = (flat(&a), flat(&b));
            assert!(fa.iter().zip(&fb).all(|(x, y)| x.to_bits() == y.to_bits()), "degree {degree}");
            // ...and both are the plain per-element loop over every value.
            let mut c = m0.clone();
            let mut sc = AdamState::new(&c);
            for t in 1..=3 {
                let s = Step { bc1: 1.0 - BETA1.powi(t), bc2: 1.0 - BETA2.powi(t) };
                let sets: Vec<&mut Gaussians> = c.sets_mut().collect();
                for (((p, g), m), v) in sets.into_iter().zip(&grads).zip(&mut sc.m).zip(&mut sc.v) {
                    let each = |p: &mut [f64], g: &[f64], m: &mut [f64], v: &mut [f64], lr: &dyn Fn(usize) -> f64| {
                        for i in 0..p.len() {
                            s.apply(&mut p[i], g[i], &mut m[i], &mut v[i], lr(i));
                        }
                    };
                    let (pm, gm, mm, vm) = (&mut p.means, &g.means, &mut m.means, &mut v.means);
                    each(
                        pm.as_flattened_mut(),
                        gm.as_flattened(),
                        mm.as_flattened_mut(),
                        vm.as_flattened_mut(),
                        &|_| 1e-3,
                    );
                    let (ps, gs, ms, vs) = (&mut p.log_scales, &g.log_scales, &mut m.log_scales, &mut v.log_scales);
                    let r = lr.log_scales;
                    each(
                        ps.as_flattened_mut(),
                        gs.as_flattened(),
                        ms.as_flattened_mut(),
                        vs.as_flattened_mut(),
                        &|_| r,
                    );
                    let (pr, gr, mr, vr) = (&mut p.rotations, &g.rotations, &mut m.rotations, &mut v.rotations);
                    let r = lr.rotations;
                    each(
                        pr.as_flattened_mut(),
                        gr.as_flattened(),
                        mr.as_flattened_mut(),
                        vr.as_flattened_mut(),
                        &|_| r,
                    );
                    let r = lr.opacity;
                    each(
                        &mut p.opacity_logits,
                        &g.opacity_logits,
                        &mut m.opacity_logits,
                        &mut v.opacity_logits,
                        &|_| r,
                    );
                    let (dc, rest) = (lr.sh_dc, lr.sh_rest);
                    each(&mut p.sh, &g.sh, &mut m.sh, &mut v.sh, &|j| if j % k < 3 { dc } else { rest });
                }
                let r = lr.sky;
                let (pk, mk, vk) = (&mut c.sky.texels, &mut sc.sky_m, &mut sc.sky_v);
                for i in 0..pk.len() {
                    s.apply(&mut pk[i], sky_grad[i], &mut mk[i], &mut vk[i], r);
                }
            }
            assert!(flat(&c).iter().zip(&fa).all(|(x, y)| x.to_bits() == y.to_bits()), "degree {degree}: plain loop");
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
