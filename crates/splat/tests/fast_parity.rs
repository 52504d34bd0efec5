//! The f32 CPU path (`splat::fast`) against the f64 reference (`raster`, `backward`): every
//! forward channel and every gradient, on random scenes (dense enough that pixels saturate and
//! alphas hit the 0.99 clamp, with features, antialiasing and world-frame normals) and on
//! degenerate ones (tiny, huge and very flat Gaussians, Gaussians at the near plane, bad
//! numbers, empty images). Tolerances (docs/cpu-f32.md):
//! - forward: per channel, mean |f32 - f64| <= 1e-5 x the channel's scale (its largest
//!   magnitude, at least 1) and max <= 2e-3 x scale (room for a pixel where a Gaussian's alpha
//!   sits at the 1/255 cut-off or the early stop and flips in f32; seen: mean <= 5e-7, max <= 8e-6);
//! - gradients: per parameter array, |f32 - f64|_2 <= 1e-4 |f64|_2 (seen <= 5.2e-6), and at most
//!   0.2% of entries off by more than 1e-3 of the array's largest magnitude (seen: none).
//!
//! A wrong formula (a missing term, a sign) moves these by orders of magnitude; `tolerances_bite`
//! checks that a small real change of the scene already breaks them.

mod common;

use common::{dense_scene, tilted_camera};

use splat::backward::{backward_into, Gradients, Upstream};
use splat::fast::{self, FastContext};
use splat::random::{random_gaussians, XorShift as Rng};
use splat::render::{render_into, render_with_context, Context, Features, Image, RenderOptions};
use splat::{Camera, Gaussians};

fn camera(w: u32, h: u32) -> Camera {
    let (wf, hf) = (w as f64, h as f64);
    tilted_camera(w, h, 0.86 * wf, 0.87 * wf, 0.503 * wf, 0.505 * hf)
}

struct Up {
    rgb: Vec<[f64; 3]>,
    alpha: Vec<f64>,
    depth: Vec<f64>,
    normal: Vec<[f64; 3]>,
    features: Vec<f64>,
}

impl Up {
    fn random(n_px: usize, k: usize, seed: u64) -> Up {
        let mut r = Rng(seed);
        let mut v = || r.range(-1.0, 1.0);
        Up {
            rgb: (0..n_px).map(|_| [v(), v(), v()]).collect(),
            alpha: (0..n_px).map(|_| v()).collect(),
            depth: (0..n_px).map(|_| 0.2 * v()).collect(),
            normal: (0..n_px).map(|_| [v(), v(), v()]).collect(),
            features: (0..n_px * k).map(|_| v()).collect(),
        }
    }

    fn get(&self) -> Upstream<'_> {
        Upstream {
            rgb: &self.rgb,
            alpha: &self.alpha,
            depth: &self.depth,
            normal: &self.normal,
            features: &self.features,
        }
    }
}

/// Channels of an image as named flat arrays.
fn channels(img: &Image) -> Vec<(&'static str, Vec<f64>)> {
    vec![
        ("rgb", img.rgb.iter().flatten().copied().collect()),
        ("alpha", img.alpha.clone()),
        ("depth", img.depth.clone()),
        ("normal", img.normal.iter().flatten().copied().collect()),
        ("features", img.features.clone()),
    ]
}

/// (mean, max) |a - b| per channel over the channel's scale (its largest magnitude, at least 1).
fn forward_errors(a: &Image, b: &Image) -> Vec<(&'static str, f64, f64)> {
    assert_eq!((a.width, a.height, a.channels), (b.width, b.height, b.channels));
    channels(a)
        .into_iter()
        .zip(channels(b))
        .map(|((name, x), (_, y))| {
            assert_eq!(x.len(), y.len(), "{name}");
            assert!(x.iter().all(|v| v.is_finite()), "{name}: non-finite f32 output");
            let scale = y.iter().fold(1.0f64, |m, v| m.max(v.abs()));
            let diffs: Vec<f64> = x.iter().zip(&y).map(|(p, q)| (p - q).abs() / scale).collect();
            let mean = diffs.iter().sum::<f64>() / diffs.len().max(1) as f64;
            (name, mean, diffs.iter().fold(0.0f64, |m, d| m.max(*d)))
        })
        .collect()
}

fn check_forward(what: &str, a: &Image, b: &Image) {
    for (name, mean, max) in forward_errors(a, b) {
        eprintln!("{what}: forward {name}: mean {mean:.2e}, max {max:.2e}");
        assert!(mean <= 1e-5 && max <= 2e-3, "{what}: {name}: mean {mean:.2e} max {max:.2e} (scaled)");
    }
}

fn fields(g: &Gradients) -> Vec<(&'static str, Vec<f64>)> {
    vec![
        ("means", g.means.iter().flatten().copied().collect()),
        ("log_scales", g.log_scales.iter().flatten().copied().collect()),
        ("rotations", g.rotations.iter().flatten().copied().collect()),
        ("opacity_logits", g.opacity_logits.clone()),
        ("sh", g.sh.clone()),
        ("features", g.features.clone()),
        ("mean2d_norm", g.mean2d_norm.clone()),
    ]
}

/// Per field: (relative L2 error, fraction of entries off by more than 1e-3 of the largest).
fn gradient_errors(a: &Gradients, b: &Gradients) -> Vec<(&'static str, f64, f64)> {
    fields(a)
        .into_iter()
        .zip(fields(b))
        .map(|((name, x), (_, y))| {
            assert_eq!(x.len(), y.len(), "{name}");
            assert!(x.iter().all(|v| v.is_finite()), "{name}: non-finite f32 gradient");
            let norm = y.iter().map(|v| v * v).sum::<f64>().sqrt();
            let err = x.iter().zip(&y).map(|(p, q)| (p - q) * (p - q)).sum::<f64>().sqrt();
            let big = y.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            let off = x.iter().zip(&y).filter(|(p, q)| (*p - *q).abs() > 1e-3 * big).count();
            let rel = if norm > 0.0 { err / norm } else { err };
            (name, rel, off as f64 / x.len().max(1) as f64)
        })
        .collect()
}

fn check_gradients(what: &str, a: &Gradients, b: &Gradients) {
    for (name, rel, off) in gradient_errors(a, b) {
        eprintln!("{what}: gradient {name}: relative L2 {rel:.2e}, entries off {off:.4}");
        assert!(rel <= 1e-4 && off <= 0.002, "{what}: {name}: relative L2 {rel:.2e}, {off:.4} of entries off");
    }
}

/// Renders and differentiates with both paths (buffers kept, as in training).
fn both(g: &Gaussians, cam: &Camera, f: &Features, opts: &RenderOptions, up: &Upstream) -> [(Image, Gradients); 2] {
    let (mut i64_, mut c64, mut g64) = (Image::default(), Context::default(), Gradients::default());
    render_into(g, cam, f, opts, &mut i64_, &mut c64);
    backward_into(g, cam, f, opts, &c64, up, &mut g64);
    let (mut i32_, mut c32, mut g32) = (Image::default(), FastContext::default(), Gradients::default());
    fast::render_into(g, cam, f, opts, &mut i32_, &mut c32);
    fast::backward_into(g, cam, f, opts, &c32, up, &mut g32);
    [(i32_, g32), (i64_, g64)]
}

#[test]
fn dense_random_scenes_match_the_reference() {
    let cam = camera(70, 45);
    let n_px = 70 * 45;
    for (seed, aa, world) in [(21u64, false, false), (22, true, true), (23, true, false)] {
        let g = dense_scene(900, seed);
        let fv: Vec<f64> = {
            let mut r = Rng(seed + 100);
            (0..g.len() * 3).map(|_| r.range(-1.0, 1.0)).collect()
        };
        let f = Features { values: &fv, channels: 3 };
        let opts = RenderOptions { background: [0.3, 0.5, 0.2], antialiased: aa, normals_world: world, smooth: false };
        let up = Up::random(n_px, 3, seed + 200);
        let [(i32_, g32), (i64_, g64)] = both(&g, &cam, &f, &opts, &up.get());
        let saturated = i64_.alpha.iter().filter(|a| **a > 0.998).count();
        assert!(saturated > n_px / 10, "seed {seed}: only {saturated} saturated pixels");
        let what = format!("dense seed {seed} aa {aa} world {world}");
        check_forward(&what, &i32_, &i64_);
        check_gradients(&what, &g32, &g64);
    }
}

#[test]
fn street_sized_random_scene_matches_the_reference() {
    let cam = Camera::at_origin(240, 160, 200.0);
    let g = random_gaussians(6000, &cam, 3, 11);
    let up = Up::random(240 * 160, 0, 5);
    let opts = RenderOptions { background: [0.1, 0.2, 0.3], ..Default::default() };
    let [(i32_, g32), (i64_, g64)] = both(&g, &cam, &Features::default(), &opts, &up.get());
    check_forward("random 6000", &i32_, &i64_);
    check_gradients("random 6000", &g32, &g64);
}

/// Tiny, huge and very flat Gaussians, Gaussians just past the near plane, behind the camera and
/// with bad numbers, mixed into an ordinary scene: no panic, no NaN, the same image and gradients.
#[test]
fn degenerate_scenes_match_the_reference() {
    let cam = camera(64, 48);
    let mut g = dense_scene(300, 77);
    let n = g.len();
    let mut r = Rng(5);
    for i in 0..n {
        match i % 10 {
            0 => g.log_scales[i] = [-12.0, -12.0, -12.0], // tiny
            1 => g.log_scales[i] = [1.5, 1.2, 1.0],       // huge
            2 => g.log_scales[i] = [-1.5, -1.6, -11.0],   // very flat
            3 => {
                g.means[i] =
                    world_of(&cam, [r.range(-2e-3, 2e-3), r.range(-2e-3, 2e-3), 0.01 * (1.0 + r.range(1e-6, 0.5))])
            } // just past the near plane
            4 => g.means[i][2] = -g.means[i][2],          // behind
            5 => g.opacity_logits[i] = 12.0,              // alpha clamped
            _ => {}
        }
    }
    // A few bad numbers (culled by both paths).
    g.means[13] = [f64::NAN, 0.0, 3.0];
    g.log_scales[23] = [f64::INFINITY, 0.0, 0.0];
    g.rotations[33] = [0.0; 4];
    g.opacity_logits[43] = f64::NAN;
    // Extreme but finite numbers: far off, overflowing and underflowing scales, saturated logits.
    g.means[53] = [1e20, -1e20, 5.0];
    g.log_scales[63] = [80.0, 80.0, 80.0];
    g.log_scales[73] = [-80.0, -80.0, -80.0];
    g.opacity_logits[83] = 1e30;
    g.opacity_logits[93] = -1e30;
    g.rotations[103] = [1e-30, 0.0, 0.0, 1e-30];
    // A NaN log-scale behind a larger one (a max over the three would hide it), a scale of 0.
    g.log_scales[113] = [0.5, f64::NAN, -1.0];
    g.log_scales[123] = [-1.0, 0.0, f64::NAN];
    g.log_scales[133] = [f64::NEG_INFINITY, -2.0, -2.0];
    let up = Up::random(64 * 48, 0, 9);
    // Every kind but the ones behind is drawn by the reference (the near-plane ones included),
    // so each is compared.
    let (_, ctx) = render_with_context(&g, &cam, &Features::default(), &RenderOptions::default());
    for kind in 0..6 {
        let drawn = ctx.proj.iter().any(|p| p.index % 10 == kind);
        assert_eq!(drawn, kind != 4, "kind {kind} drawn: {drawn}");
    }
    for aa in [false, true] {
        let opts = RenderOptions { background: [0.2, 0.2, 0.2], antialiased: aa, ..Default::default() };
        // The same Gaussians drawn: none of the bad ones.
        let (_, c64) = render_with_context(&g, &cam, &Features::default(), &opts);
        let (_, c32) = fast::render_with_context(&g, &cam, &Features::default(), &opts);
        let mut d64: Vec<usize> = c64.proj.iter().map(|p| p.index).collect();
        let mut d32 = Vec::new();
        c32.for_each_drawn(&mut |i, _| d32.push(i));
        d64.sort_unstable();
        // The one difference: 63's 5e34 m scales make its conic underflow in f32, so only the
        // reference draws it (docs/cpu-f32.md).
        assert!(d64.contains(&63) && !d32.contains(&63), "aa {aa}: Gaussian 63");
        d64.retain(|i| *i != 63);
        assert_eq!(d32, d64, "aa {aa}: the drawn Gaussians");
        assert!(![13, 23, 43, 113, 123].iter().any(|i| d32.contains(i)), "a bad Gaussian drawn");
        let [(i32_, g32), (i64_, g64)] = both(&g, &cam, &Features::default(), &opts, &up.get());
        check_forward(&format!("degenerate aa {aa}"), &i32_, &i64_);
        check_gradients(&format!("degenerate aa {aa}"), &g32, &g64);
    }
}

/// The world point at camera point `p`: `R^T (p - t)`.
fn world_of(cam: &Camera, p: [f64; 3]) -> [f64; 3] {
    let m = &cam.camera_from_world;
    let d = [p[0] - m[0][3], p[1] - m[1][3], p[2] - m[2][3]];
    std::array::from_fn(|c| (0..3).map(|r| m[r][c] * d[r]).sum())
}

#[test]
fn empty_images_and_empty_models() {
    let cam = camera(40, 30);
    let up = Up::random(40 * 30, 0, 3);
    let opts = RenderOptions { background: [0.25, 0.5, 0.75], ..Default::default() };
    // No Gaussians; Gaussians all behind or outside the view.
    let mut away = dense_scene(50, 4);
    away.means.iter_mut().for_each(|m| m[0] += 1e3);
    for g in [dense_scene(0, 1), away] {
        let [(i32_, g32), (i64_, g64)] = both(&g, &cam, &Features::default(), &opts, &up.get());
        assert_eq!(i32_, i64_, "an empty image is the background exactly");
        assert_eq!(g32, g64, "no gradients");
        assert!(i32_.rgb.iter().all(|c| *c == [0.25, 0.5, 0.75]));
    }
}

#[test]
fn deterministic_and_buffers_reused() {
    let cam = camera(70, 45);
    let g = dense_scene(700, 8);
    let up = Up::random(70 * 45, 0, 1);
    let opts = RenderOptions::default();
    let (mut img, mut ctx, mut grads) = (Image::default(), FastContext::default(), Gradients::default());
    // A bigger scene first, so the buffers hold stale data of another size.
    let other = dense_scene(1500, 9);
    let cam2 = camera(90, 61);
    let up2 = Up::random(90 * 61, 0, 2);
    fast::render_into(&other, &cam2, &Features::default(), &opts, &mut img, &mut ctx);
    fast::backward_into(&other, &cam2, &Features::default(), &opts, &ctx, &up2.get(), &mut grads);
    fast::render_into(&g, &cam, &Features::default(), &opts, &mut img, &mut ctx);
    fast::backward_into(&g, &cam, &Features::default(), &opts, &ctx, &up.get(), &mut grads);
    let (fresh_img, fresh_ctx) = fast::render_with_context(&g, &cam, &Features::default(), &opts);
    let fresh = fast::render_backward(&g, &cam, &Features::default(), &opts, &up.get());
    assert_eq!(img, fresh_img, "reused buffers give the fresh image bit for bit");
    assert_eq!(grads, fresh, "and the fresh gradients");
    assert_eq!(ctx.final_t_and_last(), fresh_ctx.final_t_and_last());
}

/// The same bits with one thread or two, and with the AVX2 or the baseline (SSE2) kernels: no
/// result depends on scheduling or on the machine's vector width.
#[test]
fn independent_of_threads_and_vector_width() {
    let cam = camera(70, 45);
    let g = dense_scene(900, 31);
    let fv: Vec<f64> = (0..g.len() * 2).map(|i| (i % 7) as f64 * 0.1).collect();
    let f = Features { values: &fv, channels: 2 };
    let up = Up::random(70 * 45, 2, 12);
    let opts = RenderOptions { antialiased: true, ..Default::default() };
    let run = || {
        let (img, ctx) = fast::render_with_context(&g, &cam, &f, &opts);
        let mut grads = Gradients::default();
        fast::backward_into(&g, &cam, &f, &opts, &ctx, &up.get(), &mut grads);
        (img, grads)
    };
    let two = run();
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(run);
    assert_eq!(one, two, "one thread vs the pool");
    fast::force_baseline(true);
    let baseline = run();
    fast::force_baseline(false);
    assert_eq!(baseline, two, "baseline kernels vs AVX2");
}

/// The smooth test mode runs the f64 reference inside the fast context: identical results.
#[test]
fn smooth_mode_is_the_reference() {
    let cam = camera(30, 20);
    let g = dense_scene(40, 3);
    let up = Up::random(30 * 20, 0, 4);
    let opts = RenderOptions { smooth: true, ..Default::default() };
    let [(i32_, g32), (i64_, g64)] = both(&g, &cam, &Features::default(), &opts, &up.get());
    assert_eq!(i32_, i64_);
    assert_eq!(g32, g64);
    let (img, _) = render_with_context(&g, &cam, &Features::default(), &opts);
    assert_eq!(img, i64_);
}

/// The tolerances are tight enough to catch a small real difference: the reference against
/// itself with one opacity in ten nudged by 0.05 in logit fails them.
#[test]
fn tolerances_bite() {
    let cam = camera(70, 45);
    let g = dense_scene(900, 21);
    let mut nudged = g.clone();
    nudged.opacity_logits.iter_mut().step_by(10).for_each(|v| *v += 0.05);
    let up = Up::random(70 * 45, 0, 6);
    let opts = RenderOptions::default();
    let [_, (a_img, a)] = both(&g, &cam, &Features::default(), &opts, &up.get());
    let [_, (b_img, b)] = both(&nudged, &cam, &Features::default(), &opts, &up.get());
    let fwd_fails = forward_errors(&b_img, &a_img).iter().any(|(_, mean, max)| *mean > 1e-5 || *max > 2e-3);
    let grad_fails = gradient_errors(&b, &a).iter().filter(|(_, rel, off)| *rel > 1e-4 || *off > 0.002).count();
    assert!(fwd_fails, "a 0.05 logit change passes the forward tolerance");
    assert!(grad_fails >= 4, "a 0.05 logit change passes the gradient tolerance on {} arrays", 7 - grad_fails);
}
