//! Forward rendering: the options, output image and feature types, the per-contribution
//! accumulation every renderer shares, and the brute-force per-pixel reference. The fast tiled
//! renderer lives in `raster`; `render` gathers both for callers.
//!
//! Per Gaussian and pixel centre `q`: `alpha = min(0.99, o exp(-0.5 d^T conic d))`,
//! `d = q - mean`; skipped if `alpha < 1/255`; the pixel stops before a Gaussian that would drop
//! the transmittance below 1e-4. Outputs: `rgb = sum w max(c, 0) + T background`,
//! `alpha = 1 - T`, `depth = sum w z` (expected depth), `normal = sum w n` (camera frame, or world
//! frame on request), `features = sum w f`, with `w = alpha T` and `T` the transmittance before
//! the Gaussian.

use crate::camera::Camera;
use crate::gaussians::Gaussians;
use crate::project::{project_full, Projected};
use crate::tiles::{alpha_at, sort_by_depth, Hot, T_MIN};
use rayon::prelude::*;

pub use crate::tiles::{ALPHA_MAX, TILE};

#[derive(Clone, Debug, Default)]
pub struct RenderOptions {
    pub background: [f64; 3],
    pub antialiased: bool,
    /// Normals in the world frame instead of the camera frame.
    pub normals_world: bool,
    /// Test mode for finite-difference checks: no alpha cut-off (1/255), no 0.99 clamp, no early
    /// stop, no culling of faint Gaussians and no tile culling, so outputs are smooth functions
    /// of the parameters.
    pub smooth: bool,
}

/// Rendered channels, row-major, f64 (the reference precision).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub rgb: Vec<[f64; 3]>,
    pub alpha: Vec<f64>,
    pub depth: Vec<f64>,
    pub normal: Vec<[f64; 3]>,
    /// `channels` values per pixel.
    pub features: Vec<f64>,
    pub channels: usize,
}

/// Per-Gaussian extra feature channels: `channels` values per Gaussian.
#[derive(Clone, Debug, Default)]
pub struct Features<'a> {
    pub values: &'a [f64],
    pub channels: usize,
}

impl Features<'_> {
    /// The feature values of Gaussian `i` (empty without channels).
    pub fn of(&self, i: usize) -> &[f64] {
        &self.values[i * self.channels..(i + 1) * self.channels]
    }
}

/// One pixel's running sums (features are kept beside it, `channels` per pixel).
#[derive(Clone, Copy, Debug, Default)]
pub struct PixelSum {
    pub rgb: [f64; 3],
    pub depth: f64,
    pub normal: [f64; 3],
}

impl PixelSum {
    /// Adds one contribution of weight `w = alpha T`; `normal` is already in the output frame.
    #[inline]
    pub fn add(&mut self, w: f64, g: &Projected, normal: &[f64; 3], fv: &[f64], out_f: &mut [f64]) {
        for (o, c) in self.rgb.iter_mut().zip(g.color) {
            *o += w * c.max(0.0);
        }
        self.depth += w * g.depth;
        for (o, v) in self.normal.iter_mut().zip(normal) {
            *o += w * v;
        }
        for (o, v) in out_f.iter_mut().zip(fv) {
            *o += w * v;
        }
    }
}

impl Image {
    pub(crate) fn blank(cam: &Camera, channels: usize) -> Image {
        let mut img = Image::default();
        img.reset(cam, channels);
        img
    }

    /// Sizes the image for `cam` with every channel zero, reusing its memory.
    pub(crate) fn reset(&mut self, cam: &Camera, channels: usize) {
        let n = cam.width as usize * cam.height as usize;
        (self.width, self.height, self.channels) = (cam.width as usize, cam.height as usize, channels);
        let zero = |v: &mut Vec<f64>, len| {
            v.clear();
            v.resize(len, 0.0);
        };
        zero(&mut self.alpha, n);
        zero(&mut self.depth, n);
        zero(&mut self.features, n * channels);
        for v in [&mut self.rgb, &mut self.normal] {
            v.clear();
            v.resize(n, [0.0; 3]);
        }
    }

    /// Stores pixel `i`: its sums, final transmittance `t` over `background`, and features.
    pub(crate) fn set(&mut self, i: usize, s: &PixelSum, t: f64, background: [f64; 3], features: &[f64]) {
        self.rgb[i] = std::array::from_fn(|c| s.rgb[c] + t * background[c]);
        self.alpha[i] = 1.0 - t;
        self.depth[i] = s.depth;
        self.normal[i] = s.normal;
        self.features[i * self.channels..(i + 1) * self.channels].copy_from_slice(features);
    }
}

/// The normal a Gaussian contributes in the output frame (world frame on request).
#[inline]
pub fn output_normal(g: &Projected, world_from_camera_rot: &Option<[[f64; 3]; 3]>) -> [f64; 3] {
    match world_from_camera_rot {
        // camera_from_world rotation R: n_world = R^T n_cam.
        Some(r) => std::array::from_fn(|a| (0..3).map(|k| r[k][a] * g.normal[k]).sum()),
        None => g.normal,
    }
}

/// The camera's `camera_from_world` rotation when normals are wanted in the world frame.
pub fn normal_rotation(cam: &Camera, opts: &RenderOptions) -> Option<[[f64; 3]; 3]> {
    opts.normals_world.then(|| std::array::from_fn(|a| std::array::from_fn(|b| cam.camera_from_world[a][b])))
}

/// Projects every Gaussian (culled ones are dropped), sorted front to back.
pub fn project_sorted(g: &Gaussians, cam: &Camera, opts: &RenderOptions) -> Vec<Projected> {
    let (mut proj, mut scratch) = (Vec::new(), Vec::new());
    project_sorted_into(g, cam, opts, &mut proj, &mut scratch);
    proj
}

/// [`project_sorted`] into `proj`, with `scratch` (one slot per Gaussian) for the parallel pass;
/// both keep their memory between calls.
pub fn project_sorted_into(
    g: &Gaussians,
    cam: &Camera,
    opts: &RenderOptions,
    proj: &mut Vec<Projected>,
    scratch: &mut Vec<Option<Projected>>,
) {
    scratch.resize(g.len(), None);
    scratch
        .par_iter_mut()
        .enumerate()
        .for_each(|(i, slot)| *slot = project_full(g, i, cam, opts.antialiased, opts.smooth).map(|(p, _)| p));
    proj.clear();
    proj.extend(scratch.iter().flatten());
    sort_by_depth(proj);
}

/// The reference: every pixel walks every Gaussian in depth order (no tiles, no spans).
pub fn render_brute_force(g: &Gaussians, cam: &Camera, feats: &Features, opts: &RenderOptions) -> Image {
    let proj = project_sorted(g, cam, opts);
    let hot: Vec<Hot> = proj.iter().map(Hot::of).collect();
    let nrot = normal_rotation(cam, opts);
    let normals: Vec<[f64; 3]> = proj.iter().map(|p| output_normal(p, &nrot)).collect();
    let mut img = Image::blank(cam, feats.channels);
    let mut f = vec![0.0; feats.channels];
    for y in 0..img.height {
        for x in 0..img.width {
            let q = [x as f64 + 0.5, y as f64 + 0.5];
            let (mut sum, mut t) = (PixelSum::default(), 1.0);
            f.fill(0.0);
            for (k, h) in hot.iter().enumerate() {
                let Some((alpha, _, _)) = alpha_at(h, q, opts.smooth) else { continue };
                let next = t * (1.0 - alpha);
                if !opts.smooth && next < T_MIN {
                    break;
                }
                sum.add(alpha * t, &proj[k], &normals[k], feats.of(proj[k].index), &mut f);
                t = next;
            }
            img.set(y * img.width + x, &sum, t, opts.background, &f);
        }
    }
    img
}
