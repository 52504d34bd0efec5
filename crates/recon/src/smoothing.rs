//! Mip-Splatting's 3D smoothing filter (Yu et al., CVPR 2024): a Gaussian can be no finer than the
//! finest pixel footprint any training view saw it with. Without it, optimisation shrinks Gaussians
//! below what the images could tell (a car seen from 20 m is drawn by needles a centimetre wide),
//! and a view closer than any training view (the climax of a corner case) shows the needles as
//! shards and the gaps between them as holes.
//!
//! Each row's footprint: over the training views that see its centre (in front, deeper than
//! [`MIN_DEPTH_M`], within [`MARGIN`] of the image on every side, as Mip-Splatting), the largest
//! sampling rate `focal / depth` (pixels a metre); the filter is an isotropic Gaussian of variance
//! `f^2 = filter_3d / rate^2` (m^2; Mip-Splatting's `filter_3d` is 0.2 px^2). A row no view sees
//! takes the largest `f^2` of the rows that are seen. Actor rows are in their box frame: a view sees
//! them through `camera_from_world * world_from_box` at the view's time, and a mirrored actor's row
//! (`mirror`) counts its mirror image's views too. Convolving the row's Gaussian with the filter:
//! `s'^2 = s^2 + f^2` per axis, opacity `o' = o sqrt(prod s^2 / prod (s^2 + f^2))` (the peak drops as
//! the mass spreads), written here on log-scales and opacity logits, with the exact Jacobian for
//! the way back (`filtered_grad`). The trainer keeps `f^2` per row (`TrainState::smoothing`),
//! recomputes it after density control and at intervals (`due`), and bakes the filter into the
//! saved model (`bake`), so every reader draws it without knowing of it.

use crate::data::View;
use crate::model::SceneModel;
use crate::pose::box_pose_at;
use rayon::prelude::*;
use scene::Scene;

/// Centres nearer than this (m) to a camera plane are not sampled (Mip-Splatting's 0.2).
pub const MIN_DEPTH_M: f64 = 0.2;
/// The image is widened by this fraction on every side (Mip-Splatting's 0.15).
pub const MARGIN: f64 = 0.15;

/// One view of one set: `camera_from_set` (rows of a rigid 3x4), intrinsics and image size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sampler {
    pub m: [[f64; 4]; 3],
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub width: f64,
    pub height: f64,
}

impl Sampler {
    fn new(cam: &splat::Camera, m: [[f64; 4]; 3]) -> Sampler {
        Sampler {
            m,
            fx: cam.fx,
            fy: cam.fy,
            cx: cam.cx,
            cy: cam.cy,
            width: cam.width as f64,
            height: cam.height as f64,
        }
    }

    /// The sampling rate (pixels a metre) at set-frame point `p`, or 0 where this view misses it.
    pub fn rate(&self, p: [f64; 3]) -> f64 {
        let q: [f64; 3] =
            std::array::from_fn(|r| self.m[r][0] * p[0] + self.m[r][1] * p[1] + self.m[r][2] * p[2] + self.m[r][3]);
        // NaN is not deep enough either.
        if q[2].is_nan() || q[2] <= MIN_DEPTH_M {
            return 0.0;
        }
        let (u, v) = (self.fx * q[0] / q[2] + self.cx, self.fy * q[1] / q[2] + self.cy);
        let inside = u >= -MARGIN * self.width
            && u <= (1.0 + MARGIN) * self.width
            && v >= -MARGIN * self.height
            && v <= (1.0 + MARGIN) * self.height;
        if inside {
            self.fx.max(self.fy) / q[2]
        } else {
            0.0
        }
    }
}

/// The training views as samplers of every set of `model` (background first, then each actor
/// through its box at the view's time, where it has a pose then).
pub fn samplers(model: &SceneModel, scene: &Scene, views: &[View]) -> Vec<Vec<Sampler>> {
    let training: Vec<&View> = views.iter().filter(|v| !v.held_out).collect();
    let rows = |m: &[[f64; 4]; 4]| [m[0], m[1], m[2]];
    let mut out = vec![training.iter().map(|v| Sampler::new(&v.cam, rows(&v.cam.camera_from_world))).collect()];
    for a in &model.actors {
        let track = scene.track(&a.track_id);
        out.push(
            training
                .iter()
                .filter_map(|v| {
                    let pose = box_pose_at(scene, track?, v.time)?;
                    let w = pose.world_from_box().0;
                    let (r, t) = (w.matrix3, w.translation);
                    let c = &v.cam.camera_from_world;
                    // camera_from_box = camera_from_world * world_from_box.
                    let m: [[f64; 4]; 3] = std::array::from_fn(|i| {
                        let col = |j: usize| (0..3).map(|k| c[i][k] * r.col(j)[k]).sum::<f64>();
                        [col(0), col(1), col(2), (0..3).map(|k| c[i][k] * t[k]).sum::<f64>() + c[i][3]]
                    });
                    Some(Sampler::new(&v.cam, m))
                })
                .collect(),
        );
    }
    out
}

/// The filter variance (m^2) of every row of every set of `model` under `factor` (`filter_3d`);
/// `mirrored[a]` counts actor `a`'s rows' mirror images (y -> -y) too. With `actors_only` the
/// background's rows get none, and the unseen rows' fill is the largest of the actors' seen rows.
pub fn variances(
    model: &SceneModel,
    samplers: &[Vec<Sampler>],
    factor: f64,
    mirrored: &[bool],
    actors_only: bool,
) -> Vec<Vec<f64>> {
    let rates: Vec<Vec<f64>> = model
        .sets()
        .enumerate()
        .map(|(k, g)| {
            if k == 0 && actors_only {
                return vec![-1.0; g.len()];
            }
            let mirror = k > 0 && mirrored.get(k - 1).copied().unwrap_or(false);
            let s = &samplers[k];
            g.means
                .par_iter()
                .map(|p| {
                    let own = s.iter().map(|x| x.rate(*p)).fold(0.0, f64::max);
                    if mirror {
                        let q = [p[0], -p[1], p[2]];
                        s.iter().map(|x| x.rate(q)).fold(own, f64::max)
                    } else {
                        own
                    }
                })
                .collect()
        })
        .collect();
    let var = |rate: f64| factor / (rate * rate);
    let unseen = rates.iter().flatten().filter(|r| **r > 0.0).map(|r| var(*r)).fold(0.0, f64::max);
    // A rate of -1 marks a row the filter leaves alone.
    let of = |r: f64| {
        if r > 0.0 {
            var(r)
        } else if r < 0.0 {
            0.0
        } else {
            unseen
        }
    };
    rates.into_iter().map(|rs| rs.into_iter().map(of).collect()).collect()
}

/// The log-scales and opacity logit of a row convolved with a filter of variance `f2`.
pub fn filtered(log_scales: [f64; 3], logit: f64, f2: f64) -> ([f64; 3], f64) {
    let s2 = log_scales.map(|l| (2.0 * l).exp());
    let ls = std::array::from_fn(|a| 0.5 * (s2[a] + f2).ln());
    let c = (0..3).map(|a| s2[a] / (s2[a] + f2)).product::<f64>().sqrt();
    let sig = splat::gaussians::sigmoid(logit);
    // 1 - o' = (1 - sigma) + sigma (1 - c), without cancelling.
    let one_minus = splat::gaussians::sigmoid(-logit) + sig * (1.0 - c);
    (ls, (sig * c).ln() - one_minus.ln())
}

/// The gradients on a row's own log-scales and logit from those on its filtered ones
/// (`g_ls`, `g_logit`).
pub fn filtered_grad(log_scales: [f64; 3], logit: f64, f2: f64, g_ls: [f64; 3], g_logit: f64) -> ([f64; 3], f64) {
    let s2 = log_scales.map(|l| (2.0 * l).exp());
    let c = (0..3).map(|a| s2[a] / (s2[a] + f2)).product::<f64>().sqrt();
    let sig = splat::gaussians::sigmoid(logit);
    let one_minus = splat::gaussians::sigmoid(-logit) + sig * (1.0 - c);
    let ls = std::array::from_fn(|a| g_ls[a] * s2[a] / (s2[a] + f2) + g_logit * f2 / ((s2[a] + f2) * one_minus));
    (ls, g_logit * splat::gaussians::sigmoid(-logit) / one_minus)
}

/// Whether the filter is computed again after 1-based iteration `n` (`densified`: density control
/// just cloned, split or pruned): after every density step that moved rows, and every
/// `densify.interval` iterations afterwards until the last interval (Mip-Splatting: every 100).
pub fn due(cfg: &crate::TrainConfig, n: usize, densified: bool) -> bool {
    let until = cfg.densify_schedule().1;
    let every = cfg.densify.interval.max(1);
    cfg.filter_3d > 0.0 && (densified || (n > until && n.is_multiple_of(every) && n + every <= cfg.iterations))
}

/// `model` with the filter `f2` (per set and row) baked in: what the saved model holds.
pub fn bake(model: &SceneModel, f2: &[Vec<f64>]) -> SceneModel {
    let mut out = model.clone();
    for (g, f) in out.sets_mut().zip(f2) {
        for ((ls, logit), f2) in g.log_scales.iter_mut().zip(g.opacity_logits.iter_mut()).zip(f) {
            (*ls, *logit) = filtered(*ls, *logit, *f2);
        }
    }
    out
}

#[cfg(test)]
mod tests;
