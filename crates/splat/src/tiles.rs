//! Binning and per-tile iteration, shared by the forward and backward rasterizers and the
//! brute-force references.
//!
//! `alpha_at` is the one definition of a Gaussian's alpha at a pixel centre. Everything else here
//! only decides which (Gaussian, pixel) pairs to *try*: `bin` puts each Gaussian in the tiles its
//! alpha >= 1/255 ellipse's bounding box overlaps, and `spans` lists, row by row, the pixels of
//! a tile inside that ellipse (solved per row, padded by a pixel and a relative
//! 1e-6 so rounding never drops a pixel `alpha_at` would accept). Both are supersets of the
//! pixels `alpha_at` accepts, so the tiled renderer equals the per-pixel reference exactly while
//! touching only the pixels each Gaussian covers.

use crate::project::{Projected, ALPHA_MIN};
use rayon::prelude::*;

pub const TILE: usize = 16;
pub const ALPHA_MAX: f64 = 0.99;
pub const T_MIN: f64 = 1e-4;

/// The inner-loop data of one Gaussian on screen: compact, so a tile's candidates stay in cache.
#[derive(Clone, Copy, Debug)]
pub struct Hot {
    pub mean: [f64; 2],
    /// Inverse 2D covariance `[a, b, c]`.
    pub conic: [f64; 3],
    pub opacity: f64,
    /// Half-widths of the bounding box of the alpha >= 1/255 ellipse.
    pub extent: [f64; 2],
    /// `ln(1 / (255 o))`: below this exponent alpha < 1/255 (rejected without calling `exp`).
    pub power_min: f64,
    /// Row spans of the ellipse `d^T K d <= level` (`level = -2 power_min`, padded by a relative
    /// 1e-6): at row offset `dy` the columns `dx = -s0 dy +- sqrt(s2 + s1 dy^2)` with `s0 = b / a`,
    /// `s1 = (b^2 - a c) / a^2`, `s2 = level / a`.
    pub span: [f64; 3],
}

impl Hot {
    pub fn of(p: &Projected) -> Self {
        let power_min = (ALPHA_MIN / p.opacity).ln();
        let [a, b, c] = p.conic;
        let level = -2.0 * power_min * (1.0 + 1e-6) + 1e-9;
        Hot {
            mean: p.mean,
            conic: p.conic,
            opacity: p.opacity,
            extent: p.extent,
            power_min,
            span: [b / a, (b * b - a * c) / (a * a), level / a],
        }
    }
}

/// Alpha of candidate `h` at pixel centre `q`: `None` if it does not contribute (outside its
/// extent, power > 0, or below 1/255); else `(alpha, exp(power), clamped at 0.99)`. The one definition
/// every renderer and backward pass shares.
#[inline]
pub fn alpha_at(h: &Hot, q: [f64; 2], smooth: bool) -> Option<(f64, f64, bool)> {
    let (dx, dy) = (q[0] - h.mean[0], q[1] - h.mean[1]);
    if !smooth && (dx.abs() > h.extent[0] || dy.abs() > h.extent[1]) {
        return None;
    }
    let [a, b, c] = h.conic;
    let power = -0.5 * (a * dx * dx + c * dy * dy) - b * dx * dy;
    if power > 0.0 || (!smooth && power < h.power_min) {
        return None;
    }
    let e = power.exp();
    let raw = h.opacity * e;
    let clamped = !smooth && raw > ALPHA_MAX;
    let alpha = if clamped { ALPHA_MAX } else { raw };
    if !smooth && alpha < ALPHA_MIN {
        return None;
    }
    Some((alpha, e, clamped))
}

/// A tile's pixels: columns `x0..x0 + w`, rows `y0..y0 + h`. Per-tile buffers use
/// `(y - y0) * TILE + (x - x0)`.
#[derive(Clone, Copy, Debug)]
pub struct Rect {
    pub x0: usize,
    pub y0: usize,
    pub w: usize,
    pub h: usize,
}

impl Rect {
    /// Calls `f(buffer index, image pixel index)` for each pixel, row-major.
    pub fn for_each(&self, width: usize, mut f: impl FnMut(usize, usize)) {
        for y in self.y0..self.y0 + self.h {
            for x in self.x0..self.x0 + self.w {
                f((y - self.y0) * TILE + x - self.x0, y * width + x);
            }
        }
    }
}

/// Per tile (row-major), the indices into the depth-ordered projection of the Gaussians that can
/// touch it; each list is in depth order because the projection is.
#[derive(Clone, Debug, Default)]
pub struct Tiles {
    pub tx: usize,
    pub width: usize,
    pub height: usize,
    pub lists: Vec<Vec<u32>>,
}

impl Tiles {
    pub fn rect(&self, ti: usize) -> Rect {
        let (x0, y0) = ((ti % self.tx) * TILE, (ti / self.tx) * TILE);
        Rect { x0, y0, w: TILE.min(self.width - x0), h: TILE.min(self.height - y0) }
    }
}

/// Sorts projected Gaussians front to back: by depth, ties by Gaussian index (a total order, so
/// every path sorts identically).
pub fn sort_by_depth(proj: &mut [Projected]) {
    proj.par_sort_unstable_by(|a, b| a.depth.total_cmp(&b.depth).then(a.index.cmp(&b.index)));
}

/// Bins depth-ordered Gaussians into tiles. In smooth mode every tile gets every Gaussian.
pub fn bin(proj: &[Projected], width: usize, height: usize, smooth: bool) -> Tiles {
    let mut tiles = Tiles::default();
    bin_into(proj, width, height, smooth, &mut tiles);
    tiles
}

/// [`bin`] into existing tile lists (their memory is reused).
pub fn bin_into(proj: &[Projected], width: usize, height: usize, smooth: bool, tiles: &mut Tiles) {
    let (tx, ty) = (width.div_ceil(TILE), height.div_ceil(TILE));
    tiles.lists.resize_with(tx * ty, Vec::new);
    tiles.lists.iter_mut().for_each(Vec::clear);
    (tiles.tx, tiles.width, tiles.height) = (tx, width, height);
    let lists = &mut tiles.lists;
    for (pi, p) in proj.iter().enumerate() {
        let (x0, x1, y0, y1) = if smooth {
            (0.0, tx as f64 - 1.0, 0.0, ty as f64 - 1.0)
        } else {
            let t = TILE as f64;
            (
                ((p.mean[0] - p.extent[0]) / t).floor().max(0.0),
                ((p.mean[0] + p.extent[0]) / t).floor().min(tx as f64 - 1.0),
                ((p.mean[1] - p.extent[1]) / t).floor().max(0.0),
                ((p.mean[1] + p.extent[1]) / t).floor().min(ty as f64 - 1.0),
            )
        };
        if x1 < x0 || y1 < y0 {
            continue;
        }
        for yy in y0 as usize..=y1 as usize {
            for xx in x0 as usize..=x1 as usize {
                lists[yy * tx + xx].push(pi as u32);
            }
        }
    }
}

/// One row of pixels a Gaussian may reach in a tile: columns `x0..x1` of row `y` (image pixels).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    pub y: usize,
    pub x0: usize,
    pub x1: usize,
}

/// The rows of `r` that `h` may reach, each with its span of columns: a superset of the pixels
/// where `alpha_at` accepts `h` (every pixel in smooth mode). Rows come from the extent box;
/// columns from the ellipse solved per row (`Hot::span`), padded so rounding never drops a pixel
/// `alpha_at` would accept (the floor/ceil below add up to a pixel more).
#[inline]
pub fn spans(h: &Hot, r: Rect, smooth: bool) -> impl Iterator<Item = Span> + '_ {
    let (x_end, y_end) = (r.x0 + r.w, r.y0 + r.h);
    let (y_lo, y_hi) = if smooth {
        (r.y0, y_end)
    } else {
        (first_at_or_after(h.mean[1] - h.extent[1] - 0.5, r.y0), first_after(h.mean[1] + h.extent[1] - 0.5, y_end))
    };
    let [s0, s1, s2] = h.span;
    (y_lo..y_hi.max(y_lo)).filter_map(move |y| {
        if smooth {
            return Some(Span { y, x0: r.x0, x1: x_end });
        }
        let dy = y as f64 + 0.5 - h.mean[1];
        let half2 = s2 + s1 * dy * dy;
        if half2.is_nan() || half2 < 0.0 {
            return None;
        }
        let (mid, half) = (h.mean[0] - s0 * dy - 0.5, half2.sqrt());
        let x0 = first_at_or_after(mid - half, r.x0);
        let x1 = first_after(mid + half, x_end);
        (x1 > x0).then_some(Span { y, x0, x1 })
    })
}

/// `max(floor(v), lo)` as an index (`lo` when `v` is below it or NaN).
#[inline]
fn first_at_or_after(v: f64, lo: usize) -> usize {
    if v >= lo as f64 {
        v as usize
    } else {
        lo
    }
}

/// `min(ceil(v) + 1, end)`: one past the last index at or below `ceil(v)` (0 when `v < 0`).
#[inline]
fn first_after(v: f64, end: usize) -> usize {
    if v.is_nan() || v < 0.0 {
        return 0;
    }
    if v >= end as f64 {
        return end;
    }
    let t = v as usize;
    let ceil = if (t as f64) < v { t + 1 } else { t };
    (ceil + 1).min(end)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::XorShift;

    /// Every pixel `alpha_at` accepts lies in a span, for round, elongated (aspect up to 1e3),
    /// tiny and huge ellipses at every opacity, including tiles the ellipse only grazes.
    #[test]
    fn spans_cover_every_accepted_pixel() {
        let mut r = XorShift(99);
        let (mut accepted, mut visited) = (0usize, 0usize);
        for case in 0..3000 {
            let (l1, l2) = (10f64.powf(r.range(-0.5, 2.5)), 10f64.powf(r.range(-0.5, 1.5)));
            let th = r.range(0.0, std::f64::consts::PI);
            let (c, s) = (th.cos(), th.sin());
            // Sigma2 = R diag(l1, l2) R^T + 0.3 I; K its inverse.
            let (sxx, sxy, syy) = (c * c * l1 + s * s * l2 + 0.3, c * s * (l1 - l2), s * s * l1 + c * c * l2 + 0.3);
            let det = sxx * syy - sxy * sxy;
            let opacity = r.range(0.004, 1.0);
            let level = 2.0 * (255.0 * opacity).ln().max(0.0);
            let p = Projected {
                index: case,
                mean: [r.range(-8.0, 56.0), r.range(-8.0, 40.0)],
                conic: [syy / det, -sxy / det, sxx / det],
                depth: 1.0,
                opacity,
                extent: [(level * sxx).sqrt(), (level * syy).sqrt()],
                color: [0.0; 3],
                normal: [0.0; 3],
            };
            let h = Hot::of(&p);
            let rect = Rect { x0: 16 * (case % 3), y0: 16 * (case % 2), w: 16, h: if case % 5 == 0 { 7 } else { 16 } };
            let mut inside = [false; TILE * TILE];
            for sp in spans(&h, rect, false) {
                for x in sp.x0..sp.x1 {
                    assert!(sp.y >= rect.y0 && sp.y < rect.y0 + rect.h && x >= rect.x0 && x < rect.x0 + rect.w);
                    inside[(sp.y - rect.y0) * TILE + x - rect.x0] = true;
                    visited += 1;
                }
            }
            for y in rect.y0..rect.y0 + rect.h {
                for x in rect.x0..rect.x0 + rect.w {
                    if alpha_at(&h, [x as f64 + 0.5, y as f64 + 0.5], false).is_some() {
                        accepted += 1;
                        assert!(inside[(y - rect.y0) * TILE + x - rect.x0], "case {case}: pixel ({x}, {y}) missed");
                    }
                }
            }
        }
        assert!(accepted > 50_000, "too few accepted pixels ({accepted}) to test anything");
        // The spans are tight: padding adds at most about two pixels per row.
        assert!(visited < accepted * 3 / 2, "spans visit {visited} pixels for {accepted} accepted");
    }
}
