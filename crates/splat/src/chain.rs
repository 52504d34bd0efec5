//! The per-Gaussian half of the backward pass: from one Gaussian's screen-space gradients (mean,
//! conic, opacity, colour, depth, normal) to its parameters. They flow through
//! `K = Sigma2^-1` (`dSigma2 = -K dK K`), `Sigma2 = T Sigma3 T^T + 0.3 I`, `T = J W` (the EWA
//! Jacobian, with its clamping), the camera point, `Sigma3 = R S S R^T`, the quaternion (and its
//! normalisation), the antialiasing factor, the sigmoid, the SH colour (coefficients and view
//! direction) and the normal (the smallest-scale axis).

// Index loops mirror the matrix formulas above; iterator rewrites would hide them.
#![allow(clippy::needless_range_loop)]

use crate::backward_step::G2;
use crate::camera::Camera;
use crate::forward::RenderOptions;
use crate::gaussians::Gaussians;
use crate::project::{Frame, Projected};
use crate::sh::basis_grad;

fn mat2_mul(a: [[f64; 2]; 2], b: [[f64; 2]; 2]) -> [[f64; 2]; 2] {
    std::array::from_fn(|i| std::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j]))
}

/// One Gaussian's slots in the output gradients (all start at zero).
pub(crate) struct ParamGrads<'a> {
    pub mean: &'a mut [f64; 3],
    pub log_scale: &'a mut [f64; 3],
    pub rotation: &'a mut [f64; 4],
    pub opacity_logit: &'a mut f64,
    /// `coeffs * 3` values.
    pub sh: &'a mut [f64],
    pub mean2d_norm: &'a mut f64,
}

/// Backpropagates one Gaussian's screen-space gradients `a` to its parameters.
pub(crate) fn gaussian_backward(
    g: &Gaussians,
    cam: &Camera,
    opts: &RenderOptions,
    pr: &Projected,
    f: &Frame,
    a: &G2,
    out: ParamGrads,
) {
    let i = pr.index;
    let wr: [[f64; 3]; 3] = std::array::from_fn(|r| {
        [cam.camera_from_world[r][0], cam.camera_from_world[r][1], cam.camera_from_world[r][2]]
    });
    let [x, y, z] = f.p;
    let mut g_p = [0.0; 3]; // camera point
    let mut g_m = [0.0; 3]; // world mean (direct)
                            // Colour -> SH coefficients and view direction.
    let kc = g.coeffs();
    let sh = g.sh_of(i);
    let bg = basis_grad(g.sh_degree, f.dir);
    let mut g_dir = [0.0; 3];
    for ch in 0..3 {
        if a.color[ch] == 0.0 {
            continue;
        }
        for k in 0..kc {
            out.sh[k * 3 + ch] += a.color[ch] * f.basis[k];
            for c in 0..3 {
                g_dir[c] += a.color[ch] * sh[k * 3 + ch] * bg[k][c];
            }
        }
    }
    let dd: f64 = (0..3).map(|c| f.dir[c] * g_dir[c]).sum();
    for c in 0..3 {
        g_m[c] += (g_dir[c] - f.dir[c] * dd) / f.dist;
    }
    // Opacity -> logit and the antialiasing factor.
    *out.opacity_logit += a.opacity * f.aa * f.sigmoid * (1.0 - f.sigmoid);
    let mut g_cov = [[0.0; 2]; 2];
    if opts.antialiased && f.aa > 0.0 {
        let g_aa = a.opacity * f.sigmoid;
        let (c0, c) = (f.cov0, f.cov);
        let det0 = c0[0][0] * c0[1][1] - c0[0][1] * c0[1][0];
        let det = c[0][0] * c[1][1] - c[0][1] * c[1][0];
        // aa = sqrt(det0 / det): d aa / d det0 = aa / (2 det0), d aa / d det = -aa / (2 det);
        // d det / d Sigma = adj(Sigma)^T (same for det0 with Sigma0 = Sigma - eps I).
        let (k0, k1) = (g_aa * f.aa / (2.0 * det0), -g_aa * f.aa / (2.0 * det));
        g_cov[0][0] += k0 * c0[1][1] + k1 * c[1][1];
        g_cov[1][1] += k0 * c0[0][0] + k1 * c[0][0];
        g_cov[0][1] += -k0 * c0[1][0] - k1 * c[1][0];
        g_cov[1][0] += -k0 * c0[0][1] - k1 * c[0][1];
    }
    // Conic -> covariance: dSigma = -K G_K K.
    let kmat = [[pr.conic[0], pr.conic[1]], [pr.conic[1], pr.conic[2]]];
    let gk = [[a.conic[0], a.conic[1] / 2.0], [a.conic[1] / 2.0, a.conic[2]]];
    let prod = mat2_mul(mat2_mul(kmat, gk), kmat);
    for r in 0..2 {
        for c in 0..2 {
            g_cov[r][c] -= prod[r][c];
        }
    }
    // Sigma2 = T Sigma3 T^T.
    let t = f.t;
    let mut g_sig3 = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            g_sig3[r][c] = (0..2).map(|u| (0..2).map(|v| t[u][r] * g_cov[u][v] * t[v][c]).sum::<f64>()).sum();
        }
    }
    // dL/dT = (G + G^T) T Sigma3 (Sigma3 symmetric).
    let gsym = [[g_cov[0][0] * 2.0, g_cov[0][1] + g_cov[1][0]], [g_cov[0][1] + g_cov[1][0], g_cov[1][1] * 2.0]];
    let mut g_t = [[0.0; 3]; 2];
    for r in 0..2 {
        for c in 0..3 {
            g_t[r][c] = (0..2).map(|u| (0..3).map(|v| gsym[r][u] * t[u][v] * f.sig3[v][c]).sum::<f64>()).sum::<f64>();
        }
    }
    // T = J W -> dL/dJ = dL/dT W^T.
    let g_j: [[f64; 3]; 2] =
        std::array::from_fn(|r| std::array::from_fn(|c| (0..3).map(|k| g_t[r][k] * wr[c][k]).sum()));
    let (fx, fy) = (cam.fx, cam.fy);
    let (ux, uy) = (if f.clamped[0] { 0.0 } else { x / z }, if f.clamped[1] { 0.0 } else { y / z });
    let tx_over_z = {
        let lim = |u: f64, lo: f64, hi: f64| u.clamp(lo, hi);
        (
            lim(x / z, -1.3 * cam.cx / fx, 1.3 * (cam.width as f64 - cam.cx) / fx),
            lim(y / z, -1.3 * cam.cy / fy, 1.3 * (cam.height as f64 - cam.cy) / fy),
        )
    };
    // J = [[fx/z, 0, -fx u/z], [0, fy/z, -fy v/z]] with u = clamp(x/z), v = clamp(y/z).
    g_p[2] += g_j[0][0] * -fx / (z * z) + g_j[1][1] * -fy / (z * z);
    g_p[2] += g_j[0][2] * fx * tx_over_z.0 / (z * z) + g_j[1][2] * fy * tx_over_z.1 / (z * z);
    if !f.clamped[0] {
        // u = x / z: du/dx = 1/z, du/dz = -x/z^2
        g_p[0] += g_j[0][2] * -fx / (z * z);
        g_p[2] += g_j[0][2] * -fx / z * (-ux / z);
    }
    if !f.clamped[1] {
        g_p[1] += g_j[1][2] * -fy / (z * z);
        g_p[2] += g_j[1][2] * -fy / z * (-uy / z);
    }
    // Mean on screen and depth.
    g_p[0] += a.mean[0] * fx / z;
    g_p[1] += a.mean[1] * fy / z;
    g_p[2] += a.mean[0] * -fx * x / (z * z) + a.mean[1] * -fy * y / (z * z) + a.depth;
    // Normal: n_cam = +-W R[:, kmin].
    let sign = if f.flipped { -1.0 } else { 1.0 };
    let mut g_r = [[0.0; 3]; 3];
    for r in 0..3 {
        g_r[r][f.kmin] += sign * (0..3).map(|c| wr[c][r] * a.normal[c]).sum::<f64>();
    }
    // Camera point -> world mean.
    for c in 0..3 {
        g_m[c] += (0..3).map(|r| wr[r][c] * g_p[r]).sum::<f64>();
    }
    // Sigma3 = M M^T, M = R diag(s): dL/dM = (G + G^T) M.
    let mm: [[f64; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| f.r[r][c] * f.s[c]));
    for k in 0..3 {
        let mut gs = 0.0;
        for r in 0..3 {
            let gmrk: f64 = (0..3).map(|c| (g_sig3[r][c] + g_sig3[c][r]) * mm[c][k]).sum();
            gs += gmrk * f.r[r][k];
            g_r[r][k] += gmrk * f.s[k];
        }
        out.log_scale[k] += gs * f.s[k];
    }
    // R(q) with q normalised.
    let q = g.rotations[i];
    let nq = (q.iter().map(|v| v * v).sum::<f64>()).sqrt();
    if nq > 0.0 {
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
        let dot: f64 = (0..4).map(|c| qh[c] * gq[c]).sum();
        for c in 0..4 {
            out.rotation[c] += (gq[c] - qh[c] * dot) / nq;
        }
    }
    for c in 0..3 {
        out.mean[c] += g_m[c];
    }
    *out.mean2d_norm += (a.mean[0] * a.mean[0] + a.mean[1] * a.mean[1]).sqrt();
}
