//! The per-contribution step of the backward pass that both backward rasterizers (the
//! brute-force reference in `backward`, the tiled one in `raster_backward`) share: the channel
//! gradients a loss hands in ([`Upstream`]), what a pixel carries back to front ([`PixelUp`],
//! [`Behind`]), one Gaussian's screen-space gradient accumulators, and the step itself
//! ([`step_back`]); the parameter gradients they end in ([`Gradients`]). The formulas are in
//! `backward`'s notes.

// Index loops mirror the per-channel formulas; iterator rewrites would hide them.
#![allow(clippy::needless_range_loop)]

use crate::gaussians::Gaussians;
use crate::project::Projected;

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
    pub(crate) fn is_zero(&self) -> bool {
        self.mean.iter().chain(&self.conic).chain(&self.color).chain(&self.normal).all(|v| *v == 0.0)
            && self.opacity == 0.0
            && self.depth == 0.0
    }

    pub(crate) fn add(&mut self, o: &G2) {
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
