//! The tiled forward rasterizer (rayon over 16x16 tiles) and the context it leaves for the
//! backward pass.
//!
//! Within a tile the loop is Gaussian-major: Gaussians in depth order, and for each only the
//! tile pixels inside its alpha >= 1/255 ellipse (`tiles::spans`), each pixel
//! keeping its own transmittance. Every pixel still sees its Gaussians front to back with the
//! same arithmetic as the per-pixel reference (`render_brute_force`), so the two agree exactly,
//! but a Gaussian costs only the pixels it covers rather than a test at every pixel of every
//! tile it touches. A pixel that saturates (T would drop below 1e-4) is marked done; a tile stops
//! when all its pixels are done.
//!
//! Like gsplat, the forward pass keeps per pixel the final transmittance and the number of the
//! tile's Gaussians it walked (`last`), so the backward pass can run back to front without
//! storing per-pixel lists.

use crate::camera::Camera;
use crate::forward::{normal_rotation, output_normal, project_sorted_into, Features, Image, PixelSum, RenderOptions};
use crate::gaussians::Gaussians;
use crate::project::Projected;
use crate::tiles::{alpha_at, bin_into, spans, Hot, Tiles, TILE, T_MIN};
use rayon::prelude::*;

/// What the forward pass leaves for the backward pass. Keep one between iterations and render
/// with [`render_into`] so its memory is reused.
#[derive(Clone, Debug, Default)]
pub struct Context {
    /// Projected Gaussians, front to back, and their inner-loop data.
    pub proj: Vec<Projected>,
    pub hot: Vec<Hot>,
    pub tiles: Tiles,
    /// Per pixel: the transmittance after its last contribution...
    pub final_t: Vec<f64>,
    /// ...and how many of its tile's Gaussians (in order) it walked before stopping.
    pub last: Vec<u32>,
    /// One projection slot per Gaussian (the parallel projection's output before compaction).
    scratch: Vec<Option<Projected>>,
}

/// One tile's results (buffers indexed `(y - y0) * TILE + (x - x0)`).
struct TileOut {
    sum: Vec<PixelSum>,
    feat: Vec<f64>,
    t: Vec<f64>,
    last: Vec<u32>,
}

fn tile_forward(
    ctx: &Context,
    ti: usize,
    feats: &Features,
    opts: &RenderOptions,
    nrot: &Option<[[f64; 3]; 3]>,
) -> TileOut {
    let (k, n) = (feats.channels, TILE * TILE);
    let rect = ctx.tiles.rect(ti);
    let mut out =
        TileOut { sum: vec![PixelSum::default(); n], feat: vec![0.0; n * k], t: vec![1.0; n], last: vec![0; n] };
    let mut done = vec![false; n];
    let (live, mut n_done) = (rect.w * rect.h, 0);
    for (slot, &pi) in ctx.tiles.lists[ti].iter().enumerate() {
        let (g, h) = (&ctx.proj[pi as usize], &ctx.hot[pi as usize]);
        let normal = output_normal(g, nrot);
        let fv = feats.of(g.index);
        for sp in spans(h, rect, opts.smooth) {
            let (qy, row) = (sp.y as f64 + 0.5, (sp.y - rect.y0) * TILE);
            for x in sp.x0..sp.x1 {
                let p = row + x - rect.x0;
                if done[p] {
                    continue;
                }
                let Some((alpha, _, _)) = alpha_at(h, [x as f64 + 0.5, qy], opts.smooth) else { continue };
                let t = out.t[p];
                let next = t * (1.0 - alpha);
                if !opts.smooth && next < T_MIN {
                    done[p] = true;
                    n_done += 1;
                    continue;
                }
                out.sum[p].add(alpha * t, g, &normal, fv, &mut out.feat[p * k..(p + 1) * k]);
                out.t[p] = next;
                out.last[p] = slot as u32 + 1;
            }
        }
        if n_done == live {
            break;
        }
    }
    out
}

/// The tiled renderer.
pub fn render(g: &Gaussians, cam: &Camera, feats: &Features, opts: &RenderOptions) -> Image {
    render_with_context(g, cam, feats, opts).0
}

/// The tiled renderer, also returning what `backward::backward` needs.
pub fn render_with_context(g: &Gaussians, cam: &Camera, feats: &Features, opts: &RenderOptions) -> (Image, Context) {
    let (mut img, mut ctx) = (Image::default(), Context::default());
    render_into(g, cam, feats, opts, &mut img, &mut ctx);
    (img, ctx)
}

/// [`render_with_context`] into an existing image and context, reusing their memory (a training
/// loop keeps both; fresh allocations of this size cost page faults every iteration).
pub fn render_into(
    g: &Gaussians,
    cam: &Camera,
    feats: &Features,
    opts: &RenderOptions,
    img: &mut Image,
    ctx: &mut Context,
) {
    project_sorted_into(g, cam, opts, &mut ctx.proj, &mut ctx.scratch);
    ctx.hot.clear();
    ctx.hot.extend(ctx.proj.iter().map(Hot::of));
    let (w, h) = (cam.width as usize, cam.height as usize);
    bin_into(&ctx.proj, w, h, opts.smooth, &mut ctx.tiles);
    let nrot = normal_rotation(cam, opts);
    let k = feats.channels;
    let outs: Vec<TileOut> =
        (0..ctx.tiles.lists.len()).into_par_iter().map(|ti| tile_forward(ctx, ti, feats, opts, &nrot)).collect();
    img.reset(cam, k);
    ctx.final_t.clear();
    ctx.final_t.resize(w * h, 1.0);
    ctx.last.clear();
    ctx.last.resize(w * h, 0);
    for (ti, o) in outs.iter().enumerate() {
        ctx.tiles.rect(ti).for_each(w, |p, pix| {
            img.set(pix, &o.sum[p], o.t[p], opts.background, &o.feat[p * k..(p + 1) * k]);
            ctx.final_t[pix] = o.t[p];
            ctx.last[pix] = o.last[p];
        });
    }
}
