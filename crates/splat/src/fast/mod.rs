//! The f32 CPU rasterizer: the same renderer and gradients as the f64 reference (`raster`,
//! `backward`), in single precision with SIMD tile kernels, for training and rendering on the
//! CPU where speed matters. The reference stays the definition; `tests/fast_parity.rs` holds
//! this path to it within documented tolerances (docs/cpu-f32.md).
//!
//! Pipeline per call, every buffer kept in a [`FastContext`] between calls (no allocation per
//! iteration once sizes settle, except `k > 0` feature scratch in the backward pass):
//! project (`project`, rayon over Gaussians) -> sort by depth (f32 depth bits, ties by index,
//! one `u64` key) -> bin into 16x16 tiles (`tiles::bin_into`'s rule) -> forward per tile
//! (`forward`, rayon over tiles, tile-major output) -> image rows in f64 (rayon over rows);
//! backward per tile (`backward`, rayon) -> tiles merged in list order into f64 sums (one fixed
//! order, so results are deterministic; rayon over ranges of model indices, each walking every
//! list) -> chain rule per Gaussian (`chain`, rayon, each Gaussian owns its output slots and
//! zeroes them first, so no serial clear of the whole model precedes it).
//!
//! Semantics are the reference's: alpha cut-off 1/255, clamp 0.99, early stop at T < 1e-4,
//! depth, normals (camera or world frame), feature channels, antialiased opacity, and
//! `mean2d_norm` for densification. The `smooth` test mode has no f32 version: with
//! `opts.smooth` these functions run the f64 reference (kept inside the context).

mod backward;
mod chain;
mod forward;
pub(crate) mod lanes;
pub mod project;
mod tile;

use crate::backward::{backward_into as backward_f64, Gradients, Upstream};
use crate::camera::Camera;
use crate::forward::{Features, Image, RenderOptions};
use crate::gaussians::Gaussians;
use crate::raster::{render_into as render_f64, Context};
use crate::tiles::{Tiles, TILE};
use backward::{tile_backward, TileBack, G_CH};
use chain::{gaussian_backward32, Out, Screen};
use forward::{tile_forward, TileIn, BASE_CH, CH_T};
use project::{project32, CamConst, Frame32, Hot32};
use rayon::prelude::*;
use std::sync::Mutex;
use tile::NPX;

pub use lanes::{exp as exp_f32, force_baseline};

/// Everything one render leaves for its backward pass, and the buffers both reuse.
#[derive(Default)]
pub struct FastContext {
    /// Per model index: the projected Gaussian, its chain-rule frame and whether it is drawn
    /// (entries of culled Gaussians are stale). Indexed by model index so the projection writes
    /// and the chain rule reads them in order; tile lists hold model indices.
    hot: Vec<Hot32>,
    frames: Vec<Frame32>,
    drawn: Vec<bool>,
    /// Per model index, the tiles its extent box overlaps (`tile_box`).
    boxes: Vec<[u16; 4]>,
    /// The drawn Gaussians' model indices, front to back.
    pub index: Vec<u32>,
    tiles: Tiles,
    /// Per tile, `(BASE_CH + k) * NPX` forward outputs (channel-major; final T in `CH_T`).
    tile_out: Vec<f32>,
    /// Per tile, `NPX` walk lengths.
    tile_last: Vec<u32>,
    channels: usize,
    antialiased: bool,
    nrot: Option<[[f32; 3]; 3]>,
    background: [f32; 3],
    /// Sort keys: depth bits, then the index.
    keys: Vec<u64>,
    /// The f64 reference's context, used in `smooth` mode.
    reference: Option<Box<Context>>,
    back: Mutex<BackScratch>,
}

#[derive(Default)]
struct BackScratch {
    per_tile: Vec<(Vec<f32>, Vec<f32>, usize)>,
    acc: Vec<f64>,
}

impl FastContext {
    /// Calls `f(index, half_extent_px)` for every Gaussian the last render drew, in index order
    /// (the reference's is depth order; each Gaussian is reported once either way).
    pub fn for_each_drawn(&self, f: &mut dyn FnMut(usize, f64)) {
        match &self.reference {
            Some(r) => r.proj.iter().for_each(|p| f(p.index, p.extent[0].max(p.extent[1]))),
            None => {
                for (i, (h, d)) in self.hot.iter().zip(&self.drawn).enumerate() {
                    if *d {
                        f(i, h.extent[0].max(h.extent[1]) as f64);
                    }
                }
            }
        }
    }

    /// Per pixel (row-major), the final transmittance and walk length of the last render.
    pub fn final_t_and_last(&self) -> (Vec<f32>, Vec<u32>) {
        let (w, h) = (self.tiles.width, self.tiles.height);
        let k = self.channels;
        let (mut t, mut last) = (vec![1.0; w * h], vec![0; w * h]);
        if self.reference.is_some() {
            return (t, last);
        }
        for pix in 0..w * h {
            let (ti, p) = tile_pixel(self.tiles.tx, w, pix);
            t[pix] = self.tile_out[ti * (BASE_CH + k) * NPX + CH_T * NPX + p];
            last[pix] = self.tile_last[ti * NPX + p];
        }
        (t, last)
    }
}

/// Tile and tile buffer index (`tile::slot`) of image pixel `pix`.
#[inline]
fn tile_pixel(tx: usize, width: usize, pix: usize) -> (usize, usize) {
    let (x, y) = (pix % width, pix / width);
    ((y / TILE) * tx + x / TILE, tile::slot(x % TILE, y % TILE))
}

fn rot32(cam: &Camera) -> [[f32; 3]; 3] {
    std::array::from_fn(|a| std::array::from_fn(|b| cam.camera_from_world[a][b] as f32))
}

/// Projects, sorts and bins into `ctx`.
fn prepare(g: &Gaussians, cam: &Camera, opts: &RenderOptions, ctx: &mut FastContext) {
    let cc = CamConst::of(cam);
    let n = g.len();
    ctx.hot.resize(n, Hot32::default());
    ctx.frames.resize(n, Frame32::default());
    ctx.drawn.resize(n, false);
    ctx.boxes.resize(n, [1, 0, 1, 0]);
    let (tx, ty) = ((cam.width as usize).div_ceil(TILE), (cam.height as usize).div_ceil(TILE));
    (ctx.hot.par_iter_mut(), ctx.frames.par_iter_mut(), ctx.drawn.par_iter_mut(), ctx.boxes.par_iter_mut())
        .into_par_iter()
        .enumerate()
        .for_each(|(i, (h, f, d, b))| {
            *d = match project32(g, i, cam, &cc, opts.antialiased) {
                Some((hh, ff)) => {
                    (*h, *f, *b) = (hh, ff, tile_box(&hh, tx, ty));
                    true
                }
                None => false,
            }
        });
    ctx.keys.clear();
    // Depth > near > 0, so its f32 bits order like the depth; the low half breaks ties by index.
    let hot = &ctx.hot;
    ctx.keys.extend(
        ctx.drawn
            .iter()
            .enumerate()
            .filter(|(_, d)| **d)
            .map(|(i, _)| ((hot[i].depth.to_bits() as u64) << 32) | i as u64),
    );
    ctx.keys.par_sort_unstable();
    ctx.index.clear();
    ctx.index.extend(ctx.keys.iter().map(|k| (*k & 0xffff_ffff) as u32));
    bin32(&ctx.boxes, &ctx.index, cam.width as usize, cam.height as usize, &mut ctx.tiles);
}

/// The tiles `[x0, x1, y0, y1]` (inclusive) the extent box of `h` overlaps, by
/// `tiles::bin_into`'s rule; `x1 < x0` when none.
fn tile_box(h: &Hot32, tx: usize, ty: usize) -> [u16; 4] {
    let t = TILE as f32;
    let x0 = ((h.mean[0] - h.extent[0]) / t).floor().max(0.0);
    let x1 = ((h.mean[0] + h.extent[0]) / t).floor().min(tx as f32 - 1.0);
    let y0 = ((h.mean[1] - h.extent[1]) / t).floor().max(0.0);
    let y1 = ((h.mean[1] + h.extent[1]) / t).floor().min(ty as f32 - 1.0);
    if x1 >= x0 && y1 >= y0 {
        [x0 as u16, x1 as u16, y0 as u16, y1 as u16]
    } else {
        [1, 0, 1, 0]
    }
}

/// Bins the drawn Gaussians (`order`: model indices front to back) into every tile their box
/// (`boxes`, from [`tile_box`]) overlaps, so each tile's list is in depth order.
fn bin32(boxes: &[[u16; 4]], order: &[u32], width: usize, height: usize, tiles: &mut Tiles) {
    let (tx, ty) = (width.div_ceil(TILE), height.div_ceil(TILE));
    tiles.lists.resize_with(tx * ty, Vec::new);
    tiles.lists.iter_mut().for_each(Vec::clear);
    (tiles.tx, tiles.width, tiles.height) = (tx, width, height);
    for &pi in order {
        let [x0, x1, y0, y1] = boxes[pi as usize].map(usize::from);
        for yy in y0..=y1 {
            for xx in x0..=x1 {
                tiles.lists[yy * tx + xx].push(pi);
            }
        }
    }
}

/// Renders `g` into `img` (f64 channels, as the reference's `render_into`), keeping in `ctx`
/// what [`backward_into`] needs. Reuses the memory of both.
pub fn render_into(
    g: &Gaussians,
    cam: &Camera,
    feats: &Features,
    opts: &RenderOptions,
    img: &mut Image,
    ctx: &mut FastContext,
) {
    if opts.smooth {
        let r = ctx.reference.get_or_insert_with(Default::default);
        render_f64(g, cam, feats, opts, img, r);
        return;
    }
    ctx.reference = None;
    prepare(g, cam, opts, ctx);
    let k = feats.channels;
    (ctx.channels, ctx.antialiased) = (k, opts.antialiased);
    ctx.background = opts.background.map(|v| v as f32);
    let cam_rot = rot32(cam);
    ctx.nrot = opts.normals_world.then_some(cam_rot);
    // Camera-to-world for the forward's output normals: the transpose.
    let out_rot = opts.normals_world.then(|| std::array::from_fn(|a| std::array::from_fn(|b| cam_rot[b][a])));
    let n_tiles = ctx.tiles.lists.len();
    let stride = (BASE_CH + k) * NPX;
    ctx.tile_out.resize(n_tiles * stride, 0.0);
    ctx.tile_last.resize(n_tiles * NPX, 0);
    let (tiles, hot) = (&ctx.tiles, &ctx.hot);
    ctx.tile_out.par_chunks_mut(stride).zip(ctx.tile_last.par_chunks_mut(NPX)).enumerate().for_each(
        |(ti, (out, last))| {
            let tin =
                TileIn { rect: tiles.rect(ti), list: &tiles.lists[ti], hot, feats: feats.values, k, nrot: out_rot };
            tile_forward(&tin, out, last);
        },
    );
    img.reset(cam, k);
    let (w, tx, bg) = (cam.width as usize, ctx.tiles.tx, opts.background);
    let tile_out = &ctx.tile_out;
    if w == 0 {
        return;
    }
    (img.rgb.par_chunks_mut(w), img.alpha.par_chunks_mut(w), img.depth.par_chunks_mut(w), img.normal.par_chunks_mut(w))
        .into_par_iter()
        .enumerate()
        .for_each(|(y, (rgb, alpha, depth, normal))| {
            for x in 0..w {
                let (ti, p) = tile_pixel(tx, w, y * w + x);
                let o = &tile_out[ti * stride..(ti + 1) * stride];
                let t = o[CH_T * NPX + p] as f64;
                rgb[x] = std::array::from_fn(|c| o[c * NPX + p] as f64 + t * bg[c]);
                alpha[x] = 1.0 - t;
                depth[x] = o[3 * NPX + p] as f64;
                normal[x] = std::array::from_fn(|c| o[(4 + c) * NPX + p] as f64);
            }
        });
    if k > 0 {
        img.features.par_chunks_mut(w * k).enumerate().for_each(|(y, row)| {
            for x in 0..w {
                let (ti, p) = tile_pixel(tx, w, y * w + x);
                for c in 0..k {
                    row[x * k + c] = tile_out[ti * stride + (BASE_CH + c) * NPX + p] as f64;
                }
            }
        });
    }
}

/// Gradients of `sum(upstream * outputs)` for the render that produced `ctx` (same inputs), into
/// `out` (overwritten, memory reused).
pub fn backward_into(
    g: &Gaussians,
    cam: &Camera,
    feats: &Features,
    opts: &RenderOptions,
    ctx: &FastContext,
    up: &Upstream,
    out: &mut Gradients,
) {
    if let Some(r) = &ctx.reference {
        backward_f64(g, cam, feats, opts, r, up, out);
        return;
    }
    let k = ctx.channels;
    let mut guard = ctx.back.lock().unwrap_or_else(|p| p.into_inner());
    let bs = &mut *guard;
    let n_tiles = ctx.tiles.lists.len();
    let stride = (BASE_CH + k) * NPX;
    bs.per_tile.resize_with(n_tiles, Default::default);
    let width = cam.width as usize;
    bs.per_tile.par_iter_mut().enumerate().for_each(|(ti, (sums, fscratch, walked))| {
        let tb = TileBack {
            rect: ctx.tiles.rect(ti),
            list: &ctx.tiles.lists[ti],
            hot: &ctx.hot,
            feats: feats.values,
            k,
            fwd: &ctx.tile_out[ti * stride..(ti + 1) * stride],
            last: &ctx.tile_last[ti * NPX..(ti + 1) * NPX],
            up,
            width,
            nrot: ctx.nrot,
            background: ctx.background,
        };
        *walked = tile_backward(&tb, sums, fscratch);
    });
    // Merge the tiles in f64 by model index: each thread owns a range of model indices and walks
    // every tile's list, so each Gaussian adds its tiles in list order (one fixed order, the same
    // for any thread count).
    let gs = G_CH + k;
    let n = g.len();
    let BackScratch { per_tile, acc } = bs;
    acc.resize(n * gs, 0.0);
    let per = n.div_ceil(rayon::current_num_threads().max(1)).max(1);
    let lists = &ctx.tiles.lists;
    let drawn = &ctx.drawn;
    acc.par_chunks_mut(per * gs).enumerate().for_each(|(c, acc)| {
        let (lo, hi) = (c * per, c * per + acc.len() / gs);
        // Only drawn Gaussians are in a list, and only their sums are read below: zero those
        // (a view draws a tenth to a fifth of the model).
        for (i, row) in (lo..hi).zip(acc.chunks_exact_mut(gs)) {
            if drawn[i] {
                row.fill(0.0);
            }
        }
        for (list, (sums, _, walked)) in lists.iter().zip(per_tile.iter()) {
            for (slot, &pi) in list.iter().enumerate().take(*walked) {
                let pi = pi as usize;
                if pi < lo || pi >= hi {
                    continue;
                }
                let (dst, src) = (&mut acc[(pi - lo) * gs..(pi - lo + 1) * gs], &sums[slot * gs..(slot + 1) * gs]);
                for (d, s) in dst.iter_mut().zip(src) {
                    *d += *s as f64;
                }
            }
        }
    });
    // Every row is written below (zeroed, then the drawn ones accumulate), in parallel: no
    // serial clear of the whole model first.
    out.resize_for(g, k);
    let cc = CamConst::of(cam);
    let kc = g.coeffs() * 3;
    let acc = &*acc;
    (
        out.means.par_iter_mut(),
        out.log_scales.par_iter_mut(),
        out.rotations.par_iter_mut(),
        out.opacity_logits.par_iter_mut(),
        out.sh.par_chunks_mut(kc.max(1)),
        out.mean2d_norm.par_iter_mut(),
    )
        .into_par_iter()
        .enumerate()
        .for_each(|(i, (mean, log_scale, rotation, opacity_logit, sh, mean2d_norm))| {
            (*mean, *log_scale, *rotation, *opacity_logit, *mean2d_norm) = ([0.0; 3], [0.0; 3], [0.0; 4], 0.0, 0.0);
            sh.fill(0.0);
            // Gaussians not drawn have stale sums and frames, never read.
            if !ctx.drawn[i] {
                return;
            }
            let a = &acc[i * gs..i * gs + G_CH];
            if a.iter().all(|v| *v == 0.0) {
                return;
            }
            let o = Out { mean, log_scale, rotation, opacity_logit, sh, mean2d_norm };
            gaussian_backward32(g, i, &cc, ctx.antialiased, &ctx.hot[i], &ctx.frames[i], &Screen::of(a), o);
        });
    if k > 0 {
        out.features.fill(0.0);
        for &i in &ctx.index {
            let i = i as usize;
            out.features[i * k..(i + 1) * k].copy_from_slice(&acc[i * gs + G_CH..(i + 1) * gs]);
        }
    }
}

/// Renders into a fresh image and context.
pub fn render_with_context(
    g: &Gaussians,
    cam: &Camera,
    feats: &Features,
    opts: &RenderOptions,
) -> (Image, FastContext) {
    let (mut img, mut ctx) = (Image::default(), FastContext::default());
    render_into(g, cam, feats, opts, &mut img, &mut ctx);
    (img, ctx)
}

/// Renders, then [`backward_into`], into fresh gradients.
pub fn render_backward(
    g: &Gaussians,
    cam: &Camera,
    feats: &Features,
    opts: &RenderOptions,
    up: &Upstream,
) -> Gradients {
    let (_, ctx) = render_with_context(g, cam, feats, opts);
    let mut out = Gradients::default();
    backward_into(g, cam, feats, opts, &ctx, up, &mut out);
    out
}
