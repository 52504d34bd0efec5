//! The f32 tiled backward rasterizer: one tile, its Gaussians back to front over the same half
//! rows as the forward pass, eight pixels at once; then the merge of the tiles' sums.
//!
//! Per pixel the arithmetic of `backward::step_back`: the transmittance before a Gaussian is
//! recovered as `T_i = T_{i+1} / (1 - alpha_i)` from the stored final one, a pixel takes part for
//! the Gaussians it walked in the forward pass (`last`), `d out / d alpha_i = T_i v_i - S_i /
//! (1 - alpha_i)` with `S_i` what lies behind (background included), clamped alphas and colours
//! clamped at 0 pass no gradient. Each Gaussian's screen-space sums are kept per lane and added
//! across lanes in a fixed order at the end of the Gaussian (deterministic). Lanes that do not
//! take part are made neutral by selects (alpha 0, gradient 0), never by branches.

use super::forward::{accepts, power_at, row_chunks, row_range, ALPHA_MAX, CH_T, NPX};
use super::lanes::{dispatch, exp, L};
use super::project::Hot32;
use crate::backward::Upstream;
use crate::tiles::{Rect, TILE};

/// Screen-space sums per Gaussian and tile, before the features: mean (2), conic (3), opacity,
/// colour (3), depth, normal (3).
pub const G_CH: usize = 13;

/// One tile's inputs to the backward pass.
pub struct TileBack<'a> {
    pub rect: Rect,
    pub list: &'a [u32],
    pub hot: &'a [Hot32],
    pub feats: &'a [f64],
    pub k: usize,
    /// This tile's forward output (`forward::tile_forward`'s `out`) and `last`.
    pub fwd: &'a [f32],
    pub last: &'a [u32],
    pub up: &'a Upstream<'a>,
    pub width: usize,
    /// `camera_from_world`'s rotation when the normals were output in the world frame.
    pub nrot: Option<[[f32; 3]; 3]>,
    pub background: [f32; 3],
}

/// Per-pixel state of a tile while it is walked back to front, channel-major (`NPX` each).
const S_T: usize = 0;
const S_UA: usize = 1; // d L / d alpha_out x T_final
const S_URGB: usize = 2; // 3
const S_UD: usize = 5;
const S_UN: usize = 6; // 3
const S_BRGB: usize = 9; // 3
const S_BD: usize = 12;
const S_BN: usize = 13; // 3
const S_LAST: usize = 16;
const S_N: usize = 17;

dispatch! {
    /// Walks one tile back to front; `out` gets `(G_CH + k)` sums per slot for the first
    /// `walked` slots of the tile's list (resized here; returns `walked`). `fstate` is scratch
    /// for the features (`2 k NPX`).
    pub fn tile_backward(tb: &TileBack, out: &mut Vec<f32>, fstate: &mut Vec<f32>) -> usize => tile_backward_kernel
}

#[inline(always)]
fn tile_backward_kernel(tb: &TileBack, out: &mut Vec<f32>, fstate: &mut Vec<f32>) -> usize {
    let (r, k) = (tb.rect, tb.k);
    let mut st = [0.0f32; S_N * NPX];
    let up = tb.up;
    fstate.clear();
    fstate.resize(2 * k * NPX, 0.0);
    let (gf, sf) = fstate.split_at_mut(k * NPX);
    let mut walked = 0u32;
    for y in 0..r.h {
        for x in 0..r.w {
            let (p, pix) = (y * TILE + x, (r.y0 + y) * tb.width + r.x0 + x);
            let t = tb.fwd[CH_T * NPX + p];
            let lst = tb.last[p];
            walked = walked.max(lst);
            st[S_T * NPX + p] = t;
            st[S_LAST * NPX + p] = lst as f32;
            st[S_UA * NPX + p] = (up.alpha[pix] * t as f64) as f32;
            st[S_UD * NPX + p] = up.depth[pix] as f32;
            let n = up.normal[pix];
            let nc: [f64; 3] = match &tb.nrot {
                Some(m) => {
                    std::array::from_fn(|a| m[a][0] as f64 * n[0] + m[a][1] as f64 * n[1] + m[a][2] as f64 * n[2])
                }
                None => n,
            };
            for c in 0..3 {
                st[(S_URGB + c) * NPX + p] = up.rgb[pix][c] as f32;
                st[(S_UN + c) * NPX + p] = nc[c] as f32;
                st[(S_BRGB + c) * NPX + p] = tb.background[c] * t;
            }
            for c in 0..k {
                gf[c * NPX + p] = up.features[pix * k + c] as f32;
            }
        }
    }
    let walked = walked as usize;
    let stride = G_CH + k;
    out.clear();
    out.resize(walked * stride, 0.0);
    let mut fa = vec![[0.0f32; L]; k];
    let (mut w8, mut i8, mut ti8) = ([0.0f32; L], [0.0f32; L], [0.0f32; L]);
    for slot in (0..walked).rev() {
        let h = &tb.hot[tb.list[slot] as usize];
        let vc = h.color.map(|c| c.max(0.0));
        let (n, z) = (h.normal, h.depth);
        let fv = &tb.feats[h.index as usize * k..(h.index as usize + 1) * k];
        let slot_f = slot as f32;
        let [ca, cb, cc] = h.conic;
        let (o, pmin, ex) = (h.opacity, h.power_min, h.extent[0]);
        // Lane sums: mean (2), conic (3), opacity, colour (3), depth, normal (3).
        let mut acc = [[0.0f32; L]; G_CH];
        fa.iter_mut().for_each(|v| *v = [0.0; L]);
        let (y_lo, y_hi) = row_range(h, &r);
        for y in y_lo..y_hi {
            let Some((dy, chunks)) = row_chunks(h, &r, y) else { continue };
            let cdy = -0.5 * cc * dy * dy;
            for (c, _) in chunks.iter().enumerate().filter(|(_, on)| **on) {
                let base = y * TILE + c * L;
                let qx0 = (r.x0 + c * L) as f32 + 0.5 - h.mean[0];
                let mut da8 = [0.0f32; L];
                let mut e8 = [0.0f32; L];
                let mut a8 = [0.0f32; L];
                let mut m8 = [false; L];
                for l in 0..L {
                    let p = base + l;
                    let col_ok = c * L + l < r.w;
                    let dx = qx0 + l as f32;
                    let power = power_at(ca, cb, dx, dy, cdy);
                    let e = exp(power);
                    let raw = o * e;
                    let clamped = raw > ALPHA_MAX;
                    let alpha = if clamped { ALPHA_MAX } else { raw };
                    let ok = col_ok & (slot_f < st[S_LAST * NPX + p]) & accepts(dx, ex, power, pmin, alpha);
                    let a = if ok { alpha } else { 0.0 };
                    let inv = 1.0 / (1.0 - a);
                    let ti = st[S_T * NPX + p] * inv;
                    let w = a * ti;
                    let (ur, ug, ub) = (st[S_URGB * NPX + p], st[(S_URGB + 1) * NPX + p], st[(S_URGB + 2) * NPX + p]);
                    let (un0, un1, un2) = (st[S_UN * NPX + p], st[(S_UN + 1) * NPX + p], st[(S_UN + 2) * NPX + p]);
                    let ud = st[S_UD * NPX + p];
                    acc[6][l] += ur * w;
                    acc[7][l] += ug * w;
                    acc[8][l] += ub * w;
                    acc[9][l] += ud * w;
                    acc[10][l] += un0 * w;
                    acc[11][l] += un1 * w;
                    acc[12][l] += un2 * w;
                    let b = |s: usize| st[s * NPX + p];
                    let d_alpha = st[S_UA * NPX + p] * inv
                        + ud * (ti * z - b(S_BD) * inv)
                        + ur * (ti * vc[0] - b(S_BRGB) * inv)
                        + ug * (ti * vc[1] - b(S_BRGB + 1) * inv)
                        + ub * (ti * vc[2] - b(S_BRGB + 2) * inv)
                        + un0 * (ti * n[0] - b(S_BN) * inv)
                        + un1 * (ti * n[1] - b(S_BN + 1) * inv)
                        + un2 * (ti * n[2] - b(S_BN + 2) * inv);
                    st[S_BRGB * NPX + p] += w * vc[0];
                    st[(S_BRGB + 1) * NPX + p] += w * vc[1];
                    st[(S_BRGB + 2) * NPX + p] += w * vc[2];
                    st[S_BN * NPX + p] += w * n[0];
                    st[(S_BN + 1) * NPX + p] += w * n[1];
                    st[(S_BN + 2) * NPX + p] += w * n[2];
                    st[S_BD * NPX + p] += w * z;
                    st[S_T * NPX + p] = ti;
                    da8[l] = d_alpha;
                    e8[l] = e;
                    a8[l] = a;
                    m8[l] = ok & !clamped;
                    w8[l] = w;
                    i8[l] = inv;
                    ti8[l] = ti;
                }
                for (ch, &f) in fv.iter().enumerate() {
                    let f = f as f32;
                    let (g, s) =
                        (&gf[ch * NPX + base..ch * NPX + base + L], &mut sf[ch * NPX + base..ch * NPX + base + L]);
                    for l in 0..L {
                        fa[ch][l] += g[l] * w8[l];
                        da8[l] += g[l] * (ti8[l] * f - s[l] * i8[l]);
                        s[l] += w8[l] * f;
                    }
                }
                for l in 0..L {
                    let dx = qx0 + l as f32;
                    let da = if m8[l] { da8[l] } else { 0.0 };
                    acc[5][l] += da * e8[l];
                    let dp = da * a8[l];
                    acc[2][l] += dp * (-0.5 * dx * dx);
                    acc[3][l] += dp * (-dx * dy);
                    acc[4][l] += dp * (-0.5 * dy * dy);
                    acc[0][l] += dp * (ca * dx + cb * dy);
                    acc[1][l] += dp * (cb * dx + cc * dy);
                }
            }
        }
        let o_slot = &mut out[slot * stride..(slot + 1) * stride];
        for (dst, lanes) in o_slot.iter_mut().zip(acc.iter().chain(fa.iter())) {
            *dst = lanes.iter().sum();
        }
        for ch in 0..3 {
            if h.color[ch] <= 0.0 {
                o_slot[6 + ch] = 0.0;
            }
        }
    }
    walked
}
