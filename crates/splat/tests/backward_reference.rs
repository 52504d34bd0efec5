//! The tiled backward rasterizer (Gaussian-major spans, transmittance recovered by division,
//! per-tile accumulation) against the brute-force per-pixel backward pass, in the real mode:
//! 1/255 cut-off, 0.99 clamp and early stop all active, on scenes dense enough that pixels
//! saturate. Finite differences cannot test this mode (it is not smooth); the reference can.

mod common;

use common::{dense_scene as scene, tilted_camera};
use splat::backward::{backward, render_backward_brute_force, Gradients, Upstream};
use splat::random::XorShift as Rng;
use splat::render::{render_with_context, Features, RenderOptions};

fn flat(g: &Gradients) -> Vec<f64> {
    let mut v: Vec<f64> = g.means.iter().flatten().copied().collect();
    v.extend(g.log_scales.iter().flatten());
    v.extend(g.rotations.iter().flatten());
    v.extend(&g.opacity_logits);
    v.extend(&g.sh);
    v.extend(&g.features);
    v.extend(&g.mean2d_norm);
    v
}

#[test]
fn tiled_backward_equals_brute_force() {
    let cam = tilted_camera(70, 45, 60.0, 61.0, 35.2, 22.7);
    let n_px = (cam.width * cam.height) as usize;
    for (seed, aa, world) in [(21u64, false, false), (22, true, true)] {
        let g = scene(900, seed);
        let fv: Vec<f64> = {
            let mut r = Rng(seed + 100);
            (0..g.len() * 3).map(|_| r.range(-1.0, 1.0)).collect()
        };
        let f = Features { values: &fv, channels: 3 };
        let opts = RenderOptions { background: [0.3, 0.5, 0.2], antialiased: aa, normals_world: world, smooth: false };
        let mut r = Rng(seed + 200);
        let mut v = || r.range(-1.0, 1.0);
        let rgb: Vec<[f64; 3]> = (0..n_px).map(|_| [v(), v(), v()]).collect();
        let alpha: Vec<f64> = (0..n_px).map(|_| v()).collect();
        let depth: Vec<f64> = (0..n_px).map(|_| v()).collect();
        let normal: Vec<[f64; 3]> = (0..n_px).map(|_| [v(), v(), v()]).collect();
        let features: Vec<f64> = (0..n_px * 3).map(|_| v()).collect();
        let up = Upstream { rgb: &rgb, alpha: &alpha, depth: &depth, normal: &normal, features: &features };

        let (img, ctx) = render_with_context(&g, &cam, &f, &opts);
        let saturated = img.alpha.iter().filter(|a| **a > 0.998).count();
        assert!(
            saturated > n_px / 10,
            "seed {seed}: only {saturated} pixels saturate; the early stop is not exercised"
        );
        let fast = flat(&backward(&g, &cam, &f, &opts, &ctx, &up));
        let reference = flat(&render_backward_brute_force(&g, &cam, &f, &opts, &up));
        let scale = reference.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(scale > 0.0);
        let nonzero = reference.iter().filter(|x| **x != 0.0).count();
        assert!(nonzero > reference.len() / 2, "seed {seed}: most gradients are zero ({nonzero})");
        for (i, (a, b)) in fast.iter().zip(&reference).enumerate() {
            let err = (a - b).abs() / (b.abs() + 1e-9 * scale);
            assert!(err < 1e-8, "seed {seed}: entry {i}: tiled {a:e} vs reference {b:e} (relative {err:.2e})");
        }
    }
}
