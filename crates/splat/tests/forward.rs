//! The tiled forward renderer against the per-pixel brute-force reference on random scenes,
//! a single Gaussian checked by hand, and degenerate inputs that must neither panic nor write NaN.

use splat::render::{render, render_brute_force, Features, Image, RenderOptions};
use splat::{Camera, Gaussians};

use splat::random::XorShift as Rng;

fn camera(w: u32, h: u32) -> Camera {
    Camera { far: 100.0, ..Camera::at_origin(w, h, 0.9 * w as f64) }
}

fn scene(n: usize, degree: usize, seed: u64) -> Gaussians {
    let mut r = Rng(seed);
    let k = (degree + 1) * (degree + 1);
    Gaussians {
        means: (0..n).map(|_| [r.range(-1.5, 1.5), r.range(-1.0, 1.0), r.range(2.0, 6.0)]).collect(),
        log_scales: (0..n).map(|_| [r.range(-3.0, -1.0), r.range(-3.0, -1.0), r.range(-4.0, -1.5)]).collect(),
        rotations: (0..n)
            .map(|_| [r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0)])
            .collect(),
        opacity_logits: (0..n).map(|_| r.range(-2.0, 3.0)).collect(),
        sh_degree: degree,
        sh: (0..n * k * 3).map(|_| r.range(-0.5, 0.5)).collect(),
    }
}

fn max_diff(a: &Image, b: &Image) -> f64 {
    let mut m: f64 = 0.0;
    for i in 0..a.alpha.len() {
        for c in 0..3 {
            m = m.max((a.rgb[i][c] - b.rgb[i][c]).abs()).max((a.normal[i][c] - b.normal[i][c]).abs());
        }
        m = m.max((a.alpha[i] - b.alpha[i]).abs()).max((a.depth[i] - b.depth[i]).abs());
    }
    for (x, y) in a.features.iter().zip(&b.features) {
        m = m.max((x - y).abs());
    }
    m
}

#[test]
fn tiled_equals_brute_force() {
    for (seed, degree, aa, world) in
        [(1, 0, false, false), (2, 1, true, false), (3, 3, false, true), (4, 2, true, true)]
    {
        let g = scene(300, degree, seed);
        let cam = camera(80, 56);
        let feats: Vec<f64> = (0..g.len() * 2).map(|i| (i % 7) as f64 / 7.0).collect();
        let f = Features { values: &feats, channels: 2 };
        let opts = RenderOptions { background: [0.2, 0.3, 0.4], antialiased: aa, normals_world: world, smooth: false };
        let a = render(&g, &cam, &f, &opts);
        let b = render_brute_force(&g, &cam, &f, &opts);
        let d = max_diff(&a, &b);
        assert!(d < 1e-12, "seed {seed}: tiled and brute force differ by {d}");
        let covered = a.alpha.iter().filter(|v| **v > 0.1).count();
        assert!(covered > a.alpha.len() / 4, "seed {seed}: the scene covers too little ({covered} pixels)");
    }
}

#[test]
fn one_gaussian_by_hand() {
    // A disk facing the camera straight ahead at 4 m (sigma 0.1 m across, 0.01 m thick),
    // opacity 0.8, grey (SH dc 0 -> 0.5). Its thin axis (z) projects to nothing at the centre.
    let g = Gaussians {
        means: vec![[0.0, 0.0, 4.0]],
        log_scales: vec![[0.1f64.ln(), 0.1f64.ln(), 0.01f64.ln()]],
        rotations: vec![[1.0, 0.0, 0.0, 0.0]],
        opacity_logits: vec![(0.8f64 / 0.2).ln()],
        sh_degree: 0,
        sh: vec![0.0; 3],
    };
    let cam = camera(64, 64);
    let img = render(&g, &cam, &Features::default(), &RenderOptions::default());
    // The pixel whose centre is nearest the mean (32, 32) sits half a pixel off in x and y.
    let sigma_px: f64 = 0.9 * 64.0 * 0.1 / 4.0; // fx sigma / z
    let var = sigma_px * sigma_px + 0.3;
    let expect = 0.8 * (-0.5 * (0.25 + 0.25) / var).exp();
    let i = 32 * 64 + 32;
    assert!((img.alpha[i] - expect).abs() < 1e-12, "{} vs {expect}", img.alpha[i]);
    assert!((img.rgb[i][0] - 0.5 * expect).abs() < 1e-12);
    assert!((img.depth[i] - 4.0 * expect).abs() < 1e-11);
    // The disk's normal (its thin axis) faces the camera: -z, weighted by the alpha.
    assert!((img.normal[i][2] + expect).abs() < 1e-12 && img.normal[i][0].abs() < 1e-12);
    assert_eq!(img.alpha[0], 0.0);
}

#[test]
fn degenerate_inputs_never_panic_or_write_nan() {
    let mut g = scene(40, 1, 9);
    g.log_scales[0] = [-80.0; 3]; // zero size
    g.means[1] = [0.0, 0.0, -3.0]; // behind the camera
    g.means[2] = [f64::NAN, 0.0, 3.0];
    g.log_scales[3] = [f64::NAN, 0.0, 0.0];
    g.rotations[4] = [0.0; 4]; // not a rotation
    g.opacity_logits[5] = f64::NAN;
    g.sh[6 * 12] = f64::INFINITY;
    g.log_scales[7] = [60.0; 3]; // enormous
    g.means[8] = [0.0, 0.0, 0.010001]; // at the near plane
    let cam = camera(48, 32);
    let img = render(&g, &cam, &Features::default(), &RenderOptions { antialiased: true, ..Default::default() });
    for i in 0..img.alpha.len() {
        assert!(img.alpha[i].is_finite() && img.depth[i].is_finite(), "pixel {i}");
        assert!(img.rgb[i].iter().chain(&img.normal[i]).all(|v| v.is_finite()), "pixel {i}");
    }
    let empty = Gaussians::empty(0);
    let bg = render(
        &empty,
        &cam,
        &Features::default(),
        &RenderOptions { background: [1.0, 0.0, 0.0], ..Default::default() },
    );
    assert!(bg.rgb.iter().all(|c| *c == [1.0, 0.0, 0.0]) && bg.alpha.iter().all(|a| *a == 0.0));
}

/// Buffers kept between renders (a training loop's image, context and gradients) never leak
/// state: rendering a second, smaller scene at another size into them equals a fresh render.
#[test]
fn reused_buffers_equal_fresh_ones() {
    use splat::backward::{backward, backward_into, Gradients, Upstream};
    use splat::render::{render_into, render_with_context, Context};
    let opts = RenderOptions { background: [0.1, 0.2, 0.3], ..Default::default() };
    let (mut img, mut ctx, mut grads) = (Image::default(), Context::default(), Gradients::default());
    for (n, w, h, seed) in [(400, 96, 64, 5), (150, 40, 72, 6), (400, 96, 64, 7)] {
        let (g, cam) = (scene(n, 2, seed), camera(w, h));
        let f = Features::default();
        render_into(&g, &cam, &f, &opts, &mut img, &mut ctx);
        let (fresh, fresh_ctx) = render_with_context(&g, &cam, &f, &opts);
        assert_eq!(img, fresh, "scene {seed}: reused image differs");
        let px = img.alpha.len();
        let (ones, zeros, zeros3) = (vec![[1.0; 3]; px], vec![0.5; px], vec![[0.2; 3]; px]);
        let up = Upstream { rgb: &ones, alpha: &zeros, depth: &zeros, normal: &zeros3, features: &[] };
        backward_into(&g, &cam, &f, &opts, &ctx, &up, &mut grads);
        assert_eq!(grads, backward(&g, &cam, &f, &opts, &fresh_ctx, &up), "scene {seed}: reused gradients differ");
    }
}
