//! Real spherical harmonics up to degree 3 with the constants 3DGS and gsplat use, evaluated for
//! a unit view direction. Colour = 0.5 + sum_k c_k Y_k(d), clamped at 0 by the renderer.

/// Number of coefficients per channel for a degree.
pub const fn sh_coeffs(degree: usize) -> usize {
    (degree + 1) * (degree + 1)
}

pub const C0: f64 = 0.282_094_791_773_878_14;
pub const C1: f64 = 0.488_602_511_902_919_9;
pub const C2: [f64; 5] = [
    1.092_548_430_592_079_2,
    -1.092_548_430_592_079_2,
    0.315_391_565_252_520_05,
    -1.092_548_430_592_079_2,
    0.546_274_215_296_039_6,
];
pub const C3: [f64; 7] = [
    -0.590_043_589_926_643_5,
    2.890_611_442_640_554,
    -0.457_045_799_464_465_8,
    0.373_176_332_590_115_4,
    -0.457_045_799_464_465_8,
    1.445_305_721_320_277,
    -0.590_043_589_926_643_5,
];

/// The basis values `Y_k(d)` for `k < sh_coeffs(degree)`, `d` a unit vector.
pub fn basis(degree: usize, d: [f64; 3]) -> [f64; 16] {
    let [x, y, z] = d;
    let mut b = [0.0; 16];
    b[0] = C0;
    if degree >= 1 {
        b[1] = -C1 * y;
        b[2] = C1 * z;
        b[3] = -C1 * x;
    }
    if degree >= 2 {
        let (xx, yy, zz, xy, yz, xz) = (x * x, y * y, z * z, x * y, y * z, x * z);
        b[4] = C2[0] * xy;
        b[5] = C2[1] * yz;
        b[6] = C2[2] * (2.0 * zz - xx - yy);
        b[7] = C2[3] * xz;
        b[8] = C2[4] * (xx - yy);
        if degree >= 3 {
            b[9] = C3[0] * y * (3.0 * xx - yy);
            b[10] = C3[1] * xy * z;
            b[11] = C3[2] * y * (4.0 * zz - xx - yy);
            b[12] = C3[3] * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
            b[13] = C3[4] * x * (4.0 * zz - xx - yy);
            b[14] = C3[5] * z * (xx - yy);
            b[15] = C3[6] * x * (xx - 3.0 * yy);
        }
    }
    b
}

/// The basis values and their gradients with respect to the (unnormalised) direction
/// components, `grad[k] = dY_k / d(x, y, z)`, treating `d` as given (callers chain through the
/// normalisation).
pub fn basis_grad(degree: usize, d: [f64; 3]) -> [[f64; 3]; 16] {
    let [x, y, z] = d;
    let mut g = [[0.0; 3]; 16];
    if degree >= 1 {
        g[1] = [0.0, -C1, 0.0];
        g[2] = [0.0, 0.0, C1];
        g[3] = [-C1, 0.0, 0.0];
    }
    if degree >= 2 {
        g[4] = [C2[0] * y, C2[0] * x, 0.0];
        g[5] = [0.0, C2[1] * z, C2[1] * y];
        g[6] = [C2[2] * -2.0 * x, C2[2] * -2.0 * y, C2[2] * 4.0 * z];
        g[7] = [C2[3] * z, 0.0, C2[3] * x];
        g[8] = [C2[4] * 2.0 * x, C2[4] * -2.0 * y, 0.0];
        if degree >= 3 {
            let (xx, yy, zz) = (x * x, y * y, z * z);
            g[9] = [C3[0] * 6.0 * x * y, C3[0] * (3.0 * xx - 3.0 * yy), 0.0];
            g[10] = [C3[1] * y * z, C3[1] * x * z, C3[1] * x * y];
            g[11] = [C3[2] * -2.0 * x * y, C3[2] * (4.0 * zz - xx - 3.0 * yy), C3[2] * 8.0 * y * z];
            g[12] = [C3[3] * -6.0 * x * z, C3[3] * -6.0 * y * z, C3[3] * (6.0 * zz - 3.0 * xx - 3.0 * yy)];
            g[13] = [C3[4] * (4.0 * zz - 3.0 * xx - yy), C3[4] * -2.0 * x * y, C3[4] * 8.0 * x * z];
            g[14] = [C3[5] * 2.0 * x * z, C3[5] * -2.0 * y * z, C3[5] * (xx - yy)];
            g[15] = [C3[6] * (3.0 * xx - 3.0 * yy), C3[6] * -6.0 * x * y, 0.0];
        }
    }
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_gradient_by_finite_differences() {
        let d = [0.3, -0.5, 0.8];
        let g = basis_grad(3, d);
        for a in 0..3 {
            let h = 1e-6;
            let (mut p, mut m) = (d, d);
            p[a] += h;
            m[a] -= h;
            let (bp, bm) = (basis(3, p), basis(3, m));
            for (k, gk) in g.iter().enumerate() {
                let fd = (bp[k] - bm[k]) / (2.0 * h);
                assert!((fd - gk[a]).abs() < 1e-8, "Y{k} d/d{a}: {fd} vs {}", gk[a]);
            }
        }
    }

    #[test]
    fn orthonormal_on_the_sphere() {
        // Monte Carlo-free check: integrate Y_i Y_j over a Fibonacci sphere of 20k points.
        let n = 20_000;
        let mut gram = [[0.0f64; 16]; 16];
        for k in 0..n {
            let z = 1.0 - 2.0 * (k as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).sqrt();
            let phi = k as f64 * std::f64::consts::PI * (3.0 - 5f64.sqrt());
            let b = basis(3, [r * phi.cos(), r * phi.sin(), z]);
            for (row, bi) in gram.iter_mut().zip(b) {
                for (cell, bj) in row.iter_mut().zip(b) {
                    *cell += bi * bj * 4.0 * std::f64::consts::PI / n as f64;
                }
            }
        }
        for (i, row) in gram.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((v - want).abs() < 2e-3, "<Y{i}, Y{j}> = {v}");
            }
        }
    }
}
