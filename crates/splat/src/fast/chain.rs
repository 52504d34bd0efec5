//! The per-Gaussian chain rule in f32: one Gaussian's screen-space gradient sums (mean, conic,
//! opacity, colour, depth, normal) to its parameters, from the `Frame32` its projection kept.
//!
//! A line-by-line port of `chain::gaussian_backward` (see there for the derivation: conic ->
//! covariance, `Sigma2 = T Sigma3 T^T + 0.3 I`, the clamped EWA Jacobian, the camera point,
//! `Sigma3 = R S S R^T`, the normalised quaternion, the antialiasing factor, the sigmoid, the
//! SH colour and view direction, the smallest-scale normal). The SH basis and its gradient are
//! the reference's f64 functions (cheap per Gaussian); results are written as f64.

// Index loops mirror the matrix formulas; iterator rewrites would hide them.
#![allow(clippy::needless_range_loop)]

use super::project::{CamConst, Frame32, Hot32};
use crate::gaussians::Gaussians;
use crate::sh::{basis, basis_grad};

/// Screen-space sums of one Gaussian (layout of `backward::G_CH`).
pub struct Screen {
    pub mean: [f32; 2],
    pub conic: [f32; 3],
    pub opacity: f32,
    pub color: [f32; 3],
    pub depth: f32,
    pub normal: [f32; 3],
}

impl Screen {
    pub fn of(v: &[f64]) -> Screen {
        let f = |i: usize| v[i] as f32;
        Screen {
            mean: [f(0), f(1)],
            conic: [f(2), f(3), f(4)],
            opacity: f(5),
            color: [f(6), f(7), f(8)],
            depth: f(9),
            normal: [f(10), f(11), f(12)],
        }
    }
}

/// One Gaussian's output slots (all start at zero).
pub struct Out<'a> {
    pub mean: &'a mut [f64; 3],
    pub log_scale: &'a mut [f64; 3],
    pub rotation: &'a mut [f64; 4],
    pub opacity_logit: &'a mut f64,
    pub sh: &'a mut [f64],
    pub mean2d_norm: &'a mut f64,
}

fn mat2_mul(a: [[f32; 2]; 2], b: [[f32; 2]; 2]) -> [[f32; 2]; 2] {
    std::array::from_fn(|i| std::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j]))
}

/// Backpropagates Gaussian `h`'s screen-space sums `a` to its parameters.
#[allow(clippy::too_many_arguments)]
pub fn gaussian_backward32(
    g: &Gaussians,
    i: usize,
    cc: &CamConst,
    antialiased: bool,
    h: &Hot32,
    f: &Frame32,
    a: &Screen,
    out: Out,
) {
    let wr = &cc.wr;
    let [x, y, z] = f.p;
    let mut g_p = [0.0f32; 3];
    let mut g_m = [0.0f32; 3];
    // Colour -> SH coefficients and view direction (f64 basis).
    let kc = g.coeffs();
    let sh = g.sh_of(i);
    let dir64 = f.dir.map(|v| v as f64);
    let b = basis(g.sh_degree, dir64);
    let bg = basis_grad(g.sh_degree, dir64);
    let mut g_dir = [0.0f64; 3];
    for ch in 0..3 {
        if a.color[ch] == 0.0 {
            continue;
        }
        let ac = a.color[ch] as f64;
        for k in 0..kc {
            out.sh[k * 3 + ch] += ac * b[k];
            for c in 0..3 {
                g_dir[c] += ac * sh[k * 3 + ch] * bg[k][c];
            }
        }
    }
    let g_dir = g_dir.map(|v| v as f32);
    let dd: f32 = (0..3).map(|c| f.dir[c] * g_dir[c]).sum();
    for c in 0..3 {
        g_m[c] += (g_dir[c] - f.dir[c] * dd) / f.dist;
    }
    // Opacity -> logit and the antialiasing factor.
    *out.opacity_logit += (a.opacity * f.aa * f.sigmoid * (1.0 - f.sigmoid)) as f64;
    let mut g_cov = [[0.0f32; 2]; 2];
    if antialiased && f.aa > 0.0 {
        let g_aa = a.opacity * f.sigmoid;
        let (c0, c) = (f.cov0, f.cov);
        let (det0, det) = (f.det0, f.det);
        let (k0, k1) = (g_aa * f.aa / (2.0 * det0), -g_aa * f.aa / (2.0 * det));
        g_cov[0][0] += k0 * c0[1][1] + k1 * c[1][1];
        g_cov[1][1] += k0 * c0[0][0] + k1 * c[0][0];
        g_cov[0][1] += -k0 * c0[1][0] - k1 * c[1][0];
        g_cov[1][0] += -k0 * c0[0][1] - k1 * c[0][1];
    }
    // Conic -> covariance: dSigma = -K G_K K.
    let kmat = [[h.conic[0], h.conic[1]], [h.conic[1], h.conic[2]]];
    let gk = [[a.conic[0], a.conic[1] / 2.0], [a.conic[1] / 2.0, a.conic[2]]];
    let prod = mat2_mul(mat2_mul(kmat, gk), kmat);
    for r in 0..2 {
        for c in 0..2 {
            g_cov[r][c] -= prod[r][c];
        }
    }
    let t = f.t;
    let mut g_sig3 = [[0.0f32; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            g_sig3[r][c] = (0..2).map(|u| (0..2).map(|v| t[u][r] * g_cov[u][v] * t[v][c]).sum::<f32>()).sum();
        }
    }
    let gsym = [[g_cov[0][0] * 2.0, g_cov[0][1] + g_cov[1][0]], [g_cov[0][1] + g_cov[1][0], g_cov[1][1] * 2.0]];
    let mut g_t = [[0.0f32; 3]; 2];
    for r in 0..2 {
        for c in 0..3 {
            g_t[r][c] = (0..2).map(|u| (0..3).map(|v| gsym[r][u] * t[u][v] * f.sig3[v][c]).sum::<f32>()).sum::<f32>();
        }
    }
    let g_j: [[f32; 3]; 2] =
        std::array::from_fn(|r| std::array::from_fn(|c| (0..3).map(|k| g_t[r][k] * wr[c][k]).sum()));
    let (fx, fy) = (cc.fx, cc.fy);
    let (ux, uy) = (if f.clamped[0] { 0.0 } else { x / z }, if f.clamped[1] { 0.0 } else { y / z });
    let lim = |l: [f64; 2]| [l[0] as f32, l[1] as f32];
    let (lx, ly) = (lim(cc.bound.lim_x), lim(cc.bound.lim_y));
    let tx_over_z = ((x / z).clamp(lx[0], lx[1]), (y / z).clamp(ly[0], ly[1]));
    let zz = z * z;
    g_p[2] += g_j[0][0] * -fx / zz + g_j[1][1] * -fy / zz;
    g_p[2] += g_j[0][2] * fx * tx_over_z.0 / zz + g_j[1][2] * fy * tx_over_z.1 / zz;
    if !f.clamped[0] {
        g_p[0] += g_j[0][2] * -fx / zz;
        g_p[2] += g_j[0][2] * -fx / z * (-ux / z);
    }
    if !f.clamped[1] {
        g_p[1] += g_j[1][2] * -fy / zz;
        g_p[2] += g_j[1][2] * -fy / z * (-uy / z);
    }
    g_p[0] += a.mean[0] * fx / z;
    g_p[1] += a.mean[1] * fy / z;
    g_p[2] += a.mean[0] * -fx * x / zz + a.mean[1] * -fy * y / zz + a.depth;
    let sign = if f.flipped { -1.0 } else { 1.0 };
    let kmin = f.kmin as usize;
    let mut g_r = [[0.0f32; 3]; 3];
    for r in 0..3 {
        g_r[r][kmin] += sign * (0..3).map(|c| wr[c][r] * a.normal[c]).sum::<f32>();
    }
    for c in 0..3 {
        g_m[c] += (0..3).map(|r| wr[r][c] * g_p[r]).sum::<f32>();
    }
    let mm: [[f32; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| f.r[r][c] * f.s[c]));
    for k in 0..3 {
        let mut gs = 0.0f32;
        for r in 0..3 {
            let gmrk: f32 = (0..3).map(|c| (g_sig3[r][c] + g_sig3[c][r]) * mm[c][k]).sum();
            gs += gmrk * f.r[r][k];
            g_r[r][k] += gmrk * f.s[k];
        }
        out.log_scale[k] += (gs * f.s[k]) as f64;
    }
    let q = g.rotations[i].map(|v| v as f32);
    let nq = (q.iter().map(|v| v * v).sum::<f32>()).sqrt();
    if nq > 0.0 && nq.is_finite() {
        let [w, qx, qy, qz] = q.map(|v| v / nq);
        let gg = g_r;
        let gw = 2.0 * (-qz * gg[0][1] + qy * gg[0][2] + qz * gg[1][0] - qx * gg[1][2] - qy * gg[2][0] + qx * gg[2][1]);
        let gx = 2.0
            * (qy * gg[0][1] + qz * gg[0][2] + qy * gg[1][0] - 2.0 * qx * gg[1][1] - w * gg[1][2]
                + qz * gg[2][0]
                + w * gg[2][1]
                - 2.0 * qx * gg[2][2]);
        let gy = 2.0
            * (-2.0 * qy * gg[0][0] + qx * gg[0][1] + w * gg[0][2] + qx * gg[1][0] + qz * gg[1][2] - w * gg[2][0]
                + qz * gg[2][1]
                - 2.0 * qy * gg[2][2]);
        let gz = 2.0
            * (-2.0 * qz * gg[0][0] - w * gg[0][1] + qx * gg[0][2] + w * gg[1][0] - 2.0 * qz * gg[1][1]
                + qy * gg[1][2]
                + qx * gg[2][0]
                + qy * gg[2][1]);
        let gq = [gw, gx, gy, gz];
        let qh = [w, qx, qy, qz];
        let dot: f32 = (0..4).map(|c| qh[c] * gq[c]).sum();
        for c in 0..4 {
            out.rotation[c] += ((gq[c] - qh[c] * dot) / nq) as f64;
        }
    }
    for c in 0..3 {
        out.mean[c] += g_m[c] as f64;
    }
    *out.mean2d_norm += ((a.mean[0] * a.mean[0] + a.mean[1] * a.mean[1]) as f64).sqrt();
}
