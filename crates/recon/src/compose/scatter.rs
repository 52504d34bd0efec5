//! The way back from a composed scene (`compose`): world-frame gradients to each model's own
//! parameters, through the yaw placement (`R^T` for means, the transpose of `q_yaw`'s
//! left-multiplication for quaternions, `M_l` for SH), the mirror (its own adjoint: y negated, the
//! quaternion's x and z negated, the y-odd SH negated) and the smoothing filter
//! (`smoothing::filtered_grad`); and the per-model gradient buffers' upkeep.

// Index loops mirror the per-component formulas in the comments above.
#![allow(clippy::needless_range_loop)]

use super::{mirror_sh, yaw_rotation, Composed};
use crate::model::{clear, SceneModel};
use rayon::prelude::*;
use splat::backward::Gradients;
use splat::sh::sh_coeffs;
use splat::Gaussians;

/// Adds the world-frame gradients `gw` of a composed scene to per-model gradients `grads`
/// (background first, then actors: the order of `SceneModel::sets`), each shaped like its model.
pub fn scatter_gradients(composed: &Composed, gw: &Gradients, grads: &mut [Gaussians]) {
    let every: Vec<usize> = (0..composed.world.len()).collect();
    scatter_rows(composed, gw, grads, &every);
}

/// [`scatter_gradients`] for the world rows `world_rows` only: the same sums where every other
/// row's world gradient is zero (a Gaussian the view did not draw has none), without visiting the
/// rest of the scene. The background's rows (most of them) are added in parallel chunks of rows.
pub fn scatter_rows(composed: &Composed, gw: &Gradients, grads: &mut [Gaussians], world_rows: &[usize]) {
    // The background, when drawn, is the first part: world rows [0, n) in its own order; every
    // other part is an actor's, with its pose.
    let n = composed.parts.first().filter(|p| p.actor.is_none()).map_or(0, |p| p.len);
    let (mut background, actors): (Vec<usize>, Vec<usize>) = world_rows.iter().partition(|&&wi| wi < n);
    background.sort_unstable();
    let k = sh_coeffs(composed.world.sh_degree) * 3;
    let raw = &composed.raw;
    if let Some(dst) = grads.first_mut() {
        par_rows(dst, &background, &|i, row| {
            let (g_ls, g_logit) = unsmoothed(raw, i, gw);
            for a in 0..3 {
                row.log_scales[a] += g_ls[a];
            }
            *row.opacity += g_logit;
            for a in 0..3 {
                row.means[a] += gw.means[i][a];
            }
            for a in 0..4 {
                row.rotations[a] += gw.rotations[i][a];
            }
            for (d, g) in row.sh.iter_mut().zip(&gw.sh[i * k..(i + 1) * k]) {
                *d += g;
            }
        });
    }
    for &wi in &actors {
        if let Some((pi, j)) = composed.owner(wi) {
            scatter_actor_row(composed, pi, j, gw, grads);
        }
    }
}

/// World row `wi`'s gradients on its model row's own log-scales and logit: through the smoothing
/// filter's Jacobian when the scene was composed with one (`Composed::raw`).
fn unsmoothed(raw: &[([f64; 3], f64, f64)], wi: usize, gw: &Gradients) -> ([f64; 3], f64) {
    match raw.get(wi) {
        Some(&(ls, logit, f2)) => {
            crate::smoothing::filtered_grad(ls, logit, f2, gw.log_scales[wi], gw.opacity_logits[wi])
        }
        None => (gw.log_scales[wi], gw.opacity_logits[wi]),
    }
}

/// One row of a `Gaussians`, borrowed field by field.
struct RowMut<'a> {
    means: &'a mut [f64; 3],
    log_scales: &'a mut [f64; 3],
    rotations: &'a mut [f64; 4],
    opacity: &'a mut f64,
    sh: &'a mut [f64],
}

/// Calls `f(i, row i)` for every row `i` of the ascending list `rows`, in parallel chunks of rows
/// (each row is visited once, so the result does not depend on the thread count).
fn par_rows(g: &mut Gaussians, rows: &[usize], f: &(dyn Fn(usize, RowMut) + Sync)) {
    const R: usize = 1 << 12;
    let kd = g.coeffs() * 3;
    let Gaussians { means, log_scales, rotations, opacity_logits, sh, .. } = g;
    let chunks = means.par_chunks_mut(R).zip(log_scales.par_chunks_mut(R)).zip(rotations.par_chunks_mut(R));
    chunks.zip(opacity_logits.par_chunks_mut(R)).zip(sh.par_chunks_mut(R * kd)).enumerate().for_each(
        |(c, ((((m, s), q), o), sh))| {
            let (lo, hi) = (rows.partition_point(|&i| i < c * R), rows.partition_point(|&i| i < (c + 1) * R));
            for &i in &rows[lo..hi] {
                let j = i - c * R;
                let row = RowMut {
                    means: &mut m[j],
                    log_scales: &mut s[j],
                    rotations: &mut q[j],
                    opacity: &mut o[j],
                    sh: &mut sh[j * kd..(j + 1) * kd],
                };
                f(i, row);
            }
        },
    );
}

impl Composed {
    /// The part holding world row `wi` and the row's index in that part.
    pub fn owner(&self, wi: usize) -> Option<(usize, usize)> {
        let pi = self.parts.partition_point(|p| p.start + p.len <= wi);
        let p = self.parts.get(pi)?;
        (wi >= p.start && wi < p.start + p.len).then(|| (pi, wi - p.start))
    }

    /// The set (0 the background, `a + 1` actor `a`) and row of world row `wi`.
    pub fn set_row(&self, wi: usize) -> Option<(usize, usize)> {
        self.owner(wi).map(|(pi, j)| (self.parts[pi].actor.map_or(0, |a| a + 1), j))
    }
}

/// Row `j` of actor part `pi`: world gradients back to its box frame, added to `grads`.
fn scatter_actor_row(composed: &Composed, pi: usize, j: usize, gw: &Gradients, grads: &mut [Gaussians]) {
    let part = &composed.parts[pi];
    let (Some(actor), Some((pose, rot))) = (part.actor, &part.pose) else {
        debug_assert!(false, "part {pi} is the background: its rows are scattered by par_rows");
        return;
    };
    let active = composed.world.sh_degree;
    let k = sh_coeffs(active) * 3;
    let dst = &mut grads[actor + 1];
    let kd = dst.coeffs() * 3;
    let (i, wi) = (j, part.start + j);
    let (g_ls, g_logit) = unsmoothed(&composed.raw, wi, gw);
    for a in 0..3 {
        dst.log_scales[i][a] += g_ls[a];
    }
    dst.opacity_logits[i] += g_logit;
    let r = yaw_rotation(pose.heading);
    let gm = gw.means[wi];
    // The mirror (y -> -y, quaternion (w, -x, y, -z), y-odd SH negated) is its own adjoint.
    let my = if part.mirror { -1.0 } else { 1.0 };
    for a in 0..3 {
        let g = (0..3).map(|b| r[b][a] * gm[b]).sum::<f64>();
        dst.means[i][a] += if a == 1 { my * g } else { g };
    }
    let (c, s) = ((pose.heading / 2.0).cos(), (pose.heading / 2.0).sin());
    let [gw_, gx, gy, gz] = gw.rotations[wi];
    let q = &mut dst.rotations[i];
    q[0] += c * gw_ + s * gz;
    q[1] += my * (c * gx + s * gy);
    q[2] += -s * gx + c * gy;
    q[3] += my * (-s * gw_ + c * gz);
    if part.mirror {
        let mut local = vec![0.0; kd];
        rot.grad_to_local(&gw.sh[wi * k..(wi + 1) * k], &mut local, active);
        mirror_sh(&mut local);
        dst.sh[i * kd..(i + 1) * kd].iter_mut().zip(&local).for_each(|(d, g)| *d += g);
    } else {
        rot.grad_to_local(&gw.sh[wi * k..(wi + 1) * k], &mut dst.sh[i * kd..(i + 1) * kd], active);
    }
}

/// Readies per-model gradient buffers for a scatter: when they are shaped like the model and
/// `touched` names the SH degree and (set, row)s the last scatter wrote, only those rows are
/// zeroed; otherwise every buffer is zeroed, reshaped to the model.
pub fn clear_gradients(model: &SceneModel, grads: &mut Vec<Gaussians>, touched: Option<(usize, &[(usize, usize)])>) {
    let shaped = grads.len() == model.actors.len() + 1
        && grads.iter().zip(model.sets()).all(|(g, m)| g.len() == m.len() && g.sh_degree == m.sh_degree);
    match touched {
        Some((degree, rows)) if shaped => zero_rows(grads, rows, degree),
        _ => reset_gradients(model, grads),
    }
}

/// Zeroes rows `rows` (set, row) of per-model gradient buffers already shaped like the model,
/// which a scatter at SH degree `degree` wrote (the coefficients of higher bands it left zero).
pub(super) fn zero_rows(grads: &mut [Gaussians], rows: &[(usize, usize)], degree: usize) {
    let zero = |row: RowMut, used: usize| {
        *row.means = [0.0; 3];
        *row.log_scales = [0.0; 3];
        *row.rotations = [0.0; 4];
        *row.opacity = 0.0;
        row.sh[..used].fill(0.0);
    };
    let mut by_set: Vec<Vec<usize>> = vec![Vec::new(); grads.len()];
    rows.iter().for_each(|&(set, i)| by_set[set].push(i));
    for (g, mut rows) in grads.iter_mut().zip(by_set) {
        if rows.is_empty() {
            continue;
        }
        rows.sort_unstable();
        let used = sh_coeffs(degree.min(g.sh_degree)) * 3;
        par_rows(g, &rows, &|_, row| zero(row, used));
    }
}

/// Zeroes per-model gradient buffers, resizing them to the model's current shape.
fn reset_gradients(model: &SceneModel, grads: &mut Vec<Gaussians>) {
    grads.resize_with(model.actors.len() + 1, || Gaussians::empty(0));
    for (g, m) in grads.iter_mut().zip(model.sets()) {
        if g.len() != m.len() || g.sh_degree != m.sh_degree {
            *g = crate::model::zeros_like(m);
        } else {
            clear(g);
        }
    }
}
