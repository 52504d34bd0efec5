//! Composing the scene at one instant: the background (already in the world) and every actor
//! alive at time `t`, moved by its `world_from_box` (yaw + translation), concatenated into one
//! world-frame `Gaussians` the rasterizer draws; and the way back, from world-frame gradients to
//! each model's own parameters.
//!
//! Per actor Gaussian: `mean_w = R mean_b + t`, `q_w = q_yaw * q_b` (so the normal axis turns
//! with it), scales unchanged, SH coefficients rotated (`sh_rotate`). Gradients: `R^T` for
//! means, the transpose of the left-multiplication matrix of `q_yaw` for quaternions, `M_l` for
//! SH. Only the first `sh_coeffs(active_degree)` coefficients are drawn (the SH schedule).
//!
//! Training composes through two reparametrisations of the models (`Reparam`), both baked into
//! the saved model so no reader needs them: a **mirrored** actor is drawn twice, as its Gaussians
//! and as their mirror images about the box's x-z plane (`mirror_row`: mean (x, -y, z), rotation
//! `M R M` with `M = diag(1, -1, 1)`, i.e. quaternion (w, -x, y, -z), and the SH basis functions odd
//! in y negated), in a part of its own after every unmirrored part; and with the **3D smoothing
//! filter** every row is drawn convolved with its filter (`smoothing::filtered`). The way back
//! (`scatter_rows`) takes both adjoints.

// Index loops mirror the per-component formulas in the comments above.
#![allow(clippy::needless_range_loop)]

use crate::model::SceneModel;
use crate::pose::{box_pose_at, BoxPose};
use crate::sh_rotate::ShRotation;
use rayon::prelude::*;
use scene::Scene;
use splat::sh::sh_coeffs;
use splat::Gaussians;

/// Which model a run of world Gaussians came from.
#[derive(Clone, Debug)]
pub struct Part {
    /// `None` for the background, `Some(i)` for actor `i`.
    pub actor: Option<usize>,
    pub start: usize,
    pub len: usize,
    /// The actor's mirror image (`mirror_row`).
    pub mirror: bool,
    pose: Option<(BoxPose, ShRotation)>,
}

/// A composed scene (reused between iterations: its memory is kept).
#[derive(Clone, Debug)]
pub struct Composed {
    pub world: Gaussians,
    pub parts: Vec<Part>,
    /// With the smoothing filter: per world row, its model row's own log-scales, logit and filter
    /// variance (the filter's Jacobian needs them); empty without.
    pub raw: Vec<([f64; 3], f64, f64)>,
}

impl Default for Composed {
    fn default() -> Self {
        Composed { world: Gaussians::empty(0), parts: vec![], raw: vec![] }
    }
}

/// How training draws the models: which actors are mirrored, and the smoothing filter's variance
/// per set and row (`TrainState::smoothing`). `NONE` draws the models as they are.
#[derive(Clone, Copy, Debug)]
pub struct Reparam<'a> {
    pub mirrored: &'a [bool],
    pub smoothing: Option<&'a [Vec<f64>]>,
}

impl Reparam<'_> {
    pub const NONE: Reparam<'static> = Reparam { mirrored: &[], smoothing: None };

    fn mirrors(&self, actor: usize) -> bool {
        self.mirrored.get(actor).copied().unwrap_or(false)
    }
}

/// SH coefficients (of the basis order of `splat::sh::basis`) whose basis function is odd in y.
pub const Y_ODD_COEFFS: [usize; 6] = [1, 4, 5, 9, 10, 11];

/// Negates the y-odd coefficients of SH rows `sh` (3 values a coefficient): the mirror's SH map,
/// its own inverse and adjoint.
pub fn mirror_sh(sh: &mut [f64]) {
    let n = sh.len();
    for k in Y_ODD_COEFFS.iter().filter(|k| 3 * **k < n) {
        sh[3 * k..3 * k + 3].iter_mut().for_each(|v| *v = -*v);
    }
}

/// Row `i` of `g` mirrored about the x-z plane: its mean and rotation, its SH into `sh`.
pub fn mirror_row(g: &Gaussians, i: usize, sh: &mut [f64]) -> ([f64; 3], [f64; 4]) {
    let [x, y, z] = g.means[i];
    let [qw, qx, qy, qz] = g.rotations[i];
    sh.copy_from_slice(&g.sh_of(i)[..sh.len()]);
    mirror_sh(sh);
    ([x, -y, z], [qw, -qx, qy, -qz])
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
    compose_with(model, scene, t, active_degree, layers, poses, &Reparam::NONE, out);
}

/// [`compose_into`] through the training reparametrisations `rp`: the mirrored actors' mirror
/// images after every other part, and every row smoothed.
#[allow(clippy::too_many_arguments)]
pub fn compose_with(
    model: &SceneModel,
    scene: &Scene,
    t: f64,
    active_degree: usize,
    layers: Layers,
    poses: &dyn Fn(usize) -> Option<Option<BoxPose>>,
    rp: &Reparam,
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
    out.raw.clear();
    if layers != Layers::ActorsOnly {
        push_background(&model.background, active_degree, w);
        out.parts.push(Part { actor: None, start: 0, len: model.background.len(), mirror: false, pose: None });
    }
    if layers != Layers::BackgroundOnly {
        let placed: Vec<(usize, BoxPose)> = (0..model.actors.len())
            .filter_map(|ai| poses(ai).unwrap_or_else(|| actor_pose(model, scene, ai, t)).map(|p| (ai, p)))
            .collect();
        let mirrored = placed.iter().filter(|(ai, _)| rp.mirrors(*ai));
        for (mirror, &(ai, pose)) in placed.iter().map(|p| (false, p)).chain(mirrored.map(|p| (true, p))) {
            let g = &model.actors[ai].gaussians;
            let start = w.len();
            let rot = push_actor_with(g, &pose, active_degree, mirror, w);
            out.parts.push(Part { actor: Some(ai), start, len: g.len(), mirror, pose: Some((pose, rot)) });
        }
    }
    if let Some(f2) = rp.smoothing {
        smooth(model, f2, out);
    }
}

/// Replaces every composed row's log-scales and logit by its smoothed ones, keeping the model
/// row's own values and filter variance in `out.raw` for the way back.
fn smooth(model: &SceneModel, f2: &[Vec<f64>], out: &mut Composed) {
    let sets: Vec<&Gaussians> = model.sets().collect();
    for p in &out.parts {
        let set = p.actor.map_or(0, |a| a + 1);
        let (g, f) = (sets[set], &f2[set]);
        out.raw.extend((0..p.len).map(|j| (g.log_scales[j], g.opacity_logits[j], f.get(j).copied().unwrap_or(0.0))));
    }
    let w = &mut out.world;
    w.log_scales
        .par_iter_mut()
        .zip(w.opacity_logits.par_iter_mut())
        .zip(out.raw.par_iter())
        .for_each(|((ls, lg), &(raw_ls, raw_lg, f2))| (*ls, *lg) = crate::smoothing::filtered(raw_ls, raw_lg, f2));
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
    push_actor_with(g, pose, active_degree, false, w)
}

/// [`push_actor`] of `g`'s mirror image (`mirror_row`) when `mirror`.
fn push_actor_with(g: &Gaussians, pose: &BoxPose, active_degree: usize, mirror: bool, w: &mut Gaussians) -> ShRotation {
    let k = sh_coeffs(active_degree) * 3;
    let r = yaw_rotation(pose.heading);
    let rot = ShRotation::new(g.sh_degree, r);
    let (c, s) = ((pose.heading / 2.0).cos(), (pose.heading / 2.0).sin());
    let mut buf = vec![0.0; k];
    let mut local = vec![0.0; g.coeffs() * 3];
    for i in 0..g.len() {
        let (m, q) = if mirror { mirror_row(g, i, &mut local) } else { (g.means[i], g.rotations[i]) };
        w.means.push(std::array::from_fn(|a| (0..3).map(|b| r[a][b] * m[b]).sum::<f64>() + pose.center[a]));
        w.log_scales.push(g.log_scales[i]);
        let [qw, qx, qy, qz] = q;
        w.rotations.push([c * qw - s * qz, c * qx - s * qy, c * qy + s * qx, c * qz + s * qw]);
        w.opacity_logits.push(g.opacity_logits[i]);
        rot.to_world(if mirror { &local } else { g.sh_of(i) }, &mut buf, active_degree);
        w.sh.extend_from_slice(&buf);
    }
    rot
}

mod scatter;
pub use scatter::{clear_gradients, scatter_gradients, scatter_rows};

#[cfg(test)]
mod tests;
