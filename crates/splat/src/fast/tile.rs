//! What the f32 tile kernels share: the tile's chunk layout, which chunks a Gaussian may reach,
//! the one per-pixel acceptance test, and prefetching.
//!
//! A 16x16 tile is 32 chunks of 8 lanes, each chunk 4 columns by 2 rows (lane `l` is column
//! `l % 4`, row `l / 4`): small Gaussians, the common case, cover few columns, so square-ish
//! chunks waste fewer lanes than half rows would. Per-tile buffers are chunk-major
//! (`chunk * 8 + lane`, see [`slot`]). For a Gaussian, each row pair's columns come from its
//! alpha >= 1/255 ellipse solved per row (`Hot32::span`, padded by a pixel and a relative 1e-4 in
//! the level), so the chunks visited are a superset of the pixels [`accepts`] takes
//! (`chunks_cover_every_accepted_pixel`).

use super::lanes::L;
use super::project::{Hot32, ALPHA_MIN};
use crate::tiles::{Rect, TILE};

pub const NPX: usize = TILE * TILE;
pub const CHUNKS: usize = NPX / L;
/// Chunk columns per tile row pair.
pub const QUADS: usize = TILE / 4;
pub const T_MIN: f32 = 1e-4;
pub const ALPHA_MAX: f32 = 0.99;

pub type Lanes = [f32; L];

/// Lane offsets inside a chunk: column and row.
pub const LANE_DX: Lanes = [0.0, 1.0, 2.0, 3.0, 0.0, 1.0, 2.0, 3.0];
pub const LANE_DY: Lanes = [0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0];

/// Chunk-major buffer index of tile-local pixel `(x, y)`.
#[inline(always)]
pub fn slot(x: usize, y: usize) -> usize {
    ((y / 2) * QUADS + x / 4) * L + (y % 2) * 4 + x % 4
}

/// The exponent at offset `(dx, dy)` from the mean: the one expression the forward and backward
/// kernels share, so both accept the same pixels.
#[inline(always)]
pub fn power_at(ca: f32, cb: f32, cc: f32, dx: f32, dy: f32) -> f32 {
    -0.5 * (ca * dx * dx + cc * dy * dy) - cb * dx * dy
}

/// Whether a pixel accepts a Gaussian: the reference's rejections (`tiles::alpha_at`: outside
/// the extent box, `power > 0`, below the ellipse, alpha under 1/255), written as the same
/// comparisons so NaN behaves alike.
#[inline(always)]
#[allow(clippy::neg_cmp_op_on_partial_ord, clippy::too_many_arguments)]
pub fn accepts(dx: f32, dy: f32, ex: f32, ey: f32, power: f32, pmin: f32, alpha: f32) -> bool {
    !(dx.abs() > ex) & !(dy.abs() > ey) & !(power > 0.0) & !(power < pmin) & !(alpha < ALPHA_MIN)
}

/// Whether any lane of a chunk may accept the Gaussian: [`accepts`] without the alpha test (a
/// superset), and `live` (the lane still takes part). Lets a kernel skip chunks of the ellipse's
/// box that no pixel of it reaches before computing `exp`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn any_lane(h: &Hot32, dx0: f32, dy0: f32, live: &[bool; L]) -> bool {
    let [ca, cb, cc] = h.conic;
    let mut any = false;
    for l in 0..L {
        let (dx, dy) = (dx0 + LANE_DX[l], dy0 + LANE_DY[l]);
        let power = power_at(ca, cb, cc, dx, dy);
        any |= live[l] & accepts(dx, dy, h.extent[0], h.extent[1], power, h.power_min, ALPHA_MIN);
    }
    any
}

/// The tile-local column interval `[lo, hi]` Gaussian `h` may reach in tile row `y`, or `None`.
#[inline(always)]
fn row_cols(h: &Hot32, span: &[f32; 3], r: &Rect, y: usize) -> Option<(f32, f32)> {
    let dy = (r.y0 + y) as f32 + 0.5 - h.mean[1];
    if dy.abs() > h.extent[1] {
        return None;
    }
    let [s0, s1, s2] = *span;
    let half2 = s2 + s1 * dy * dy;
    if half2.is_nan() || half2 < 0.0 {
        return None;
    }
    let half = half2.sqrt();
    let mid = h.mean[0] - s0 * dy - 0.5 - r.x0 as f32;
    Some((mid - half - 1.5, mid + half + 1.5))
}

/// The row pairs (tile-local pair indices `lo..hi`) Gaussian `h` may reach: its extent box,
/// padded by a row.
#[inline(always)]
pub fn pair_range(h: &Hot32, r: &Rect) -> (usize, usize) {
    let lo = h.mean[1] - h.extent[1] - 1.0 - r.y0 as f32;
    let hi = h.mean[1] + h.extent[1] + 1.0 - r.y0 as f32;
    let y_lo = if lo > 0.0 { (lo as usize).min(r.h) } else { 0 };
    let y_hi = if hi > 0.0 { (hi as usize + 1).min(r.h) } else { 0 };
    (y_lo / 2, y_hi.max(y_lo).div_ceil(2))
}

/// The chunk columns `lo..hi` of row pair `j` Gaussian `h` (with `span = h.span()`) may reach
/// (`lo == hi`: none).
#[inline(always)]
pub fn pair_quads(h: &Hot32, span: &[f32; 3], r: &Rect, j: usize) -> (usize, usize) {
    let a = row_cols(h, span, r, 2 * j);
    let b = if 2 * j + 1 < r.h { row_cols(h, span, r, 2 * j + 1) } else { None };
    let (lo, hi) = match (a, b) {
        (Some(a), Some(b)) => (a.0.min(b.0), a.1.max(b.1)),
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => return (0, 0),
    };
    if hi < 0.0 || lo >= r.w as f32 {
        return (0, 0);
    }
    let q_lo = if lo > 0.0 { lo as usize / 4 } else { 0 };
    let q_hi = ((hi as usize).min(r.w - 1) / 4 + 1).min(QUADS);
    (q_lo.min(q_hi), q_hi)
}

/// Starts loading Gaussian `i`'s inner-loop data (one cache line): tile lists jump through a
/// large array, and without this every list entry waits on memory.
#[inline(always)]
pub fn prefetch(hot: &[Hot32], i: usize) {
    #[cfg(target_arch = "x86_64")]
    if let Some(h) = hot.get(i) {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        // SAFETY: prefetching is only a hint, and the address is that of `hot[i]`.
        unsafe { _mm_prefetch(h as *const Hot32 as *const i8, _MM_HINT_T0) }
    }
}

/// How many list entries ahead to prefetch.
pub const AHEAD: usize = 4;

#[cfg(test)]
mod tests {
    use super::super::lanes::exp;
    use super::*;
    use crate::random::XorShift;

    /// Every pixel the lane test accepts lies in a chunk `pair_range`/`pair_quads` visit, for
    /// round, elongated (aspect up to 1e3), tiny and huge ellipses at every opacity, in full and
    /// partial tiles; and the chunks visited are not many more than needed.
    #[test]
    fn chunks_cover_every_accepted_pixel() {
        let mut r = XorShift(7);
        let (mut accepted, mut visited, mut needed) = (0usize, 0usize, 0usize);
        for case in 0..3000 {
            let (l1, l2) = (10f64.powf(r.range(-1.0, 2.5)), 10f64.powf(r.range(-1.0, 1.5)));
            let th = r.range(0.0, std::f64::consts::PI);
            let (c, s) = (th.cos(), th.sin());
            let (sxx, sxy, syy) = (c * c * l1 + s * s * l2 + 0.3, c * s * (l1 - l2), s * s * l1 + c * c * l2 + 0.3);
            let det = sxx * syy - sxy * sxy;
            let o = r.range(0.004, 1.0);
            let level = 2.0 * (255.0 * o).ln().max(0.0);
            let (ka, kb, kc) = ((syy / det) as f32, (-sxy / det) as f32, (sxx / det) as f32);
            let power_min = (ALPHA_MIN / o as f32).ln();
            let h = Hot32 {
                mean: [r.range(-8.0, 56.0) as f32, r.range(-8.0, 40.0) as f32],
                conic: [ka, kb, kc],
                opacity: o as f32,
                extent: [(level * sxx).sqrt() as f32, (level * syy).sqrt() as f32],
                power_min,
                ..Default::default()
            };
            let span = h.span();
            let rect = Rect {
                x0: 16 * (case % 3),
                y0: 16 * (case % 2),
                w: if case % 7 == 0 { 11 } else { 16 },
                h: if case % 5 == 0 { 7 } else { 16 },
            };
            let mut inside = [false; NPX];
            let (j_lo, j_hi) = pair_range(&h, &rect);
            for j in j_lo..j_hi {
                let (q_lo, q_hi) = pair_quads(&h, &span, &rect, j);
                for q in q_lo..q_hi {
                    visited += 1;
                    (0..L).for_each(|l| inside[(j * QUADS + q) * L + l] = true);
                }
            }
            let mut chunks_needed = std::collections::BTreeSet::new();
            for y in 0..rect.h {
                for x in 0..rect.w {
                    let dx = (rect.x0 + x) as f32 + 0.5 - h.mean[0];
                    let dy = (rect.y0 + y) as f32 + 0.5 - h.mean[1];
                    let power = power_at(ka, kb, kc, dx, dy);
                    let alpha = (h.opacity * exp(power)).min(ALPHA_MAX);
                    if accepts(dx, dy, h.extent[0], h.extent[1], power, h.power_min, alpha) {
                        accepted += 1;
                        chunks_needed.insert(slot(x, y) / L);
                        assert!(inside[slot(x, y)], "case {case}: pixel ({x}, {y}) of {rect:?} missed");
                    }
                }
            }
            needed += chunks_needed.len();
        }
        assert!(accepted > 30_000, "too few accepted pixels ({accepted})");
        assert!(visited < needed * 3 / 2, "{visited} chunks visited for {needed} needed");
    }

    #[test]
    fn slots_are_a_permutation() {
        let mut seen = [false; NPX];
        for y in 0..TILE {
            for x in 0..TILE {
                assert!(!std::mem::replace(&mut seen[slot(x, y)], true));
            }
        }
    }
}
