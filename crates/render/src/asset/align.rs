//! Aligning an asset's point set to an actor in the actor's box frame (paper §III-C).
//!
//! Both sets are reduced to a canonical frame: the minimum-area rectangle of their XY convex
//! hull (a side of it is collinear with a hull edge, so every edge is tried: the rotating
//! calipers result), turned so the rectangle's long side lies along x, centred on the rectangle
//! and on the middle of the z range. The asset's yaw onto the actor is then `d` (long side on
//! long side) or one of `d + pi`, `d + pi/2`, `d - pi/2`; for each candidate the per-axis scale
//! maps the asset's extents onto the actor's (or, with `isotropic`, their geometric mean does).
//! Each candidate is scored
//!
//! `score = extent_error + lambda * chamfer`
//!
//! * `extent_error` (m): the mean over the three axes of `|e_actor - s_iso e_asset|` with the
//!   isotropic scale `s_iso`, i.e. how far the candidate's proportions are from the actor's: it
//!   separates the quarter turns from `d` and `d + pi`;
//! * `chamfer` (m): the symmetric Chamfer distance between the scaled candidate and the actor
//!   (mean nearest-neighbour distance both ways, over all points, `kiddo` k-d trees): it tells
//!   `d` from `d + pi` whenever the asset is not symmetric front to back.
//!
//! The lowest score wins; scores within `1e-9` relative of each other count as tied and the
//! earlier candidate (in the order above) is kept, so a symmetric asset is aligned the same way
//! every time.

use super::covariance::{diag, mat_mul, mat_vec, yaw_matrix, Mat3};
use kiddo::{KdTree, SquaredEuclidean};
use serde::{Deserialize, Serialize};
use std::f64::consts::{FRAC_PI_2, PI};

/// A rectangle in the XY plane: centre, yaw of its first axis, extents along its axes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rect {
    pub centre: [f64; 2],
    pub yaw: f64,
    /// `extents[0] >= extents[1]`: the first axis is the long side.
    pub extents: [f64; 2],
}

/// A point set's canonical frame: rectangle in XY plus the z range.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Frame {
    pub centre: [f64; 3],
    pub yaw: f64,
    /// Extents along the frame's axes (length >= width, height).
    pub extents: [f64; 3],
}

/// Andrew's monotone chain (counter-clockwise, collinear points dropped).
pub fn convex_hull(points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut p = points.to_vec();
    p.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        for &q in &p {
            while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0 {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
        if pass == 0 {
            p.reverse();
        }
    }
    hull
}

/// Wraps an angle to `(-pi, pi]`.
pub fn wrap(a: f64) -> f64 {
    let w = a.rem_euclid(2.0 * PI);
    if w > PI {
        w - 2.0 * PI
    } else {
        w
    }
}

/// The minimum-area bounding rectangle of `points` (XY), long side first, yaw in `(-pi/2, pi/2]`.
/// `None` for fewer than one point.
pub fn min_area_rect(points: &[[f64; 2]]) -> Option<Rect> {
    let hull = convex_hull(points);
    let first = *hull.first()?;
    let mut best: Option<(f64, Rect)> = None;
    let n = hull.len();
    for i in 0..n.max(1) {
        let (a, b) = (hull[i], hull[(i + 1) % n]);
        let yaw = if n < 2 { 0.0 } else { (b[1] - a[1]).atan2(b[0] - a[0]) };
        let (s, c) = yaw.sin_cos();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &hull {
            let (dx, dy) = (p[0] - first[0], p[1] - first[1]);
            let uv = [c * dx + s * dy, -s * dx + c * dy];
            for k in 0..2 {
                lo[k] = lo[k].min(uv[k]);
                hi[k] = hi[k].max(uv[k]);
            }
        }
        let ext = [hi[0] - lo[0], hi[1] - lo[1]];
        let area = ext[0] * ext[1];
        let mid = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
        let centre = [first[0] + c * mid[0] - s * mid[1], first[1] + s * mid[0] + c * mid[1]];
        let (yaw, extents) = if ext[0] >= ext[1] { (yaw, ext) } else { (yaw + FRAC_PI_2, [ext[1], ext[0]]) };
        // Long axis direction is defined up to pi: keep yaw in (-pi/2, pi/2].
        let mut yaw = wrap(yaw);
        if yaw <= -FRAC_PI_2 {
            yaw += PI;
        } else if yaw > FRAC_PI_2 {
            yaw -= PI;
        }
        let rect = Rect { centre, yaw, extents };
        if best.is_none_or(|(a, _)| area < a * (1.0 - 1e-12)) {
            best = Some((area, rect));
        }
    }
    best.map(|(_, r)| r)
}

/// The canonical frame of a 3D point set (`None` when empty).
pub fn frame_of(points: &[[f64; 3]]) -> Option<Frame> {
    let xy: Vec<[f64; 2]> = points.iter().map(|p| [p[0], p[1]]).collect();
    let r = min_area_rect(&xy)?;
    let (zlo, zhi) = points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p[2]), b.max(p[2])));
    Some(Frame {
        centre: [r.centre[0], r.centre[1], (zlo + zhi) / 2.0],
        yaw: r.yaw,
        extents: [r.extents[0], r.extents[1], zhi - zlo],
    })
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AlignOptions {
    /// Weight of the Chamfer term (1/m... both terms are metres, so 1.0 weighs them equally).
    pub lambda: f64,
    /// One scale for all axes (the geometric mean of the per-axis ratios).
    pub isotropic: bool,
}

impl Default for AlignOptions {
    fn default() -> Self {
        AlignOptions { lambda: 1.0, isotropic: false }
    }
}

/// One scored candidate.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// The candidate's name: `d`, `d+pi`, `d+pi/2`, `d-pi/2`.
    pub name: String,
    /// The asset's yaw in the actor's frame (rad, wrapped): the rotation applied to the asset.
    pub yaw: f64,
    /// Scale along the actor frame's axes.
    pub scale: [f64; 3],
    pub extent_error_m: f64,
    pub chamfer_m: f64,
    pub score: f64,
}

/// The chosen alignment: `actor_from_asset(x) = linear x + translation`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Alignment {
    pub linear: Mat3,
    pub translation: [f64; 3],
    /// The rotation part of `linear` (yaw about z), for colours.
    pub rotation: Mat3,
    pub chosen: usize,
    pub candidates: Vec<Candidate>,
    pub options: AlignOptions,
    pub asset_frame: Frame,
    pub actor_frame: Frame,
}

impl Alignment {
    pub fn chosen(&self) -> &Candidate {
        &self.candidates[self.chosen]
    }

    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let m = mat_vec(&self.linear, p);
        std::array::from_fn(|a| m[a] + self.translation[a])
    }
}

/// Why an alignment cannot be made.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AlignError {
    #[error("the {0} has no points")]
    Empty(&'static str),
    #[error("the {which} is flat along axis {axis} (extent {extent} m): no scale can be taken from it")]
    Flat { which: &'static str, axis: usize, extent: f64 },
}

/// Symmetric Chamfer distance (mean nearest distance both ways) against a prebuilt tree of `b`.
fn chamfer(a: &[[f64; 3]], b: &[[f64; 3]], tree_b: &KdTree<f64, 3>) -> f64 {
    let mut tree_a: KdTree<f64, 3> = KdTree::with_capacity(a.len().max(1));
    for (i, p) in a.iter().enumerate() {
        tree_a.add(p, i as u64);
    }
    let one_way = |from: &[[f64; 3]], tree: &KdTree<f64, 3>| {
        from.iter().map(|p| tree.nearest_one::<SquaredEuclidean>(p).distance.sqrt()).sum::<f64>() / from.len() as f64
    };
    one_way(a, tree_b) + one_way(b, &tree_a)
}

const CANDIDATES: [(&str, f64); 4] = [("d", 0.0), ("d+pi", PI), ("d+pi/2", FRAC_PI_2), ("d-pi/2", -FRAC_PI_2)];

/// Aligns `asset` points to `actor` points. `actor_frame` overrides the actor's canonical frame
/// (the tracked box: centre 0, yaw 0, extents = its size), else it is measured from the points.
pub fn align(
    asset: &[[f64; 3]],
    actor: &[[f64; 3]],
    actor_frame: Option<Frame>,
    opts: &AlignOptions,
) -> Result<Alignment, AlignError> {
    let fa = frame_of(asset).ok_or(AlignError::Empty("asset"))?;
    let ft = match actor_frame {
        Some(f) => f,
        None => frame_of(actor).ok_or(AlignError::Empty("actor"))?,
    };
    if actor.is_empty() {
        return Err(AlignError::Empty("actor"));
    }
    for (which, f) in [("asset", &fa), ("actor", &ft)] {
        if let Some(axis) = (0..3).find(|&k| f.extents[k] <= 1e-9 * f.extents[0].max(1e-9) || f.extents[k] <= 0.0) {
            return Err(AlignError::Flat { which, axis, extent: f.extents[axis] });
        }
    }
    let mut tree: KdTree<f64, 3> = KdTree::with_capacity(actor.len());
    for (i, p) in actor.iter().enumerate() {
        tree.add(p, i as u64);
    }
    let to_target = yaw_matrix(ft.yaw);
    let mut scored = Vec::with_capacity(4);
    for (name, turn) in CANDIDATES {
        // asset canonical: R(-d_s)(x - c_s); candidate: R(turn) of that.
        let rot_c = mat_mul(&yaw_matrix(turn), &yaw_matrix(-fa.yaw));
        let ext = if turn == 0.0 || turn == PI { fa.extents } else { [fa.extents[1], fa.extents[0], fa.extents[2]] };
        let ratios: [f64; 3] = std::array::from_fn(|k| ft.extents[k] / ext[k]);
        let iso = (ratios[0] * ratios[1] * ratios[2]).cbrt();
        let scale = if opts.isotropic { [iso; 3] } else { ratios };
        let extent_error_m = (0..3).map(|k| (ft.extents[k] - iso * ext[k]).abs()).sum::<f64>() / 3.0;
        let linear = mat_mul(&to_target, &mat_mul(&diag(scale), &rot_c));
        let offset = mat_vec(&linear, fa.centre);
        let translation = std::array::from_fn(|k| ft.centre[k] - offset[k]);
        let moved: Vec<[f64; 3]> = asset
            .iter()
            .map(|p| {
                let m = mat_vec(&linear, *p);
                std::array::from_fn(|k| m[k] + translation[k])
            })
            .collect();
        let chamfer_m = chamfer(&moved, actor, &tree);
        let yaw = wrap(ft.yaw + turn - fa.yaw);
        let cand = Candidate {
            name: name.to_string(),
            yaw,
            scale,
            extent_error_m,
            chamfer_m,
            score: extent_error_m + opts.lambda * chamfer_m,
        };
        scored.push((cand, linear, translation, mat_mul(&to_target, &rot_c)));
    }
    let mut chosen = 0;
    for (i, c) in scored.iter().enumerate().skip(1) {
        let best = scored[chosen].0.score;
        if c.0.score < best - 1e-9 * best.abs().max(1e-12) {
            chosen = i;
        }
    }
    let (_, linear, translation, rotation) = scored[chosen].clone();
    Ok(Alignment {
        linear,
        translation,
        rotation,
        chosen,
        candidates: scored.into_iter().map(|s| s.0).collect(),
        options: *opts,
        asset_frame: fa,
        actor_frame: ft,
    })
}

#[cfg(test)]
mod tests;
