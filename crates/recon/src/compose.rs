//! Composing the scene at one instant: the background (already in the world) and every actor
//! alive at time `t`, moved by its `world_from_box` (yaw + translation), concatenated into one
//! world-frame `Gaussians` the rasterizer draws; and the way back, from world-frame gradients to
//! each model's own parameters.
//!
//! Per actor Gaussian: `mean_w = R mean_b + t`, `q_w = q_yaw * q_b` (so the normal axis turns
//! with it), scales unchanged, SH coefficients rotated (`sh_rotate`). Gradients: `R^T` for
//! means, the transpose of the left-multiplication matrix of `q_yaw` for quaternions, `M_l` for
//! SH. Only the first `sh_coeffs(active_degree)` coefficients are drawn (the SH schedule).

// Index loops mirror the per-component formulas in the comments above.
#![allow(clippy::needless_range_loop)]

use crate::model::{clear, SceneModel};
use crate::pose::{box_pose_at, BoxPose};
use crate::sh_rotate::ShRotation;
use rayon::prelude::*;
use scene::Scene;
use splat::backward::Gradients;
use splat::sh::sh_coeffs;
use splat::Gaussians;

/// Which model a run of world Gaussians came from.
#[derive(Clone, Debug)]
pub struct Part {
    /// `None` for the background, `Some(i)` for actor `i`.
    pub actor: Option<usize>,
    pub start: usize,
    pub len: usize,
    pose: Option<(BoxPose, ShRotation)>,
}

/// A composed scene (reused between iterations: its memory is kept).
#[derive(Clone, Debug)]
pub struct Composed {
    pub world: Gaussians,
    pub parts: Vec<Part>,
}

impl Default for Composed {
    fn default() -> Self {
        Composed { world: Gaussians::empty(0), parts: vec![] }
    }
}

/// Actor `i`'s pose at `t`, or `None` when its track has no valid state around `t`.
pub fn actor_pose(model: &SceneModel, scene: &Scene, i: usize, t: f64) -> Option<BoxPose> {
    scene.track(&model.actors[i].track_id).and_then(|tr| box_pose_at(scene, tr, t))
}

pub(crate) fn yaw_rotation(h: f64) -> [[f64; 3]; 3] {
    [[h.cos(), -h.sin(), 0.0], [h.sin(), h.cos(), 0.0], [0.0, 0.0, 1.0]]
}

/// Which models to draw.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Layers {
    All,
    /// Actors only (for actor masks).
    ActorsOnly,
    /// The background only.
    BackgroundOnly,
}

/// Composes the scene at time `t`. `poses` overrides actor poses (by actor index; an override of
/// `Some(pose)` draws the actor there even outside its logged lifespan).
pub fn compose_into(
    model: &SceneModel,
    scene: &Scene,
    t: f64,
    active_degree: usize,
    layers: Layers,
    poses: &dyn Fn(usize) -> Option<Option<BoxPose>>,
    out: &mut Composed,
) {
    let w = &mut out.world;
    w.sh_degree = active_degree;
    w.means.clear();
    w.log_scales.clear();
    w.rotations.clear();
    w.opacity_logits.clear();
    w.sh.clear();
    out.parts.clear();
    if layers != Layers::ActorsOnly {
        push_background(&model.background, active_degree, w);
        out.parts.push(Part { actor: None, start: 0, len: model.background.len(), pose: None });
    }
    if layers == Layers::BackgroundOnly {
        return;
    }
    for (ai, actor) in model.actors.iter().enumerate() {
        let pose = poses(ai).unwrap_or_else(|| actor_pose(model, scene, ai, t));
        let Some(pose) = pose else { continue };
        let start = w.len();
        let rot = push_actor(&actor.gaussians, &pose, active_degree, w);
        out.parts.push(Part { actor: Some(ai), start, len: actor.gaussians.len(), pose: Some((pose, rot)) });
    }
}

/// Appends the background `bg` (already in the world) to `w`, with its first
/// `sh_coeffs(active_degree)` SH coefficients.
/// The copy runs on every thread (indexed `par_extend` writes in place): it is a training step's
/// largest serial memory pass otherwise.
pub(crate) fn push_background(bg: &Gaussians, active_degree: usize, w: &mut Gaussians) {
    let k = sh_coeffs(active_degree) * 3;
    let kc = bg.coeffs() * 3;
    w.means.par_extend(bg.means.par_iter().copied());
    w.log_scales.par_extend(bg.log_scales.par_iter().copied());
    w.rotations.par_extend(bg.rotations.par_iter().copied());
    w.opacity_logits.par_extend(bg.opacity_logits.par_iter().copied());
    if k == kc {
        w.sh.par_extend(bg.sh.par_iter().copied());
    } else {
        w.sh.par_extend((0..bg.len() * k).into_par_iter().map(|j| bg.sh[j / k * kc + j % k]));
    }
}

/// Appends the actor Gaussians `g` (box frame) placed at `pose` to the world set `w`, with the
/// first `sh_coeffs(active_degree)` SH coefficients rotated; returns the SH rotation used.
pub(crate) fn push_actor(g: &Gaussians, pose: &BoxPose, active_degree: usize, w: &mut Gaussians) -> ShRotation {
    let k = sh_coeffs(active_degree) * 3;
    let r = yaw_rotation(pose.heading);
    let rot = ShRotation::new(g.sh_degree, r);
    let (c, s) = ((pose.heading / 2.0).cos(), (pose.heading / 2.0).sin());
    let mut buf = vec![0.0; k];
    for i in 0..g.len() {
        let m = g.means[i];
        w.means.push(std::array::from_fn(|a| (0..3).map(|b| r[a][b] * m[b]).sum::<f64>() + pose.center[a]));
        w.log_scales.push(g.log_scales[i]);
        let [qw, qx, qy, qz] = g.rotations[i];
        w.rotations.push([c * qw - s * qz, c * qx - s * qy, c * qy + s * qx, c * qz + s * qw]);
        w.opacity_logits.push(g.opacity_logits[i]);
        rot.to_world(g.sh_of(i), &mut buf, active_degree);
        w.sh.extend_from_slice(&buf);
    }
    rot
}

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
    if let Some(dst) = grads.first_mut() {
        par_rows(dst, &background, &|i, row| {
            for a in 0..3 {
                row.log_scales[a] += gw.log_scales[i][a];
            }
            *row.opacity += gw.opacity_logits[i];
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
    for a in 0..3 {
        dst.log_scales[i][a] += gw.log_scales[wi][a];
    }
    dst.opacity_logits[i] += gw.opacity_logits[wi];
    let r = yaw_rotation(pose.heading);
    let gm = gw.means[wi];
    for a in 0..3 {
        dst.means[i][a] += (0..3).map(|b| r[b][a] * gm[b]).sum::<f64>();
    }
    let (c, s) = ((pose.heading / 2.0).cos(), (pose.heading / 2.0).sin());
    let [gw_, gx, gy, gz] = gw.rotations[wi];
    let q = &mut dst.rotations[i];
    q[0] += c * gw_ + s * gz;
    q[1] += c * gx + s * gy;
    q[2] += -s * gx + c * gy;
    q[3] += -s * gw_ + c * gz;
    rot.grad_to_local(&gw.sh[wi * k..(wi + 1) * k], &mut dst.sh[i * kd..(i + 1) * kd], active);
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
fn zero_rows(grads: &mut [Gaussians], rows: &[(usize, usize)], degree: usize) {
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

#[cfg(test)]
mod tests;
