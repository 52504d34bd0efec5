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

/// Writes `g` as raw little-endian f32 rows for tools outside Rust (the gsplat side-by-side in
/// `tools/bench/`): per Gaussian `mean (3), log_scale (3), rotation wxyz (4), opacity logit (1),
/// sh (coeffs x 3, coefficient-major, RGB interleaved)`. Written to a temp file and renamed.
pub fn write_f32_rows(path: &std::path::Path, g: &Gaussians) -> std::io::Result<()> {
    let mut bytes = Vec::with_capacity(g.len() * (11 + g.coeffs() * 3) * 4);
    for i in 0..g.len() {
        let row = g.means[i]
            .iter()
            .chain(&g.log_scales[i])
            .chain(&g.rotations[i])
            .chain(std::iter::once(&g.opacity_logits[i]))
            .chain(g.sh_of(i));
        for v in row {
            bytes.extend_from_slice(&(*v as f32).to_le_bytes());
        }
    }
    let tmp = path.with_extension("tmp");
    std::fs::write(&tmp, &bytes)?;
    std::fs::rename(&tmp, path)
}

#[cfg(test)]
mod dump_tests {
    use super::*;

    #[test]
    fn rows_hold_every_parameter_in_order() {
        let cam = Camera::at_origin(64, 48, 50.0);
        let g = random_gaussians(3, &cam, 1, 5);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("g.f32");
        write_f32_rows(&path, &g).unwrap();
        let f: Vec<f32> =
            std::fs::read(&path).unwrap().chunks(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        let row = 11 + 4 * 3;
        assert_eq!(f.len(), 3 * row);
        let r2 = &f[2 * row..];
        assert_eq!(r2[0], g.means[2][0] as f32);
        assert_eq!(r2[5], g.log_scales[2][2] as f32);
        assert_eq!(r2[6], g.rotations[2][0] as f32);
        assert_eq!(r2[10], g.opacity_logits[2] as f32);
        assert_eq!(r2[11 + 3 * 3 + 2], g.sh_of(2)[11] as f32);
    }
}
