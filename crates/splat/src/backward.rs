//! Hand-derived gradients of every rendered channel with respect to every Gaussian parameter:
//! the entry points and the brute-force per-pixel reference; the per-contribution step both
//! backward rasterizers share is `backward_step`.
//!
//! Per pixel, the forward composite `out = sum_i w_i v_i + T_N bg` (`w_i = alpha_i T_i`) is walked
//! back to front: `d out / d alpha_i = T_i v_i - S_i / (1 - alpha_i)` with `S_i` the sum of what
//! lies behind `i` (background included), and `d alpha_out / d alpha_i = T_N / (1 - alpha_i)`.
//! Then `alpha = o exp(power)`, `power = -0.5 d^T K d` (`K` the conic, `d = q - mean`) give the
//! screen-space gradients (mean, conic, opacity); `chain` takes them on to the parameters.
//! Colours clamped at 0 and alphas clamped at 0.99 pass no gradient, like the forward.

// Index loops mirror the per-channel formulas above; iterator rewrites would hide them.
#![allow(clippy::needless_range_loop)]

use crate::backward_step::{step_back, Behind, PixelUp, G2};
pub use crate::backward_step::{Gradients, Upstream};
use crate::camera::Camera;
use crate::chain::{gaussian_backward, ParamGrads};
use crate::forward::{normal_rotation, project_sorted, Features, RenderOptions};
use crate::gaussians::Gaussians;
use crate::project::{project_full, Projected};
use crate::raster::render_with_context;
use crate::raster::Context;
use crate::raster_backward::tile_backward;
use crate::tiles::{alpha_at, Hot, T_MIN};
use rayon::prelude::*;

/// From the screen-space gradients of every projected Gaussian (`acc[k]` for `proj[k]`) to the
/// parameter gradients in `out` (reset here; rayon over Gaussians, each projected Gaussian owns
/// its output slots).
#[allow(clippy::too_many_arguments)]
fn finish(
    g: &Gaussians,
    cam: &Camera,
    opts: &RenderOptions,
    proj: &[Projected],
    acc: &[G2],
    facc: &[f64],
    k: usize,
    out: &mut Gradients,
) {
    let kc = g.coeffs() * 3;
    out.reset(g, k);
    let mut slot_of = vec![u32::MAX; g.len()];
    for (s, p) in proj.iter().enumerate() {
        slot_of[p.index] = s as u32;
    }
    (
        out.means.par_iter_mut(),
        out.log_scales.par_iter_mut(),
        out.rotations.par_iter_mut(),
        out.opacity_logits.par_iter_mut(),
        out.sh.par_chunks_mut(kc),
        out.mean2d_norm.par_iter_mut(),
    )
        .into_par_iter()
        .enumerate()
        .for_each(|(i, (mean, log_scale, rotation, opacity_logit, sh, mean2d_norm))| {
            let s = slot_of[i];
            if s == u32::MAX {
                return;
            }
            let (pr, a) = (&proj[s as usize], &acc[s as usize]);
            // Every parameter gradient is linear in the screen-space ones: nothing to do at zero.
            if a.is_zero() {
                return;
            }
            // Deterministic: the same call that projected it in the forward pass.
            let Some((_, f)) = project_full(g, i, cam, opts.antialiased, opts.smooth) else { return };
            let grads = ParamGrads { mean, log_scale, rotation, opacity_logit, sh, mean2d_norm };
            gaussian_backward(g, cam, opts, pr, &f, a, grads);
        });
    for (s, p) in proj.iter().enumerate() {
        out.features[p.index * k..(p.index + 1) * k].copy_from_slice(&facc[s * k..(s + 1) * k]);
    }
}

/// Gradients of `sum(upstream * outputs)` for the render that produced `ctx` (same inputs).
pub fn backward(
    g: &Gaussians,
    cam: &Camera,
    feats: &Features,
    opts: &RenderOptions,
    ctx: &Context,
    up: &Upstream,
) -> Gradients {
    let mut out = Gradients::default();
    backward_into(g, cam, feats, opts, ctx, up, &mut out);
    out
}

/// [`backward`] into existing gradients, reusing their memory (overwritten, not added to).
pub fn backward_into(
    g: &Gaussians,
    cam: &Camera,
    feats: &Features,
    opts: &RenderOptions,
    ctx: &Context,
    up: &Upstream,
    out: &mut Gradients,
) {
    let nrot = normal_rotation(cam, opts);
    let k = feats.channels;
    let per_tile: Vec<(Vec<G2>, Vec<f64>)> =
        (0..ctx.tiles.lists.len()).into_par_iter().map(|ti| tile_backward(ctx, ti, feats, opts, up, &nrot)).collect();
    let n = ctx.proj.len();
    let (mut acc, mut facc) = (vec![G2::default(); n], vec![0.0; n * k]);
    for (list, (a, fa)) in ctx.tiles.lists.iter().zip(&per_tile) {
        for (slot, &pi) in list.iter().enumerate().take(a.len()) {
            let pi = pi as usize;
            acc[pi].add(&a[slot]);
            for c in 0..k {
                facc[pi * k + c] += fa[slot * k + c];
            }
        }
    }
    finish(g, cam, opts, &ctx.proj, &acc, &facc, k, out);
}

/// Renders, then [`backward`]: gradients of `sum(upstream * outputs)` for a render with these inputs.
pub fn render_backward(
    g: &Gaussians,
    cam: &Camera,
    feats: &Features,
    opts: &RenderOptions,
    up: &Upstream,
) -> Gradients {
    let (_, ctx) = render_with_context(g, cam, feats, opts);
    backward(g, cam, feats, opts, &ctx, up)
}

/// The reference: every pixel re-walks every Gaussian front to back, keeps its contributions,
/// then walks them back to front (no tiles, no spans, no stored transmittance).
pub fn render_backward_brute_force(
    g: &Gaussians,
    cam: &Camera,
    feats: &Features,
    opts: &RenderOptions,
    up: &Upstream,
) -> Gradients {
    let proj = project_sorted(g, cam, opts);
    let hot: Vec<Hot> = proj.iter().map(Hot::of).collect();
    let nrot = normal_rotation(cam, opts);
    let k = feats.channels;
    let (mut acc, mut facc) = (vec![G2::default(); proj.len()], vec![0.0; proj.len() * k]);
    let (w, h) = (cam.width as usize, cam.height as usize);
    for pix in 0..w * h {
        let q = [(pix % w) as f64 + 0.5, (pix / w) as f64 + 0.5];
        // (projected index, (alpha, T before, 1 / (1 - alpha), exp(power), clamped))
        let mut hits = Vec::new();
        let mut t = 1.0;
        for (s, hs) in hot.iter().enumerate() {
            let Some((alpha, e, clamped)) = alpha_at(hs, q, opts.smooth) else { continue };
            let next = t * (1.0 - alpha);
            if !opts.smooth && next < T_MIN {
                break;
            }
            hits.push((s, (alpha, t, 1.0 / (1.0 - alpha), e, clamped)));
            t = next;
        }
        let pu = PixelUp::new(up, pix, t, &nrot);
        let gf = &up.features[pix * k..(pix + 1) * k];
        let (mut behind, mut s_f) = (Behind::new(opts.background, t), vec![0.0; k]);
        for &(s, step) in hits.iter().rev() {
            let p = &proj[s];
            let fa = &mut facc[s * k..(s + 1) * k];
            step_back(&pu, gf, &mut behind, &mut s_f, p, feats.of(p.index), q, step, &mut acc[s], fa);
        }
    }
    let mut out = Gradients::default();
    finish(g, cam, opts, &proj, &acc, &facc, k, &mut out);
    out
}
