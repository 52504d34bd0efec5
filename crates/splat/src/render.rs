//! Forward rendering: project (rayon), bin into 16x16 tiles, sort each tile's Gaussians by depth,
//! composite front to back per pixel (rayon over tiles). Per Gaussian and pixel centre `q`:
//! `alpha = min(0.99, o exp(-0.5 d^T conic d))`, `d = q - mean`; skipped if `alpha < 1/255`; the
//! pixel stops before a Gaussian that would drop the transmittance below 1e-4. Outputs:
//! `rgb = sum w max(c, 0) + T background`, `alpha = 1 - T`, `depth = sum w z` (expected depth),
//! `normal = sum w n` (camera frame, or world frame on request), `features = sum w f`, with
//! `w = alpha T` and `T` the transmittance before the Gaussian.

use crate::camera::Camera;
use crate::gaussians::Gaussians;
use crate::project::{project_full, Frame, Projected, ALPHA_MIN};
use rayon::prelude::*;

pub const TILE: usize = 16;
pub const ALPHA_MAX: f64 = 0.99;
pub const T_MIN: f64 = 1e-4;

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
#[derive(Clone, Debug, PartialEq)]
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

/// One pixel's accumulation over depth-sorted candidates.
#[allow(clippy::too_many_arguments)]
/// The inner-loop data of one depth-ordered candidate: mean x, y, conic a, b, c, opacity,
/// radius, and the exponent below which alpha < 1/255 (`ln(1 / (255 o))`, so faint
/// contributions are rejected without calling `exp`). Compact, so a tile's candidates stay in
/// cache while its pixels scan them.
pub type Hot = [f64; 8];

pub fn hot(proj: &[Projected], order: &[usize]) -> Vec<Hot> {
    order
        .iter()
        .map(|&pi| {
            let g = &proj[pi];
            [
                g.mean[0],
                g.mean[1],
                g.conic[0],
                g.conic[1],
                g.conic[2],
                g.opacity,
                g.radius,
                (ALPHA_MIN / g.opacity).ln(),
            ]
        })
        .collect()
}

/// Alpha of candidate `h` at pixel centre `q`: `None` if it does not contribute (outside its
/// radius, power > 0, or below 1/255); else `(alpha, power, clamped at 0.99)`. The one definition
/// the forward and backward passes share.
#[inline]
pub fn alpha_at(h: &Hot, q: [f64; 2], smooth: bool) -> Option<(f64, f64, bool)> {
    let (dx, dy) = (q[0] - h[0], q[1] - h[1]);
    // Outside the radius alpha < 1/255: rejected before any arithmetic.
    if !smooth && (dx.abs() > h[6] || dy.abs() > h[6]) {
        return None;
    }
    let power = -0.5 * (h[2] * dx * dx + h[4] * dy * dy) - h[3] * dx * dy;
    if power > 0.0 || (!smooth && power < h[7]) {
        return None;
    }
    let raw = h[5] * power.exp();
    let clamped = !smooth && raw > ALPHA_MAX;
    let alpha = if clamped { ALPHA_MAX } else { raw };
    if !smooth && alpha < ALPHA_MIN {
        return None;
    }
    Some((alpha, power, clamped))
}

#[allow(clippy::too_many_arguments)]
fn composite(
    q: [f64; 2],
    order: &[usize],
    hot: &[Hot],
    proj: &[Projected],
    feats: &Features,
    opts: &RenderOptions,
    normal_rot: &Option<[[f64; 3]; 3]>,
    out_f: &mut [f64],
) -> ([f64; 3], f64, f64, [f64; 3]) {
    let (mut rgb, mut depth, mut n) = ([0.0; 3], 0.0, [0.0; 3]);
    let mut t = 1.0;
    for (slot, h) in hot.iter().enumerate() {
        let Some((alpha, _, _)) = alpha_at(h, q, opts.smooth) else { continue };
        let next = t * (1.0 - alpha);
        if !opts.smooth && next < T_MIN {
            break;
        }
        let g = &proj[order[slot]];
        let w = alpha * t;
        for (o, c) in rgb.iter_mut().zip(g.color) {
            *o += w * c.max(0.0);
        }
        depth += w * g.depth;
        let gn = match normal_rot {
            Some(r) => std::array::from_fn(|a| (0..3).map(|k| r[k][a] * g.normal[k]).sum()),
            None => g.normal,
        };
        for (o, v) in n.iter_mut().zip(gn) {
            *o += w * v;
        }
        for (c, o) in out_f.iter_mut().enumerate() {
            *o += w * feats.values[g.index * feats.channels + c];
        }
        t = next;
    }
    for (o, b) in rgb.iter_mut().zip(opts.background) {
        *o += t * b;
    }
    (rgb, 1.0 - t, depth, n)
}

impl Image {
    /// Stores one pixel's composite (rgb, alpha, depth, normal) and features.
    fn set(&mut self, i: usize, (rgb, alpha, depth, normal): ([f64; 3], f64, f64, [f64; 3]), features: &[f64]) {
        self.rgb[i] = rgb;
        self.alpha[i] = alpha;
        self.depth[i] = depth;
        self.normal[i] = normal;
        self.features[i * self.channels..(i + 1) * self.channels].copy_from_slice(features);
    }
}

/// Front-to-back order: by depth, ties by Gaussian index (so every path sorts identically).
fn by_depth(proj: &[Projected]) -> impl Fn(&usize, &usize) -> std::cmp::Ordering + '_ {
    |a, b| (proj[*a].depth, proj[*a].index).partial_cmp(&(proj[*b].depth, proj[*b].index)).expect("finite depths")
}

fn blank(cam: &Camera, channels: usize) -> Image {
    let (w, h) = (cam.width as usize, cam.height as usize);
    Image {
        width: w,
        height: h,
        rgb: vec![[0.0; 3]; w * h],
        alpha: vec![0.0; w * h],
        depth: vec![0.0; w * h],
        normal: vec![[0.0; 3]; w * h],
        features: vec![0.0; w * h * channels],
        channels,
    }
}

fn rotation_of(cam: &Camera, opts: &RenderOptions) -> Option<[[f64; 3]; 3]> {
    opts.normals_world.then(|| std::array::from_fn(|a| std::array::from_fn(|b| cam.camera_from_world[a][b])))
}

/// Projects every Gaussian (culled ones are dropped), with the backward pass's intermediates.
pub fn project_all_full(g: &Gaussians, cam: &Camera, opts: &RenderOptions) -> Vec<(Projected, Frame)> {
    (0..g.len()).into_par_iter().filter_map(|i| project_full(g, i, cam, opts.antialiased, opts.smooth)).collect()
}

/// Projects every Gaussian (culled ones are dropped).
pub fn project_all(g: &Gaussians, cam: &Camera, opts: &RenderOptions) -> Vec<Projected> {
    project_all_full(g, cam, opts).into_iter().map(|(p, _)| p).collect()
}

/// Per tile (row-major, `TILE` pixels square) the indices into `proj` of the Gaussians that can
/// touch it, sorted by (depth, index). In smooth mode every tile gets every Gaussian.
pub fn bin(proj: &[Projected], w: usize, h: usize, smooth: bool) -> (usize, Vec<Vec<usize>>) {
    let (tx, ty) = (w.div_ceil(TILE), h.div_ceil(TILE));
    let mut tiles: Vec<Vec<usize>> = vec![Vec::new(); tx * ty];
    for (pi, p) in proj.iter().enumerate() {
        let (x0, x1, y0, y1) = if smooth {
            (0.0, tx as f64 - 1.0, 0.0, ty as f64 - 1.0)
        } else {
            (
                ((p.mean[0] - p.radius) / TILE as f64).floor().max(0.0),
                ((p.mean[0] + p.radius) / TILE as f64).floor().min(tx as f64 - 1.0),
                ((p.mean[1] - p.radius) / TILE as f64).floor().max(0.0),
                ((p.mean[1] + p.radius) / TILE as f64).floor().min(ty as f64 - 1.0),
            )
        };
        if x1 < x0 || y1 < y0 {
            continue;
        }
        for yy in y0 as usize..=y1 as usize {
            for xx in x0 as usize..=x1 as usize {
                tiles[yy * tx + xx].push(pi);
            }
        }
    }
    tiles.par_iter_mut().for_each(|t| t.sort_by(by_depth(proj)));
    (tx, tiles)
}

/// The tiled renderer.
pub fn render(g: &Gaussians, cam: &Camera, feats: &Features, opts: &RenderOptions) -> Image {
    let proj = project_all(g, cam, opts);
    let mut img = blank(cam, feats.channels);
    let (w, h) = (img.width, img.height);
    let (tx, tiles) = bin(&proj, w, h, opts.smooth);
    let nrot = rotation_of(cam, opts);
    /// (pixel index, (rgb, alpha, depth, normal), features)
    type Pixel = (usize, ([f64; 3], f64, f64, [f64; 3]), Vec<f64>);
    let done: Vec<(usize, Vec<Pixel>)> = tiles
        .par_iter()
        .enumerate()
        .map(|(ti, order)| {
            let (bx, by) = ((ti % tx) * TILE, (ti / tx) * TILE);
            let hot = hot(&proj, order);
            let mut px = Vec::with_capacity(TILE * TILE);
            for y in by..(by + TILE).min(h) {
                for x in bx..(bx + TILE).min(w) {
                    let mut f = vec![0.0; feats.channels];
                    let out =
                        composite([x as f64 + 0.5, y as f64 + 0.5], order, &hot, &proj, feats, opts, &nrot, &mut f);
                    px.push((y * w + x, out, f));
                }
            }
            (ti, px)
        })
        .collect();
    for (_, px) in done {
        for (i, out, f) in px {
            img.set(i, out, &f);
        }
    }
    img
}

/// The reference: every pixel walks every Gaussian in global depth order (no tiles).
pub fn render_brute_force(g: &Gaussians, cam: &Camera, feats: &Features, opts: &RenderOptions) -> Image {
    let proj = project_all(g, cam, opts);
    let mut order: Vec<usize> = (0..proj.len()).collect();
    order.sort_by(by_depth(&proj));
    let mut img = blank(cam, feats.channels);
    let nrot = rotation_of(cam, opts);
    let hot = hot(&proj, &order);
    for y in 0..img.height {
        for x in 0..img.width {
            let i = y * img.width + x;
            let mut f = vec![0.0; feats.channels];
            let out = composite([x as f64 + 0.5, y as f64 + 0.5], &order, &hot, &proj, feats, opts, &nrot, &mut f);
            img.set(i, out, &f);
        }
    }
    img
}
