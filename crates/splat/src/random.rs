//! Seeded random Gaussians inside a camera's view (for benchmarks and quick looks): means spread
//! over the frustum between 2 and 20 m, anisotropic scales, random rotations, opacities and SH.

use crate::camera::Camera;
use crate::gaussians::Gaussians;
use crate::sh::sh_coeffs;

/// A small seeded xorshift generator (uniform f64 in [0, 1)), shared by benchmarks and tests.
pub struct XorShift(pub u64);

impl XorShift {
    pub fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.uniform()
    }
}

/// `n` Gaussians visible from `cam` (world frame), deterministic given `seed`.
pub fn random_gaussians(n: usize, cam: &Camera, degree: usize, seed: u64) -> Gaussians {
    let mut r = XorShift(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1);
    let k = sh_coeffs(degree);
    let m = &cam.camera_from_world;
    let c = cam.center();
    let mut g = Gaussians {
        means: Vec::with_capacity(n),
        log_scales: Vec::with_capacity(n),
        rotations: Vec::with_capacity(n),
        opacity_logits: Vec::with_capacity(n),
        sh_degree: degree,
        sh: Vec::with_capacity(n * k * 3),
    };
    for _ in 0..n {
        let z = r.range(2.0, 20.0);
        let u = r.range(0.0, cam.width as f64);
        let v = r.range(0.0, cam.height as f64);
        let p = [(u - cam.cx) / cam.fx * z, (v - cam.cy) / cam.fy * z, z];
        // world = R^T p + centre
        g.means.push(std::array::from_fn(|a| (0..3).map(|b| m[b][a] * p[b]).sum::<f64>() + c[a]));
        let base = r.range(-4.5, -2.0) + (z / 10.0).ln();
        g.log_scales.push([base + r.range(-0.5, 0.5), base + r.range(-0.5, 0.5), base - r.range(0.5, 1.5)]);
        g.rotations.push([r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0), r.range(-1.0, 1.0)]);
        g.opacity_logits.push(r.range(-2.0, 3.0));
        for j in 0..k * 3 {
            g.sh.push(if j < 3 { r.range(-1.5, 1.5) } else { r.range(-0.2, 0.2) });
        }
    }
    g
}
