//! What the rasterizer comparison tests share: a slightly tilted camera and a dense random scene
//! (opacities up to sigmoid(6) = 0.9975, so pixels saturate and some alphas hit the 0.99 clamp).

use splat::random::XorShift as Rng;
use splat::{Camera, Gaussians};

/// A `w x h` camera looking down +z, tilted about 6 degrees, with the given intrinsics.
pub fn tilted_camera(w: u32, h: u32, fx: f64, fy: f64, cx: f64, cy: f64) -> Camera {
    Camera {
        width: w,
        height: h,
        fx,
        fy,
        cx,
        cy,
        camera_from_world: [
            [1.0, 0.0, 0.0, 0.1],
            [0.0, 0.995, -0.0998, 0.0],
            [0.0, 0.0998, 0.995, 0.2],
            [0.0, 0.0, 0.0, 1.0],
        ],
        near: 0.01,
        far: 100.0,
    }
}

/// `n` random Gaussians in front of [`tilted_camera`], SH degree 2.
pub fn dense_scene(n: usize, seed: u64) -> Gaussians {
    let mut r = Rng(seed);
    Gaussians {
        means: (0..n).map(|_| [r.range(-1.6, 1.6), r.range(-1.0, 1.0), r.range(2.0, 5.0)]).collect(),
        log_scales: (0..n).map(|_| [r.range(-2.5, -1.2), r.range(-2.5, -1.2), r.range(-3.5, -2.0)]).collect(),
        rotations: (0..n)
            .map(|_| [r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0)])
            .collect(),
        opacity_logits: (0..n).map(|_| r.range(-2.0, 6.0)).collect(),
        sh_degree: 2,
        sh: (0..n * 9 * 3).map(|_| r.range(-0.6, 0.6)).collect(),
    }
}
