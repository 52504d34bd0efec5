//! The training loss of one view and its gradient with respect to the rendered channels.
//!
//! * photometric: `(1 - l) L1 + l (1 - SSIM)`, `l = 0.2`, on the composite
//!   `rgb + sky * (1 - alpha)`;
//! * depth: relative L1 `|d - d_prior| / d_prior` where the prior has a value (plain metres would
//!   let the far half of a street, where LiDAR and stereo errors are largest, outweigh the rest);
//! * normal (`L_normal`): masked mean of `1 - cos(n_r, n_ref)`; the rendered normal and the
//!   reference are both in the **same OpenCV camera frame** (the original code compared a
//!   world-frame render with a camera-frame reference);
//! * geometry consistency (`L_geo`, REFERENCE.md section 3): `w = (1 - minmax |Sobel(depth prior)|)
//!   * M`, `nbar = normalize(avgpool3x3(n))`, `L = sum w (1 - n . nbar) / sum w`.
//!
//! The flattening term acts on scales directly and lives in the trainer. Every sum runs in a fixed
//! order so a run is bit-for-bit repeatable.

// Index loops mirror the per-component formulas in the comments above.
#![allow(clippy::needless_range_loop)]

use crate::ssim::ssim_channel_with;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// What a view is compared with, at training resolution. Maps are row-major; `normal` is unit, in
/// OpenCV camera axes, `[0, 0, 0]` where unknown; `depth` is z-depth in metres, 0 where unknown.
/// Stored in f32, the precision they come in (the decoder's f32 image, the priors' f32 maps; the
/// `L_geo` weights are rounded to it): every view of a log is held for the whole run, and a full-size
/// log has a billion pixels (`memory`). The loss reads them into f64.
#[derive(Clone, Debug, Default)]
pub struct Targets {
    pub rgb: Vec<[f32; 3]>,
    pub depth: Option<Vec<f32>>,
    pub normal: Option<Vec<[f32; 3]>>,
    /// Supervision mask M = (ground OR object) AND valid depth.
    pub mask: Option<Vec<bool>>,
    /// `L_geo` pixel weights (zero outside M).
    pub geo_weight: Option<Vec<f32>>,
    /// Pixels left out of training (`protocol`): 1 where the photometric loss counts a pixel, 0
    /// where it does not (the depth, normal and geo targets are emptied there too), and the
    /// SSIM weight of the window centred on each pixel (0 where the window reaches a left-out
    /// pixel, so no left-out target value enters the loss). `None`: every pixel trains.
    pub keep: Option<Vec<f32>>,
    pub ssim_keep: Option<Vec<f32>>,
}

impl Targets {
    /// Whether pixel `i` trains (`keep`).
    pub fn keeps(&self, i: usize) -> bool {
        self.keep.as_ref().is_none_or(|k| k[i] > 0.0)
    }
}

/// Loss weights (the paper: 0.1 for each geometry term).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LossWeights {
    pub ssim: f64,
    pub depth: f64,
    pub flat: f64,
    pub normal: f64,
    pub geo: f64,
}

impl Default for LossWeights {
    fn default() -> Self {
        LossWeights { ssim: 0.2, depth: 0.1, flat: 0.1, normal: 0.1, geo: 0.1 }
    }
}

/// The value of each term (unweighted) and the weighted total.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LossParts {
    pub total: f64,
    pub l1: f64,
    pub ssim: f64,
    pub depth: f64,
    pub normal: f64,
    pub geo: f64,
    pub flat: f64,
}

/// Gradients with respect to the rendered channels and the per-pixel sky colour.
#[derive(Clone, Debug, Default)]
pub struct ChannelGrads {
    pub rgb: Vec<[f64; 3]>,
    pub alpha: Vec<f64>,
    pub depth: Vec<f64>,
    pub normal: Vec<[f64; 3]>,
    pub sky: Vec<[f64; 3]>,
}

/// What was rendered for a view (OpenCV camera-frame normals) plus the sky behind each pixel.
pub struct Rendered<'a> {
    pub width: usize,
    pub height: usize,
    pub rgb: &'a [[f64; 3]],
    pub alpha: &'a [f64],
    pub depth: &'a [f64],
    pub normal: &'a [[f64; 3]],
    pub sky: &'a [[f64; 3]],
}

/// The displayed image: `rgb + sky * (1 - alpha)`.
pub fn composite(r: &Rendered) -> Vec<[f64; 3]> {
    (0..r.rgb.len()).map(|i| std::array::from_fn(|c| r.rgb[i][c] + r.sky[i][c] * (1.0 - r.alpha[i]))).collect()
}

fn normalise(v: [f64; 3]) -> ([f64; 3], f64) {
    let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    if n > 1e-12 {
        (v.map(|x| x / n), n)
    } else {
        ([0.0; 3], 0.0)
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Back through `u = v / |v|`: `g_v = (g_u - (g_u . u) u) / |v|`.
fn through_normalise(g_u: [f64; 3], u: [f64; 3], norm: f64) -> [f64; 3] {
    if norm == 0.0 {
        return [0.0; 3];
    }
    let d = dot(g_u, u);
    std::array::from_fn(|c| (g_u[c] - d * u[c]) / norm)
}

/// The loss of one view and its channel gradients (into `g`, resized here).
pub fn view_loss(r: &Rendered, t: &Targets, w: &LossWeights, g: &mut ChannelGrads) -> LossParts {
    let n = r.width * r.height;
    g.rgb.clear();
    g.rgb.resize(n, [0.0; 3]);
    for v in [&mut g.alpha, &mut g.depth] {
        v.clear();
        v.resize(n, 0.0);
    }
    g.normal.clear();
    g.normal.resize(n, [0.0; 3]);
    let out = composite(r);
    let mut parts = LossParts::default();
    // Photometric.
    let mut g_out = vec![[0.0; 3]; n];
    let inv = 1.0 / (3 * n) as f64;
    let mut l1 = 0.0;
    for i in 0..n {
        if !t.keeps(i) {
            continue;
        }
        for c in 0..3 {
            let d = out[i][c] - t.rgb[i][c] as f64;
            l1 += d.abs();
            g_out[i][c] = (1.0 - w.ssim) * inv * d.signum();
        }
    }
    parts.l1 = l1 * inv;
    let ssim_keep: Option<Vec<f64>> = t.ssim_keep.as_ref().map(|k| k.iter().map(|v| *v as f64).collect());
    // The three channels' SSIM on every thread, combined in channel order (the same sums).
    let per_channel: Vec<(f64, Vec<f64>)> = (0..3)
        .into_par_iter()
        .map(|c| {
            let x: Vec<f64> = out.iter().map(|p| p[c]).collect();
            let y: Vec<f64> = t.rgb.iter().map(|p| p[c] as f64).collect();
            let mut gs = vec![0.0; n];
            (ssim_channel_with(&x, &y, r.width, r.height, ssim_keep.as_deref(), Some(&mut gs), None), gs)
        })
        .collect();
    let mut ssim = 0.0;
    for (c, (value, gs)) in per_channel.iter().enumerate() {
        ssim += value / 3.0;
        for i in 0..n {
            g_out[i][c] -= w.ssim * gs[i] / 3.0;
        }
    }
    parts.ssim = ssim;
    let mut total = (1.0 - w.ssim) * parts.l1 + w.ssim * (1.0 - ssim);
    // Composite -> rgb, alpha, sky.
    g.sky.clear();
    g.sky.resize(n, [0.0; 3]);
    for i in 0..n {
        g.rgb[i] = g_out[i];
        g.alpha[i] = -(0..3).map(|c| g_out[i][c] * r.sky[i][c]).sum::<f64>();
        g.sky[i] = g_out[i].map(|v| v * (1.0 - r.alpha[i]));
    }
    // Depth.
    if let (Some(dp), true) = (&t.depth, w.depth > 0.0) {
        let valid = dp.iter().filter(|d| **d > 0.0).count();
        if valid > 0 {
            let s = 1.0 / valid as f64;
            let mut l = 0.0;
            for i in 0..n {
                if dp[i] > 0.0 {
                    let di = dp[i] as f64;
                    let d = r.depth[i] - di;
                    l += d.abs() / di;
                    g.depth[i] += w.depth * s * d.signum() / di;
                }
            }
            parts.depth = l * s;
            total += w.depth * parts.depth;
        }
    }
    // Normals (rendered, normalised).
    let unit: Vec<([f64; 3], f64)> = r.normal.iter().map(|v| normalise(*v)).collect();
    let mut g_unit = vec![[0.0; 3]; n];
    if let (Some(nref), Some(mask), true) = (&t.normal, &t.mask, w.normal > 0.0) {
        let used: Vec<usize> = (0..n).filter(|&i| mask[i] && unit[i].1 > 0.0 && nref[i] != [0.0; 3]).collect();
        if !used.is_empty() {
            let s = 1.0 / used.len() as f64;
            let mut l = 0.0;
            for &i in &used {
                let nr = nref[i].map(f64::from);
                l += 1.0 - dot(unit[i].0, nr);
                for c in 0..3 {
                    g_unit[i][c] -= w.normal * s * nr[c];
                }
            }
            parts.normal = l * s;
            total += w.normal * parts.normal;
        }
    }
    if let (Some(wg), true) = (&t.geo_weight, w.geo > 0.0) {
        let (l, wsum) = geo_term(&unit, wg, r.width, r.height, w.geo, &mut g_unit);
        if wsum > 0.0 {
            parts.geo = l;
            total += w.geo * l;
        }
    }
    for i in 0..n {
        g.normal[i] = through_normalise(g_unit[i], unit[i].0, unit[i].1);
    }
    parts.total = total;
    parts
}

/// `L_geo` and (scaled by `weight`) its gradient with respect to the unit normals, added into
/// `g_unit`. Returns `(L, sum w)`.
fn geo_term(
    unit: &[([f64; 3], f64)],
    wg: &[f32],
    width: usize,
    height: usize,
    weight: f64,
    g_unit: &mut [[f64; 3]],
) -> (f64, f64) {
    let n = width * height;
    let wsum: f64 = wg.iter().map(|w| *w as f64).sum();
    if wsum <= 0.0 {
        return (0.0, 0.0);
    }
    // m = avgpool3x3(u) (zero padding, divided by 9), nbar = m / |m|.
    let mut m = vec![[0.0; 3]; n];
    for y in 0..height {
        for x in 0..width {
            let mut s = [0.0; 3];
            for dy in -1isize..=1 {
                for dx in -1isize..=1 {
                    let (xx, yy) = (x as isize + dx, y as isize + dy);
                    if xx >= 0 && yy >= 0 && (xx as usize) < width && (yy as usize) < height {
                        let u = unit[yy as usize * width + xx as usize].0;
                        for c in 0..3 {
                            s[c] += u[c] / 9.0;
                        }
                    }
                }
            }
            m[y * width + x] = s;
        }
    }
    let nbar: Vec<([f64; 3], f64)> = m.iter().map(|v| normalise(*v)).collect();
    let mut l = 0.0;
    let mut g_m = vec![[0.0; 3]; n];
    let s = weight / wsum;
    for i in 0..n {
        let wi = wg[i] as f64;
        if wi <= 0.0 || unit[i].1 == 0.0 {
            continue;
        }
        l += wi * (1.0 - dot(unit[i].0, nbar[i].0));
        for c in 0..3 {
            g_unit[i][c] -= s * wi * nbar[i].0[c];
        }
        let g_nbar = unit[i].0.map(|v| -s * wi * v);
        g_m[i] = through_normalise(g_nbar, nbar[i].0, nbar[i].1);
    }
    // Adjoint of the average pool.
    for y in 0..height {
        for x in 0..width {
            let gm = g_m[y * width + x];
            if gm == [0.0; 3] {
                continue;
            }
            for dy in -1isize..=1 {
                for dx in -1isize..=1 {
                    let (xx, yy) = (x as isize + dx, y as isize + dy);
                    if xx >= 0 && yy >= 0 && (xx as usize) < width && (yy as usize) < height {
                        let j = yy as usize * width + xx as usize;
                        for c in 0..3 {
                            g_unit[j][c] += gm[c] / 9.0;
                        }
                    }
                }
            }
        }
    }
    (l / wsum, wsum)
}

/// `L_geo` weights from a depth prior and the supervision mask: `(1 - minmax |Sobel(depth)|) * M`
/// (pixels without depth get no weight), computed in f64 and stored in f32 as the other targets.
pub fn geo_weights(depth: &[f32], mask: &[bool], width: usize, height: usize) -> Vec<f32> {
    let at = |x: isize, y: isize| {
        let (x, y) = (x.clamp(0, width as isize - 1) as usize, y.clamp(0, height as isize - 1) as usize);
        depth[y * width + x] as f64
    };
    let mut mag = vec![0.0; width * height];
    for y in 0..height as isize {
        for x in 0..width as isize {
            let gx = (at(x + 1, y - 1) + 2.0 * at(x + 1, y) + at(x + 1, y + 1))
                - (at(x - 1, y - 1) + 2.0 * at(x - 1, y) + at(x - 1, y + 1));
            let gy = (at(x - 1, y + 1) + 2.0 * at(x, y + 1) + at(x + 1, y + 1))
                - (at(x - 1, y - 1) + 2.0 * at(x, y - 1) + at(x + 1, y - 1));
            mag[y as usize * width + x as usize] = (gx * gx + gy * gy).sqrt();
        }
    }
    let used = |i: usize| mask[i] && depth[i] > 0.0;
    let (lo, hi) =
        (0..mag.len()).filter(|&i| used(i)).fold((f64::MAX, f64::MIN), |(lo, hi), i| (lo.min(mag[i]), hi.max(mag[i])));
    (0..mag.len())
        .map(|i| {
            if used(i) && hi > lo {
                (1.0 - (mag[i] - lo) / (hi - lo)) as f32
            } else if used(i) {
                1.0
            } else {
                0.0
            }
        })
        .collect()
}

#[cfg(test)]
mod tests;
