//! Rotating spherical-harmonic colour coefficients with the Gaussian they belong to.
//!
//! An actor's Gaussians live in its box frame; drawn in the world, the colour a world view
//! direction `d` sees must be the colour its box-frame direction `R^T d` saw. Each SH band `l`
//! mixes only within itself: `Y_l(R^T d) = M_l Y_l(d)`, so world coefficients are
//! `c_world = M_l^T c_box` and gradients go back as `dL/dc_box = M_l dL/dc_world`. `M_l` is found
//! by least squares over fixed, well-spread directions (the system is exact, so the residual is
//! round-off), which works for any rotation without hand-derived Wigner matrices that are easy to
//! get wrong for the 3DGS sign conventions.

use splat::sh::{basis, sh_coeffs};

/// Per-band mixing matrices `M_l` (row-major, `(2l+1)^2` values each) for one rotation.
#[derive(Clone, Debug)]
pub struct ShRotation {
    degree: usize,
    bands: Vec<Vec<f64>>,
}

fn band_range(l: usize) -> std::ops::Range<usize> {
    l * l..(l + 1) * (l + 1)
}

/// Fixed directions on a Fibonacci sphere (unit vectors).
fn directions(n: usize) -> Vec<[f64; 3]> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            [r * a.cos(), r * a.sin(), z]
        })
        .collect()
}

/// Solves the normal equations `(A^T A) X = A^T B` for `X` (`n x n`), Gauss-Jordan with pivoting.
fn least_squares(a: &[Vec<f64>], b: &[Vec<f64>], n: usize) -> Vec<f64> {
    let mut m = vec![vec![0.0; 2 * n]; n];
    for (ra, rb) in a.iter().zip(b) {
        for i in 0..n {
            for j in 0..n {
                m[i][j] += ra[i] * ra[j];
                m[i][n + j] += ra[i] * rb[j];
            }
        }
    }
    for c in 0..n {
        let p = (c..n).max_by(|&x, &y| m[x][c].abs().total_cmp(&m[y][c].abs())).unwrap_or(c);
        m.swap(c, p);
        let d = m[c][c];
        for v in m[c].iter_mut() {
            *v /= d;
        }
        for r in 0..n {
            if r != c {
                let f = m[r][c];
                let pivot = m[c].clone();
                for (v, pv) in m[r].iter_mut().zip(pivot) {
                    *v -= f * pv;
                }
            }
        }
    }
    m.iter().flat_map(|row| row[n..].to_vec()).collect()
}

impl ShRotation {
    /// The mixing for `world_from_local` rotation `r` (rows), bands 1..=degree (band 0 is fixed).
    pub fn new(degree: usize, r: [[f64; 3]; 3]) -> ShRotation {
        let dirs = directions(48);
        let bands = (1..=degree)
            .map(|l| {
                let range = band_range(l);
                let n = range.len();
                let (mut a, mut b) = (Vec::new(), Vec::new());
                for d in &dirs {
                    // local = R^T d
                    let local = std::array::from_fn(|k| (0..3).map(|i| r[i][k] * d[i]).sum::<f64>());
                    a.push(basis(degree, *d)[range.clone()].to_vec());
                    b.push(basis(degree, local)[range.clone()].to_vec());
                }
                // B = A M^T: X = M^T, stored transposed back into M (row-major).
                let x = least_squares(&a, &b, n);
                let mut m = vec![0.0; n * n];
                for i in 0..n {
                    for j in 0..n {
                        m[i * n + j] = x[j * n + i];
                    }
                }
                m
            })
            .collect();
        ShRotation { degree, bands }
    }

    /// World coefficients from box-frame ones for the first `sh_coeffs(degree_out)` coefficients
    /// (`src` has `3 * sh_coeffs(self.degree)` values, rgb interleaved; `dst` `3 *
    /// sh_coeffs(degree_out)`).
    pub fn to_world(&self, src: &[f64], dst: &mut [f64], degree_out: usize) {
        let k = sh_coeffs(degree_out);
        dst[..3].copy_from_slice(&src[..3]);
        for l in 1..=degree_out.min(self.degree) {
            let (range, m) = (band_range(l), &self.bands[l - 1]);
            let n = range.len();
            for i in 0..n {
                for ch in 0..3 {
                    // c_world[i] = sum_j M[j][i] c_box[j]
                    dst[(range.start + i) * 3 + ch] =
                        (0..n).map(|j| m[j * n + i] * src[(range.start + j) * 3 + ch]).sum();
                }
            }
        }
        debug_assert_eq!(dst.len(), 3 * k);
    }

    /// Adds `dL/dc_box = M dL/dc_world` for the world gradient `g` (`3 * sh_coeffs(degree_out)`).
    pub fn grad_to_local(&self, g: &[f64], out: &mut [f64], degree_out: usize) {
        for ch in 0..3 {
            out[ch] += g[ch];
        }
        for l in 1..=degree_out.min(self.degree) {
            let (range, m) = (band_range(l), &self.bands[l - 1]);
            let n = range.len();
            for j in 0..n {
                for ch in 0..3 {
                    out[(range.start + j) * 3 + ch] +=
                        (0..n).map(|i| m[j * n + i] * g[(range.start + i) * 3 + ch]).sum::<f64>();
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn colour(coeffs: &[f64], degree: usize, d: [f64; 3]) -> [f64; 3] {
        let b = basis(degree, d);
        std::array::from_fn(|ch| (0..sh_coeffs(degree)).map(|k| coeffs[k * 3 + ch] * b[k]).sum())
    }

    #[test]
    fn rotated_coefficients_see_the_same_colour() {
        let yaw: f64 = 0.7;
        let r = [[yaw.cos(), -yaw.sin(), 0.0], [yaw.sin(), yaw.cos(), 0.0], [0.0, 0.0, 1.0]];
        // A general rotation too (yaw, then a tilt about x).
        let t: f64 = 0.4;
        let rx = [[1.0, 0.0, 0.0], [0.0, t.cos(), -t.sin()], [0.0, t.sin(), t.cos()]];
        let general: [[f64; 3]; 3] =
            std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| r[i][k] * rx[k][j]).sum()));
        for rot in [r, general] {
            let rotation = ShRotation::new(3, rot);
            let local: Vec<f64> = (0..48).map(|i| ((i * 37 % 17) as f64 - 8.0) * 0.05).collect();
            let mut world = vec![0.0; 48];
            rotation.to_world(&local, &mut world, 3);
            for d in directions(20) {
                let l = std::array::from_fn(|k| (0..3).map(|i| rot[i][k] * d[i]).sum::<f64>());
                let (a, b) = (colour(&world, 3, d), colour(&local, 3, l));
                for ch in 0..3 {
                    assert!((a[ch] - b[ch]).abs() < 1e-10, "{a:?} vs {b:?}");
                }
            }
        }
    }

    #[test]
    fn gradient_is_the_adjoint() {
        let yaw: f64 = -2.1;
        let r = [[yaw.cos(), -yaw.sin(), 0.0], [yaw.sin(), yaw.cos(), 0.0], [0.0, 0.0, 1.0]];
        let rot = ShRotation::new(3, r);
        let local: Vec<f64> = (0..48).map(|i| (i as f64 * 0.37).sin()).collect();
        let gw: Vec<f64> = (0..48).map(|i| (i as f64 * 0.11).cos()).collect();
        let mut world = vec![0.0; 48];
        rot.to_world(&local, &mut world, 3);
        let mut gl = vec![0.0; 48];
        rot.grad_to_local(&gw, &mut gl, 3);
        // <gw, W c> == <W^T gw, c>
        let lhs: f64 = gw.iter().zip(&world).map(|(a, b)| a * b).sum();
        let rhs: f64 = gl.iter().zip(&local).map(|(a, b)| a * b).sum();
        assert!((lhs - rhs).abs() < 1e-10);
    }
}
