//! The f32 tiled forward rasterizer: one 16x16 tile, Gaussians front to back, each over the
//! 8-pixel half rows its alpha >= 1/255 ellipse reaches, all eight lanes at once.
//!
//! Same compositing as `raster::tile_forward` and the per-pixel reference: per pixel centre,
//! `alpha = min(0.99, o exp(power))`, rejected outside the extent box, for `power > 0`, below the
//! ellipse (`power < ln(1 / (255 o))`) or `alpha < 1/255`; a pixel stops (is done) before a
//! Gaussian that would drop its transmittance below 1e-4; a tile stops when all its pixels are
//! done. Branches are selects, so each half row is one vectorised loop (`lanes`). Per pixel it
//! keeps the final transmittance and how many of the tile's Gaussians it walked, as the f64
//! `Context` does, for the backward pass.

use super::lanes::{dispatch, exp, L};
use super::project::{Hot32, ALPHA_MIN};
use crate::tiles::{Rect, TILE};

pub const NPX: usize = TILE * TILE;
pub const T_MIN: f32 = 1e-4;
pub const ALPHA_MAX: f32 = 0.99;
/// Per-tile output channels before the features: rgb (3), depth, normal (3), final T.
pub const BASE_CH: usize = 8;
pub const CH_T: usize = 7;

/// Which half rows (chunks of `L` lanes) of tile row `y` (tile-local) Gaussian `h` may reach,
/// and `dy` there; `None` when the row is outside its extent or ellipse. A superset of the
/// pixels the per-lane test accepts (padded by a pixel and a relative 1e-4 in the level).
#[inline(always)]
pub fn row_chunks(h: &Hot32, r: &Rect, y: usize) -> Option<(f32, [bool; 2])> {
    let dy = (r.y0 + y) as f32 + 0.5 - h.mean[1];
    if dy.abs() > h.extent[1] {
        return None;
    }
    let [s0, s1, s2] = h.span;
    let half2 = s2 + s1 * dy * dy;
    if half2.is_nan() || half2 < 0.0 {
        return None;
    }
    let half = half2.sqrt();
    let mid = h.mean[0] - s0 * dy - 0.5 - r.x0 as f32;
    let (lo, hi) = (mid - half - 1.5, mid + half + 1.5);
    let c0 = lo < L as f32 && hi >= 0.0;
    let c1 = r.w > L && lo < (2 * L) as f32 && hi >= L as f32;
    Some((dy, [c0, c1]))
}

/// The exponent at offset `(dx, dy)` from the mean, `cdy = -0.5 c dy^2` precomputed per row: the
/// one expression the forward and backward kernels share, so both accept the same pixels.
#[inline(always)]
pub fn power_at(ca: f32, cb: f32, dx: f32, dy: f32, cdy: f32) -> f32 {
    -0.5 * ca * dx * dx + cdy - cb * dx * dy
}

/// Whether a pixel accepts a Gaussian: the reference's rejections (`tiles::alpha_at`: outside
/// the extent box, `power > 0`, below the ellipse, alpha under 1/255), written as the same
/// comparisons so NaN behaves alike. Shared by the forward and backward kernels.
#[inline(always)]
#[allow(clippy::neg_cmp_op_on_partial_ord)]
pub fn accepts(dx: f32, ex: f32, power: f32, pmin: f32, alpha: f32) -> bool {
    !(dx.abs() > ex) & !(power > 0.0) & !(power < pmin) & !(alpha < ALPHA_MIN)
}

/// The tile-local rows Gaussian `h` may reach: from its extent box, padded by a row.
#[inline(always)]
pub fn row_range(h: &Hot32, r: &Rect) -> (usize, usize) {
    let lo = h.mean[1] - h.extent[1] - 1.0 - r.y0 as f32;
    let hi = h.mean[1] + h.extent[1] + 1.0 - r.y0 as f32;
    let y_lo = if lo > 0.0 { (lo as usize).min(r.h) } else { 0 };
    let y_hi = if hi > 0.0 { (hi as usize + 1).min(r.h) } else { 0 };
    (y_lo, y_hi.max(y_lo))
}

/// One tile's inputs.
pub struct TileIn<'a> {
    pub rect: Rect,
    /// Indices into `hot`, front to back.
    pub list: &'a [u32],
    pub hot: &'a [Hot32],
    /// Feature values by Gaussian index, `k` per Gaussian.
    pub feats: &'a [f64],
    pub k: usize,
    /// Camera-to-output rotation of the normals (`n_out = nrot n_cam`), or `None` for camera frame.
    pub nrot: Option<[[f32; 3]; 3]>,
}

dispatch! {
    /// Renders one tile into `out` (`(BASE_CH + k) * NPX` values, channel-major, written whole)
    /// and `last` (`NPX`).
    pub fn tile_forward(tin: &TileIn, out: &mut [f32], last: &mut [u32]) => tile_forward_kernel
}

#[inline(always)]
fn tile_forward_kernel(tin: &TileIn, out: &mut [f32], last: &mut [u32]) {
    let (r, k) = (tin.rect, tin.k);
    out.fill(0.0);
    last.fill(0);
    let (head, feat) = out.split_at_mut(BASE_CH * NPX);
    let (sums, t) = head.split_at_mut(CH_T * NPX);
    t.fill(1.0);
    let mut done = [0u32; NPX];
    let colok: [u32; 2 * L] = std::array::from_fn(|x| (x < r.w) as u32);
    let (live, mut n_done) = (r.w * r.h, 0usize);
    let mut w8 = [0.0f32; L];
    for (slot, &pi) in tin.list.iter().enumerate() {
        let h = &tin.hot[pi as usize];
        let vc = h.color.map(|c| c.max(0.0));
        let n = match &tin.nrot {
            Some(m) => std::array::from_fn(|a| m[a][0] * h.normal[0] + m[a][1] * h.normal[1] + m[a][2] * h.normal[2]),
            None => h.normal,
        };
        let fv = &tin.feats[h.index as usize * k..(h.index as usize + 1) * k];
        let slot1 = slot as u32 + 1;
        let [ca, cb, cc] = h.conic;
        let (o, z, pmin, ex) = (h.opacity, h.depth, h.power_min, h.extent[0]);
        let (y_lo, y_hi) = row_range(h, &r);
        for y in y_lo..y_hi {
            let Some((dy, chunks)) = row_chunks(h, &r, y) else { continue };
            let cdy = -0.5 * cc * dy * dy;
            for (c, _) in chunks.iter().enumerate().filter(|(_, on)| **on) {
                let base = y * TILE + c * L;
                let qx0 = (r.x0 + c * L) as f32 + 0.5 - h.mean[0];
                let mut sat_n = 0u32;
                for l in 0..L {
                    let p = base + l;
                    let dx = qx0 + l as f32;
                    let power = power_at(ca, cb, dx, dy, cdy);
                    let raw = o * exp(power);
                    let alpha = if raw > ALPHA_MAX { ALPHA_MAX } else { raw };
                    let ok = (colok[c * L + l] != 0) & (done[p] == 0) & accepts(dx, ex, power, pmin, alpha);
                    let tt = t[p];
                    let next = tt * (1.0 - alpha);
                    let sat = ok & (next < T_MIN);
                    let acc = ok & !sat;
                    let w = if acc { alpha * tt } else { 0.0 };
                    w8[l] = w;
                    sums[p] += w * vc[0];
                    sums[NPX + p] += w * vc[1];
                    sums[2 * NPX + p] += w * vc[2];
                    sums[3 * NPX + p] += w * z;
                    sums[4 * NPX + p] += w * n[0];
                    sums[5 * NPX + p] += w * n[1];
                    sums[6 * NPX + p] += w * n[2];
                    t[p] = if acc { next } else { tt };
                    last[p] = if acc { slot1 } else { last[p] };
                    done[p] |= sat as u32;
                    sat_n += sat as u32;
                }
                n_done += sat_n as usize;
                for (ch, &f) in fv.iter().enumerate() {
                    let (f, row) = (f as f32, &mut feat[ch * NPX + base..ch * NPX + base + L]);
                    for l in 0..L {
                        row[l] += w8[l] * f;
                    }
                }
            }
        }
        if n_done == live {
            break;
        }
    }
}
