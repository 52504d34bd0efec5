//! Hand-derived gradients of every rendered channel with respect to every Gaussian parameter:
//! the entry points, the per-contribution step both backward rasterizers share, and the
//! brute-force per-pixel reference.
//!
//! Per pixel, the forward composite `out = sum_i w_i v_i + T_N bg` (`w_i = alpha_i T_i`) is walked
//! back to front: `d out / d alpha_i = T_i v_i - S_i / (1 - alpha_i)` with `S_i` the sum of what
//! lies behind `i` (background included), and `d alpha_out / d alpha_i = T_N / (1 - alpha_i)`.
//! Then `alpha = o exp(power)`, `power = -0.5 d^T K d` (`K` the conic, `d = q - mean`) give the
//! screen-space gradients (mean, conic, opacity); `chain` takes them on to the parameters.
//! Colours clamped at 0 and alphas clamped at 0.99 pass no gradient, like the forward.

// Index loops mirror the per-channel formulas above; iterator rewrites would hide them.
#![allow(clippy::needless_range_loop)]

use crate::camera::Camera;
use crate::chain::{gaussian_backward, ParamGrads};
use crate::gaussians::Gaussians;
use crate::project::{project_full, Projected};
use crate::raster::Context;
use crate::raster_backward::tile_backward;
use crate::render::{normal_rotation, project_sorted, render_with_context, Features, RenderOptions};
use crate::tiles::{alpha_at, Hot, T_MIN};
use rayon::prelude::*;

/// Gradients of a scalar loss with respect to the rendered channels (same layout as `Image`).
pub struct Upstream<'a> {
    pub rgb: &'a [[f64; 3]],
    pub alpha: &'a [f64],
    pub depth: &'a [f64],
    pub normal: &'a [[f64; 3]],
    pub features: &'a [f64],
}

/// Gradients with respect to the model's parameters (same layout as `Gaussians`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Gradients {
    pub means: Vec<[f64; 3]>,
    pub log_scales: Vec<[f64; 3]>,
    pub rotations: Vec<[f64; 4]>,
    pub opacity_logits: Vec<f64>,
    pub sh: Vec<f64>,
    pub features: Vec<f64>,
    /// |dL / d mean2d| per Gaussian (the screen-space gradient densification uses).
    pub mean2d_norm: Vec<f64>,
}

impl Gradients {
    /// Sizes every array for `g` (and `channels` features per Gaussian), all zero, reusing memory.
    pub fn reset(&mut self, g: &Gaussians, channels: usize) {
        self.means.clear();
        self.log_scales.clear();
        self.rotations.clear();
        self.opacity_logits.clear();
        self.sh.clear();
        self.features.clear();
        self.mean2d_norm.clear();
        self.resize_for(g, channels);
    }

    /// Sizes every array for `g` (and `channels` features per Gaussian), leaving the rows already
    /// there as they are (only new ones are zero): for a caller that writes every row itself, in parallel,
    /// instead of a serial clear of the whole model first.
    pub fn resize_for(&mut self, g: &Gaussians, channels: usize) {
        let m = g.len();
        self.means.resize(m, [0.0; 3]);
        self.log_scales.resize(m, [0.0; 3]);
        self.rotations.resize(m, [0.0; 4]);
        self.opacity_logits.resize(m, 0.0);
        self.sh.resize(g.sh.len(), 0.0);
        self.features.resize(m * channels, 0.0);
        self.mean2d_norm.resize(m, 0.0);
    }
}

/// Screen-space gradients of one projected Gaussian.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct G2 {
    pub mean: [f64; 2],
    pub conic: [f64; 3],
    pub opacity: f64,
    pub color: [f64; 3],
    pub depth: f64,
    pub normal: [f64; 3],
}

impl G2 {
    fn is_zero(&self) -> bool {
        self.mean.iter().chain(&self.conic).chain(&self.color).chain(&self.normal).all(|v| *v == 0.0)
            && self.opacity == 0.0
            && self.depth == 0.0
    }

    fn add(&mut self, o: &G2) {
        for c in 0..3 {
            self.conic[c] += o.conic[c];
            self.color[c] += o.color[c];
            self.normal[c] += o.normal[c];
        }
        self.mean[0] += o.mean[0];
        self.mean[1] += o.mean[1];
        self.opacity += o.opacity;
        self.depth += o.depth;
    }
}

/// One pixel's upstream gradients (normal gradient in camera axes) and final transmittance.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct PixelUp {
    pub rgb: [f64; 3],
    pub alpha: f64,
    pub depth: f64,
    pub normal: [f64; 3],
    pub t_final: f64,
}

impl PixelUp {
    pub fn new(up: &Upstream, pix: usize, t_final: f64, nrot: &Option<[[f64; 3]; 3]>) -> Self {
        let n = up.normal[pix];
        // The output may be world-frame: n_world = R^T n_cam, so d/dn_cam = R d/dn_world.
        let normal = match nrot {
            Some(r) => std::array::from_fn(|a| (0..3).map(|b| r[a][b] * n[b]).sum()),
            None => n,
        };
        PixelUp { rgb: up.rgb[pix], alpha: up.alpha[pix], depth: up.depth[pix], normal, t_final }
    }
}

/// What lies behind the current Gaussian at one pixel (background included); features beside it.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Behind {
    pub rgb: [f64; 3],
    pub depth: f64,
    pub normal: [f64; 3],
}

impl Behind {
    pub fn new(background: [f64; 3], t_final: f64) -> Self {
        Behind { rgb: background.map(|b| t_final * b), ..Default::default() }
    }
}

/// One contribution's backward step at pixel centre `q`: adds to the Gaussian's screen-space
/// gradients `a` and feature gradients `fa`, then adds the contribution to what lies behind.
/// `ti` is the transmittance before it, `inv = 1 / (1 - alpha)`, `e = exp(power)`; `fi` its features, `gf` the pixel's feature gradients.
#[allow(clippy::too_many_arguments)]
#[inline]
pub(crate) fn step_back(
    up: &PixelUp,
    gf: &[f64],
    behind: &mut Behind,
    s_f: &mut [f64],
    g: &Projected,
    fi: &[f64],
    q: [f64; 2],
    (alpha, ti, inv, e, clamped): (f64, f64, f64, f64, bool),
    a: &mut G2,
    fa: &mut [f64],
) {
    let w = alpha * ti;
    let vc = g.color.map(|c| c.max(0.0));
    for ch in 0..3 {
        if g.color[ch] > 0.0 {
            a.color[ch] += up.rgb[ch] * w;
        }
        a.normal[ch] += up.normal[ch] * w;
    }
    a.depth += up.depth * w;
    for (o, gfc) in fa.iter_mut().zip(gf) {
        *o += gfc * w;
    }
    let mut d_alpha = up.alpha * up.t_final * inv + up.depth * (ti * g.depth - behind.depth * inv);
    for ch in 0..3 {
        d_alpha += up.rgb[ch] * (ti * vc[ch] - behind.rgb[ch] * inv)
            + up.normal[ch] * (ti * g.normal[ch] - behind.normal[ch] * inv);
    }
    for c in 0..fi.len() {
        d_alpha += gf[c] * (ti * fi[c] - s_f[c] * inv);
        s_f[c] += w * fi[c];
    }
    for ch in 0..3 {
        behind.rgb[ch] += w * vc[ch];
        behind.normal[ch] += w * g.normal[ch];
    }
    behind.depth += w * g.depth;
    if clamped {
        return;
    }
    a.opacity += d_alpha * e;
    let d_power = d_alpha * alpha;
    let (dx, dy) = (q[0] - g.mean[0], q[1] - g.mean[1]);
    a.conic[0] += d_power * -0.5 * dx * dx;
    a.conic[1] += d_power * -dx * dy;
    a.conic[2] += d_power * -0.5 * dy * dy;
    a.mean[0] += d_power * (g.conic[0] * dx + g.conic[1] * dy);
    a.mean[1] += d_power * (g.conic[1] * dx + g.conic[2] * dy);
}

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
