//! The f32 tiled forward rasterizer: one 16x16 tile, Gaussians front to back, each over the
//! 4x2-pixel chunks its alpha >= 1/255 ellipse reaches (`tile`), all eight lanes at once.
//!
//! Same compositing as `raster::tile_forward` and the per-pixel reference: per pixel centre,
//! `alpha = min(0.99, o exp(power))`, rejected outside the extent box, for `power > 0`, below the
//! ellipse (`power < ln(1 / (255 o))`) or `alpha < 1/255`; a pixel stops (is done) before a
//! Gaussian that would drop its transmittance below 1e-4; a tile stops when all its pixels are
//! done. Branches are selects, so each chunk is one vectorised loop (`lanes`). Per pixel it
//! keeps the final transmittance and how many of the tile's Gaussians it walked, as the f64
//! `Context` does, for the backward pass. Tile state lives in fixed-size chunk arrays, so the
//! lane loops carry no bounds checks; a done pixel keeps its transmittance negated (no flag).

use super::lanes::{dispatch, exp, L};
use super::project::Hot32;
use super::tile::{
    accepts, any_lane, pair_quads, pair_range, power_at, prefetch, Lanes, AHEAD, ALPHA_MAX, CHUNKS, LANE_DX, LANE_DY,
    NPX, QUADS, T_MIN,
};
use crate::tiles::Rect;

/// Per-tile output channels before the features: rgb (3), depth, normal (3), final T; each
/// `NPX` values in chunk-major order (`tile::slot`).
pub const BASE_CH: usize = 8;
pub const CH_T: usize = 7;

/// One tile's inputs.
pub struct TileIn<'a> {
    pub rect: Rect,
    /// Model indices (into `hot` and the features), front to back.
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
fn tile_forward_kernel(tin: &TileIn, out: &mut [f32], last_out: &mut [u32]) {
    let (r, k) = (tin.rect, tin.k);
    let mut t = [[1.0f32; L]; CHUNKS];
    let mut last = [[0u32; L]; CHUNKS];
    let mut sums = [[[0.0f32; L]; CHUNKS]; CH_T];
    let feat = &mut out[BASE_CH * NPX..];
    feat.fill(0.0);
    // Pixels outside a partial tile start done.
    for (ci, chunk) in t.iter_mut().enumerate() {
        for (l, v) in chunk.iter_mut().enumerate() {
            let (x, y) = ((ci % QUADS) * 4 + l % 4, (ci / QUADS) * 2 + l / 4);
            if x >= r.w || y >= r.h {
                *v = -1.0;
            }
        }
    }
    let list = tin.list;
    for &i in list.iter().take(AHEAD) {
        prefetch(tin.hot, i as usize);
    }
    let mut any_sat = false;
    for (slot, &pi) in list.iter().enumerate() {
        if let Some(&next) = list.get(slot + AHEAD) {
            prefetch(tin.hot, next as usize);
        }
        let h = &tin.hot[pi as usize];
        let span = h.span();
        let vc = h.color.map(|c| c.max(0.0));
        let n = match &tin.nrot {
            Some(m) => std::array::from_fn(|a| m[a][0] * h.normal[0] + m[a][1] * h.normal[1] + m[a][2] * h.normal[2]),
            None => h.normal,
        };
        let vals = [vc[0], vc[1], vc[2], h.depth, n[0], n[1], n[2]];
        let fv = &tin.feats[pi as usize * k..(pi as usize + 1) * k];
        let slot1 = slot as u32 + 1;
        let [ca, cb, cc] = h.conic;
        let (o, pmin, ex, ey) = (h.opacity, h.power_min, h.extent[0], h.extent[1]);
        let qx_base = r.x0 as f32 + 0.5 - h.mean[0];
        let qy_base = r.y0 as f32 + 0.5 - h.mean[1];
        let (j_lo, j_hi) = pair_range(h, &r);
        for j in j_lo..j_hi {
            let (q_lo, q_hi) = pair_quads(h, &span, &r, j);
            let dy0 = qy_base + (2 * j) as f32;
            for q in q_lo..q_hi {
                let ci = j * QUADS + q;
                let dx0 = qx_base + (4 * q) as f32;
                let (tt, ls) = (t[ci], last[ci]);
                if !any_lane(h, dx0, dy0, &tt.map(|v| v > 0.0)) {
                    continue;
                }
                let mut w: Lanes = [0.0; L];
                let mut nt: Lanes = [0.0; L];
                let mut nl = [0u32; L];
                let mut sat = 0u32;
                for l in 0..L {
                    let (dx, dy) = (dx0 + LANE_DX[l], dy0 + LANE_DY[l]);
                    let power = power_at(ca, cb, cc, dx, dy);
                    let raw = o * exp(power);
                    let alpha = if raw > ALPHA_MAX { ALPHA_MAX } else { raw };
                    let ok = (tt[l] > 0.0) & accepts(dx, dy, ex, ey, power, pmin, alpha);
                    let next = tt[l] * (1.0 - alpha);
                    let s = ok & (next < T_MIN);
                    let acc = ok & !s;
                    w[l] = if acc { alpha * tt[l] } else { 0.0 };
                    nt[l] = if acc {
                        next
                    } else if s {
                        -tt[l]
                    } else {
                        tt[l]
                    };
                    nl[l] = if acc { slot1 } else { ls[l] };
                    sat |= s as u32;
                }
                t[ci] = nt;
                last[ci] = nl;
                any_sat |= sat != 0;
                for (sum, v) in sums.iter_mut().zip(vals) {
                    let dst = &mut sum[ci];
                    for l in 0..L {
                        dst[l] += w[l] * v;
                    }
                }
                for (ch, &f) in fv.iter().enumerate() {
                    let (f, row) = (f as f32, &mut feat[ch * NPX + ci * L..ch * NPX + ci * L + L]);
                    for l in 0..L {
                        row[l] += w[l] * f;
                    }
                }
            }
        }
        // The tile stops once every pixel is done (checked only after some pixel stopped).
        if any_sat {
            any_sat = false;
            if t.as_flattened().iter().all(|v| *v < 0.0) {
                break;
            }
        }
    }
    for (ch, sum) in sums.iter().enumerate() {
        out[ch * NPX..(ch + 1) * NPX].copy_from_slice(sum.as_flattened());
    }
    for (o, v) in out[CH_T * NPX..(CH_T + 1) * NPX].iter_mut().zip(t.as_flattened()) {
        *o = v.abs();
    }
    last_out.copy_from_slice(last.as_flattened());
}
