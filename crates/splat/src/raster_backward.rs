//! The tiled backward rasterizer: per tile, the Gaussians back to front, each over only the tile
//! pixels inside its ellipse (the forward pass's `tiles::spans`).
//!
//! A pixel takes part for the Gaussians it walked in the forward pass (`Context::last`). Its
//! transmittance before each contribution is recovered from the stored final one by
//! `T_i = T_{i+1} / (1 - alpha_i)` (exact up to rounding: alpha <= 0.99 outside test mode), as
//! gsplat does, so nothing per contribution is stored. Each Gaussian sums its screen-space
//! gradients over the tile's pixels; `backward` merges the tiles.

use crate::backward_step::{step_back, Behind, PixelUp, Upstream, G2};
use crate::forward::{Features, RenderOptions};
use crate::raster::Context;
use crate::tiles::{alpha_at, spans, TILE};

/// One pixel's state while its tile is walked back to front (one cache line or two).
#[derive(Clone, Copy, Default)]
struct Px {
    up: PixelUp,
    behind: Behind,
    /// Transmittance after the Gaussians not yet walked back.
    t: f64,
    last: u32,
    pix: usize,
}

/// Screen-space and feature gradients of a tile's Gaussians, by their slot in the tile's list
/// (only the slots some pixel walked).
pub(crate) fn tile_backward(
    ctx: &Context,
    ti: usize,
    feats: &Features,
    opts: &RenderOptions,
    up: &Upstream,
    nrot: &Option<[[f64; 3]; 3]>,
) -> (Vec<G2>, Vec<f64>) {
    let k = feats.channels;
    let rect = ctx.tiles.rect(ti);
    let list = &ctx.tiles.lists[ti];
    let mut px = [Px::default(); TILE * TILE];
    rect.for_each(ctx.tiles.width, |p, pix| {
        let t = ctx.final_t[pix];
        let (up, behind) = (PixelUp::new(up, pix, t, nrot), Behind::new(opts.background, t));
        px[p] = Px { up, behind, t, last: ctx.last[pix], pix };
    });
    let walked = px.iter().map(|p| p.last).max().unwrap_or(0) as usize;
    let mut s_f = vec![0.0; TILE * TILE * k];
    let (mut acc, mut facc) = (vec![G2::default(); walked], vec![0.0; walked * k]);
    for slot in (0..walked).rev() {
        let pi = list[slot] as usize;
        let (g, h) = (&ctx.proj[pi], &ctx.hot[pi]);
        let fi = feats.of(g.index);
        let mut a = G2::default();
        let fa = &mut facc[slot * k..(slot + 1) * k];
        for sp in spans(h, rect, opts.smooth) {
            let (qy, row) = (sp.y as f64 + 0.5, (sp.y - rect.y0) * TILE);
            for x in sp.x0..sp.x1 {
                let p = row + x - rect.x0;
                let xp = &mut px[p];
                if slot as u32 >= xp.last {
                    continue;
                }
                let q = [x as f64 + 0.5, qy];
                let Some((alpha, e, clamped)) = alpha_at(h, q, opts.smooth) else { continue };
                let inv = 1.0 / (1.0 - alpha);
                let ti = xp.t * inv;
                let gf = &up.features[xp.pix * k..(xp.pix + 1) * k];
                let sf = &mut s_f[p * k..(p + 1) * k];
                step_back(&xp.up, gf, &mut xp.behind, sf, g, fi, q, (alpha, ti, inv, e, clamped), &mut a, fa);
                xp.t = ti;
            }
        }
        acc[slot] = a;
    }
    (acc, facc)
}
