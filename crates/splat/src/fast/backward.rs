//! The f32 tiled backward rasterizer: one tile, its Gaussians back to front over the same 4x2
//! chunks as the forward pass (`tile`), eight pixels at once; then the merge of the tiles' sums.
//!
//! Per pixel the arithmetic of `backward::step_back`: the transmittance before a Gaussian is
//! recovered as `T_i = T_{i+1} / (1 - alpha_i)` from the stored final one, a pixel takes part for
//! the Gaussians it walked in the forward pass (`last`), `d out / d alpha_i = T_i v_i - S_i /
//! (1 - alpha_i)` with `S_i` what lies behind (background included), clamped alphas and colours
//! clamped at 0 pass no gradient. Each Gaussian's screen-space sums are kept per lane and added
//! across lanes in a fixed order at the end of the Gaussian (deterministic). Lanes that do not
//! take part are made neutral by selects (alpha 0, gradient 0), never by branches.

// Index loops over the three colour / normal channels mirror the formulas.
#![allow(clippy::needless_range_loop)]

use super::forward::CH_T;
use super::lanes::{dispatch, exp, L};
use super::project::Hot32;
use super::tile::{
    accepts, any_lane, pair_quads, pair_range, power_at, prefetch, slot as tile_slot, Lanes, AHEAD, ALPHA_MAX, CHUNKS,
    LANE_DX, LANE_DY, NPX, QUADS,
};
use crate::backward::Upstream;
use crate::tiles::Rect;

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

type Plane = [Lanes; CHUNKS];

/// Per-pixel state of a tile while it is walked back to front, in half-row chunks.
struct State {
    t: Plane,
    last: Plane,
    /// d L / d alpha_out x T_final.
    ua: Plane,
    urgb: [Plane; 3],
    ud: Plane,
    un: [Plane; 3],
    brgb: [Plane; 3],
    bd: Plane,
    bn: [Plane; 3],
}

dispatch! {
    /// Walks one tile back to front; `out` gets `(G_CH + k)` sums per slot for the first
    /// `walked` slots of the tile's list (resized here; returns `walked`). `fstate` is scratch
    /// for the features (`2 k NPX`).
    pub fn tile_backward(tb: &TileBack, out: &mut Vec<f32>, fstate: &mut Vec<f32>) -> usize => tile_backward_kernel
}

#[inline(always)]
fn tile_backward_kernel(tb: &TileBack, out: &mut Vec<f32>, fstate: &mut Vec<f32>) -> usize {
    let (r, k) = (tb.rect, tb.k);
    let z3 = || [[[0.0f32; L]; CHUNKS]; 3];
    let mut st = State {
        t: [[0.0; L]; CHUNKS],
        last: [[0.0; L]; CHUNKS],
        ua: [[0.0; L]; CHUNKS],
        urgb: z3(),
        ud: [[0.0; L]; CHUNKS],
        un: z3(),
        brgb: z3(),
        bd: [[0.0; L]; CHUNKS],
        bn: z3(),
    };
    let up = tb.up;
    fstate.clear();
    fstate.resize(2 * k * NPX, 0.0);
    let (gf, sf) = fstate.split_at_mut(k * NPX);
    let mut walked = 0u32;
    for y in 0..r.h {
        for x in 0..r.w {
            let (p, pix) = (tile_slot(x, y), (r.y0 + y) * tb.width + r.x0 + x);
            let (ci, l) = (p / L, p % L);
            let t = tb.fwd[CH_T * NPX + p];
            let lst = tb.last[p];
            walked = walked.max(lst);
            st.t[ci][l] = t;
            st.last[ci][l] = lst as f32;
            st.ua[ci][l] = (up.alpha[pix] * t as f64) as f32;
            st.ud[ci][l] = up.depth[pix] as f32;
            let n = up.normal[pix];
            let nc: [f64; 3] = match &tb.nrot {
                Some(m) => {
                    std::array::from_fn(|a| m[a][0] as f64 * n[0] + m[a][1] as f64 * n[1] + m[a][2] as f64 * n[2])
                }
                None => n,
            };
            for c in 0..3 {
                st.urgb[c][ci][l] = up.rgb[pix][c] as f32;
                st.un[c][ci][l] = nc[c] as f32;
                st.brgb[c][ci][l] = tb.background[c] * t;
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
    for i in 0..AHEAD.min(walked) {
        prefetch(tb.hot, tb.list[walked - 1 - i] as usize);
    }
    for slot in (0..walked).rev() {
        if slot >= AHEAD {
            prefetch(tb.hot, tb.list[slot - AHEAD] as usize);
        }
        let pi = tb.list[slot] as usize;
        let h = &tb.hot[pi];
        let span = h.span();
        let vc = h.color.map(|c| c.max(0.0));
        let (n, z) = (h.normal, h.depth);
        let fv = &tb.feats[pi * k..(pi + 1) * k];
        let slot_f = slot as f32;
        let [ca, cb, cc] = h.conic;
        let (o, pmin, ex, ey) = (h.opacity, h.power_min, h.extent[0], h.extent[1]);
        let qx_base = r.x0 as f32 + 0.5 - h.mean[0];
        let qy_base = r.y0 as f32 + 0.5 - h.mean[1];
        // Lane sums: mean (2), conic (3), opacity, colour (3), depth, normal (3).
        let mut acc = [[0.0f32; L]; G_CH];
        fa.iter_mut().for_each(|v| *v = [0.0; L]);
        let (j_lo, j_hi) = pair_range(h, &r);
        for j in j_lo..j_hi {
            let (q_lo, q_hi) = pair_quads(h, &span, &r, j);
            let dy0 = qy_base + (2 * j) as f32;
            for q in q_lo..q_hi {
                let ci = j * QUADS + q;
                let dx0 = qx_base + (4 * q) as f32;
                let ls = st.last[ci];
                if !any_lane(h, dx0, dy0, &ls.map(|v| slot_f < v)) {
                    continue;
                }
                let (tt, ua, ud) = (st.t[ci], st.ua[ci], st.ud[ci]);
                let (ur, ug, ub) = (st.urgb[0][ci], st.urgb[1][ci], st.urgb[2][ci]);
                let (un0, un1, un2) = (st.un[0][ci], st.un[1][ci], st.un[2][ci]);
                let (br, bg, bb) = (st.brgb[0][ci], st.brgb[1][ci], st.brgb[2][ci]);
                let (bn0, bn1, bn2) = (st.bn[0][ci], st.bn[1][ci], st.bn[2][ci]);
                let bd = st.bd[ci];
                let mut w8: Lanes = [0.0; L];
                let mut i8: Lanes = [0.0; L];
                let mut ti8: Lanes = [0.0; L];
                let mut da8: Lanes = [0.0; L];
                let mut e8: Lanes = [0.0; L];
                let mut a8: Lanes = [0.0; L];
                let mut m8 = [false; L];
                for l in 0..L {
                    let (dx, dy) = (dx0 + LANE_DX[l], dy0 + LANE_DY[l]);
                    let power = power_at(ca, cb, cc, dx, dy);
                    let e = exp(power);
                    let raw = o * e;
                    let clamped = raw > ALPHA_MAX;
                    let alpha = if clamped { ALPHA_MAX } else { raw };
                    let ok = (slot_f < ls[l]) & accepts(dx, dy, ex, ey, power, pmin, alpha);
                    let a = if ok { alpha } else { 0.0 };
                    let inv = 1.0 / (1.0 - a);
                    let ti = tt[l] * inv;
                    let w = a * ti;
                    da8[l] = ua[l] * inv
                        + ud[l] * (ti * z - bd[l] * inv)
                        + ur[l] * (ti * vc[0] - br[l] * inv)
                        + ug[l] * (ti * vc[1] - bg[l] * inv)
                        + ub[l] * (ti * vc[2] - bb[l] * inv)
                        + un0[l] * (ti * n[0] - bn0[l] * inv)
                        + un1[l] * (ti * n[1] - bn1[l] * inv)
                        + un2[l] * (ti * n[2] - bn2[l] * inv);
                    e8[l] = e;
                    a8[l] = a;
                    m8[l] = ok & !clamped;
                    w8[l] = w;
                    i8[l] = inv;
                    ti8[l] = ti;
                }
                let add = |acc: &mut Lanes, u: &Lanes| {
                    for l in 0..L {
                        acc[l] += u[l] * w8[l];
                    }
                };
                add(&mut acc[6], &ur);
                add(&mut acc[7], &ug);
                add(&mut acc[8], &ub);
                add(&mut acc[9], &ud);
                add(&mut acc[10], &un0);
                add(&mut acc[11], &un1);
                add(&mut acc[12], &un2);
                let grow = |b: &mut Lanes, v: f32| {
                    for l in 0..L {
                        b[l] += w8[l] * v;
                    }
                };
                grow(&mut st.brgb[0][ci], vc[0]);
                grow(&mut st.brgb[1][ci], vc[1]);
                grow(&mut st.brgb[2][ci], vc[2]);
                grow(&mut st.bn[0][ci], n[0]);
                grow(&mut st.bn[1][ci], n[1]);
                grow(&mut st.bn[2][ci], n[2]);
                grow(&mut st.bd[ci], z);
                st.t[ci] = ti8;
                for (ch, &f) in fv.iter().enumerate() {
                    let f = f as f32;
                    let o = ch * NPX + ci * L;
                    let (g, s) = (&gf[o..o + L], &mut sf[o..o + L]);
                    for l in 0..L {
                        fa[ch][l] += g[l] * w8[l];
                        da8[l] += g[l] * (ti8[l] * f - s[l] * i8[l]);
                        s[l] += w8[l] * f;
                    }
                }
                for l in 0..L {
                    let (dx, dy) = (dx0 + LANE_DX[l], dy0 + LANE_DY[l]);
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
