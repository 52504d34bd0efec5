//! Hand-derived gradients of every rendered channel with respect to every Gaussian parameter.
//!
//! Per pixel, the forward composite `out = sum_i w_i v_i + T_N bg` (`w_i = alpha_i T_i`) is walked
//! back to front: `d out / d alpha_i = T_i v_i - S_i / (1 - alpha_i)` with `S_i` the sum of what
//! lies behind `i` (background included), and `d alpha_out / d alpha_i = T_N / (1 - alpha_i)`.
//! Then `alpha = o exp(power)`, `power = -0.5 d^T K d` (`K` the conic, `d = q - mean`) give the
//! screen-space gradients (mean, conic, opacity), and per Gaussian they flow through
//! `K = Sigma2^-1` (`dSigma2 = -K dK K`), `Sigma2 = T Sigma3 T^T + 0.3 I`, `T = J W` (the EWA
//! Jacobian, with its clamping), the camera point, `Sigma3 = R S S R^T`, the quaternion (and its
//! normalisation), the antialiasing factor, the sigmoid, the SH colour (coefficients and view
//! direction) and the normal (the smallest-scale axis). Colours clamped at 0 and alphas clamped at
//! 0.99 pass no gradient, like the forward.

// Index loops mirror the matrix formulas above; iterator rewrites would hide them.
#![allow(clippy::needless_range_loop)]

use crate::camera::Camera;
use crate::gaussians::Gaussians;
use crate::project::{Frame, Projected};
use crate::render::{alpha_at, hot, Hot};
use crate::render::{bin, project_all_full, Features, RenderOptions, TILE, T_MIN};
use crate::sh::basis_grad;
use rayon::prelude::*;

/// Gradients of a scalar loss with respect to the rendered channels (same layout as `Image`).
pub struct Upstream<'a> {
    pub rgb: &'a [[f64; 3]],
    pub alpha: &'a [f64],
    pub depth: &'a [f64],
    pub normal: &'a [[f64; 3]],
    pub features: &'a [f64],
}

/// Gradients with respect to the model's parameters (same layout as `Gaussians`).
#[derive(Clone, Debug, PartialEq)]
pub struct Gradients {
    pub means: Vec<[f64; 3]>,
    pub log_scales: Vec<[f64; 3]>,
    pub rotations: Vec<[f64; 4]>,
    pub opacity_logits: Vec<f64>,
    pub sh: Vec<f64>,
    pub features: Vec<f64>,
    /// |dL / d mean2d| per Gaussian (the screen-space gradient densification uses).
    pub mean2d_norm: Vec<f64>,
}

/// Screen-space gradients of one projected Gaussian.
#[derive(Clone, Copy, Default)]
struct G2 {
    mean: [f64; 2],
    conic: [f64; 3],
    opacity: f64,
    color: [f64; 3],
    depth: f64,
    normal: [f64; 3],
}

#[allow(clippy::too_many_arguments)]
fn pixel_backward(
    q: [f64; 2],
    pix: usize,
    order: &[usize],
    hot: &[Hot],
    proj: &[(Projected, Frame)],
    feats: &Features,
    opts: &RenderOptions,
    up: &Upstream,
    nrot: &Option<[[f64; 3]; 3]>,
    acc: &mut [G2],
    facc: &mut [f64],
) {
    let k = feats.channels;
    // Forward again: the contributing Gaussians with alpha, T before, power, clamp.
    // (tile-local slot, projected index, alpha, T before, power, clamped)
    let mut hits: Vec<(usize, usize, f64, f64, f64, bool)> = Vec::new();
    let mut t = 1.0;
    for (slot, (&pi, h)) in order.iter().zip(hot).enumerate() {
        let Some((alpha, power, clamped)) = alpha_at(h, q, opts.smooth) else { continue };
        let next = t * (1.0 - alpha);
        if !opts.smooth && next < T_MIN {
            break;
        }
        hits.push((slot, pi, alpha, t, power, clamped));
        t = next;
    }
    let t_n = t;
    let (gc, ga, gd, gn_out) = (up.rgb[pix], up.alpha[pix], up.depth[pix], up.normal[pix]);
    // Normal gradient in camera axes (the output may be world-frame: n_world = Rc^T n_cam).
    let gn: [f64; 3] = match nrot {
        Some(r) => std::array::from_fn(|a| (0..3).map(|b| r[a][b] * gn_out[b]).sum()),
        None => gn_out,
    };
    let gf = &up.features[pix * k..(pix + 1) * k];
    // Sums of what lies behind (back to front).
    let mut s_c = opts.background.map(|b| t_n * b);
    let (mut s_d, mut s_n) = (0.0, [0.0; 3]);
    let mut s_f = vec![0.0; k];
    for &(slot, pi, alpha, ti, power, clamped) in hits.iter().rev() {
        let (g, _) = &proj[pi];
        let w = alpha * ti;
        let vc = g.color.map(|c| c.max(0.0));
        let a = &mut acc[slot];
        for ch in 0..3 {
            if g.color[ch] > 0.0 {
                a.color[ch] += gc[ch] * w;
            }
            a.normal[ch] += gn[ch] * w;
        }
        a.depth += gd * w;
        let fi = &feats.values[g.index * k..(g.index + 1) * k];
        for c in 0..k {
            facc[slot * k + c] += gf[c] * w;
        }
        let inv = 1.0 / (1.0 - alpha);
        let mut d_alpha = ga * t_n * inv + gd * (ti * g.depth - s_d * inv);
        for ch in 0..3 {
            d_alpha += gc[ch] * (ti * vc[ch] - s_c[ch] * inv) + gn[ch] * (ti * g.normal[ch] - s_n[ch] * inv);
        }
        for c in 0..k {
            d_alpha += gf[c] * (ti * fi[c] - s_f[c] * inv);
        }
        for ch in 0..3 {
            s_c[ch] += w * vc[ch];
            s_n[ch] += w * g.normal[ch];
        }
        s_d += w * g.depth;
        for c in 0..k {
            s_f[c] += w * fi[c];
        }
        if clamped {
            continue;
        }
        let e = power.exp();
        a.opacity += d_alpha * e;
        let d_power = d_alpha * alpha;
        let (dx, dy) = (q[0] - g.mean[0], q[1] - g.mean[1]);
        a.conic[0] += d_power * -0.5 * dx * dx;
        a.conic[1] += d_power * -dx * dy;
        a.conic[2] += d_power * -0.5 * dy * dy;
        a.mean[0] += d_power * (g.conic[0] * dx + g.conic[1] * dy);
        a.mean[1] += d_power * (g.conic[1] * dx + g.conic[2] * dy);
    }
}

fn mat2_mul(a: [[f64; 2]; 2], b: [[f64; 2]; 2]) -> [[f64; 2]; 2] {
    std::array::from_fn(|i| std::array::from_fn(|j| a[i][0] * b[0][j] + a[i][1] * b[1][j]))
}

/// Backpropagates one Gaussian's screen-space gradients to its parameters.
#[allow(clippy::too_many_arguments)]
fn gaussian_backward(
    g: &Gaussians,
    cam: &Camera,
    opts: &RenderOptions,
    pr: &Projected,
    f: &Frame,
    a: &G2,
    out: &mut Gradients,
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
            out.sh[(i * kc + k) * 3 + ch] += a.color[ch] * f.basis[k];
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
    out.opacity_logits[i] += a.opacity * f.aa * f.sigmoid * (1.0 - f.sigmoid);
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
        out.log_scales[i][k] += gs * f.s[k];
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
            out.rotations[i][c] += (gq[c] - qh[c] * dot) / nq;
        }
    }
    for c in 0..3 {
        out.means[i][c] += g_m[c];
    }
    out.mean2d_norm[i] += (a.mean[0] * a.mean[0] + a.mean[1] * a.mean[1]).sqrt();
}

/// Gradients of `sum(upstream * outputs)` for a render with the same inputs.
pub fn render_backward(
    g: &Gaussians,
    cam: &Camera,
    feats: &Features,
    opts: &RenderOptions,
    up: &Upstream,
) -> Gradients {
    let proj = project_all_full(g, cam, opts);
    let projected: Vec<Projected> = proj.iter().map(|(p, _)| *p).collect();
    let (w, h) = (cam.width as usize, cam.height as usize);
    let (tx, tiles) = bin(&projected, w, h, opts.smooth);
    let nrot: Option<[[f64; 3]; 3]> =
        opts.normals_world.then(|| std::array::from_fn(|a| std::array::from_fn(|b| cam.camera_from_world[a][b])));
    let k = feats.channels;
    let n = proj.len();
    // Each tile accumulates into its own small table (the Gaussians it touches), merged once.
    let per_tile: Vec<(Vec<usize>, Vec<G2>, Vec<f64>)> = tiles
        .par_iter()
        .enumerate()
        .map(|(ti, order)| {
            let (bx, by) = ((ti % tx) * TILE, (ti / tx) * TILE);
            let hot = hot(&projected, order);
            let mut acc = vec![G2::default(); order.len()];
            let mut facc = vec![0.0; order.len() * k];
            for y in by..(by + TILE).min(h) {
                for x in bx..(bx + TILE).min(w) {
                    pixel_backward(
                        [x as f64 + 0.5, y as f64 + 0.5],
                        y * w + x,
                        order,
                        &hot,
                        &proj,
                        feats,
                        opts,
                        up,
                        &nrot,
                        &mut acc,
                        &mut facc,
                    );
                }
            }
            (order.clone(), acc, facc)
        })
        .collect();
    let mut acc = vec![G2::default(); n];
    let mut facc = vec![0.0; n * k];
    for (order, a, fa) in per_tile {
        for (slot, &pi) in order.iter().enumerate() {
            let (x, y) = (&mut acc[pi], &a[slot]);
            for c in 0..2 {
                x.mean[c] += y.mean[c];
            }
            for c in 0..3 {
                x.conic[c] += y.conic[c];
                x.color[c] += y.color[c];
                x.normal[c] += y.normal[c];
            }
            x.opacity += y.opacity;
            x.depth += y.depth;
            for c in 0..k {
                facc[pi * k + c] += fa[slot * k + c];
            }
        }
    }
    let m = g.len();
    let mut out = Gradients {
        means: vec![[0.0; 3]; m],
        log_scales: vec![[0.0; 3]; m],
        rotations: vec![[0.0; 4]; m],
        opacity_logits: vec![0.0; m],
        sh: vec![0.0; g.sh.len()],
        features: vec![0.0; m * k],
        mean2d_norm: vec![0.0; m],
    };
    for (pi, (pr, f)) in proj.iter().enumerate() {
        gaussian_backward(g, cam, opts, pr, f, &acc[pi], &mut out);
        out.features[pr.index * k..(pr.index + 1) * k].copy_from_slice(&facc[pi * k..(pi + 1) * k]);
    }
    out
}
