//! The projection for the f32 path: one Gaussian onto the screen, the data the tile kernels read (`Hot32`) and
//! what the chain rule needs later (`Frame32`, kept so the backward pass does not project again).
//!
//! The same EWA formulas as `project::project_full` (low-pass 0.3, antialiasing factor, Jacobian
//! clamped at 1.3x the field of view, extent where alpha falls below 1/255, smallest-scale normal
//! facing the camera). The per-Gaussian arithmetic stays in f64 (it is a small share of the time,
//! and f32 would lose what matters: world coordinates can be large, the pixel position must be
//! good to 1e-4 px, and a very flat Gaussian's small eigenvalue and the antialiasing determinant
//! vanish in f32 rounding); its results are stored in f32 for the tile kernels and the f32 chain
//! rule. Culling is the reference's, decided in f64:
//! outside `near < z < far`, non-finite values, a non-positive 2D determinant, opacity below
//! 1/255, a screen box that misses the image (`project::on_screen`).

use crate::camera::Camera;
use crate::gaussians::Gaussians;
use crate::project::{on_screen, rotation, ScreenBound, EPS2D};
use crate::sh::basis;

pub const ALPHA_MIN: f32 = 1.0 / 255.0;

/// One projected Gaussian as the tile kernels read it: one cache line.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
pub struct Hot32 {
    pub mean: [f32; 2],
    /// Inverse 2D covariance `[a, b, c]` for `[[a, b], [b, c]]`.
    pub conic: [f32; 3],
    pub opacity: f32,
    /// Half-widths of the bounding box of the alpha >= 1/255 ellipse.
    pub extent: [f32; 2],
    /// `ln(1 / (255 o))`: below this exponent alpha < 1/255.
    pub power_min: f32,
    /// SH colour before clamping at 0.
    pub color: [f32; 3],
    pub depth: f32,
    /// Unit normal in the camera frame.
    pub normal: [f32; 3],
}

impl Hot32 {
    /// Row spans as in `tiles::Hot::span`, padded more for f32 (relative 1e-4): at row offset
    /// `dy` the columns `dx = -s0 dy +- sqrt(s2 + s1 dy^2)`.
    #[inline(always)]
    pub fn span(&self) -> [f32; 3] {
        let [a, b, c] = self.conic;
        let level = -2.0 * self.power_min * (1.0 + 1e-4) + 1e-6;
        [b / a, (b * b - a * c) / (a * a), level / a]
    }
}

/// What the chain rule needs from the projection of one Gaussian (f32 `project::Frame`).
#[derive(Clone, Copy, Debug, Default)]
pub struct Frame32 {
    pub p: [f32; 3],
    pub r: [[f32; 3]; 3],
    pub s: [f32; 3],
    pub sig3: [[f32; 3]; 3],
    pub t: [[f32; 3]; 2],
    pub clamped: [bool; 2],
    pub cov0: [[f32; 2]; 2],
    pub cov: [[f32; 2]; 2],
    /// Their determinants, computed in f64 (the antialiasing gradient divides by them).
    pub det0: f32,
    pub det: f32,
    pub sigmoid: f32,
    pub aa: f32,
    pub dir: [f32; 3],
    pub dist: f32,
    pub kmin: u8,
    pub flipped: bool,
}

/// Per-camera constants of the projection.
#[derive(Clone, Copy, Debug)]
pub struct CamConst {
    pub wr: [[f32; 3]; 3],
    pub center: [f64; 3],
    pub fx: f32,
    pub fy: f32,
    /// The early cull's constants, with the clamp limits.
    pub bound: ScreenBound,
}

impl CamConst {
    pub fn of(cam: &Camera) -> Self {
        let w = &cam.camera_from_world;
        CamConst {
            wr: std::array::from_fn(|a| std::array::from_fn(|b| w[a][b] as f32)),
            center: cam.center(),
            fx: cam.fx as f32,
            fy: cam.fy as f32,
            bound: ScreenBound::of(cam),
        }
    }
}

/// Projects Gaussian `i`; `None` if culled or degenerate (never NaN out).
pub fn project32(g: &Gaussians, i: usize, cam: &Camera, cc: &CamConst, antialiased: bool) -> Option<(Hot32, Frame32)> {
    let m = g.means[i];
    let p64 = cam.to_camera(m);
    if !(p64[2] > cam.near && p64[2] < cam.far) || p64.iter().any(|v| !v.is_finite()) {
        return None;
    }
    // The reference's early cull with one exp instead of three (most Gaussians end here): exp is
    // monotone, so the largest scale is the exp of the largest log-scale and every scale is
    // finite when it is (a NaN log-scale culls, as its NaN scale does in the reference).
    let ls = g.log_scales[i];
    if ls.iter().any(|v| v.is_nan()) {
        return None;
    }
    let s_max = ls[0].max(ls[1]).max(ls[2]).exp();
    if !s_max.is_finite() || cc.bound.surely_off(p64, s_max) {
        return None;
    }
    let s64 = ls.map(f64::exp);
    let p = p64.map(|v| v as f32);
    // The covariance chain in f64: a very flat Gaussian's small eigenvalue (scale ratio below
    // about 3e-4) and the antialiasing determinant would be lost to f32 rounding.
    let r64 = rotation(g.rotations[i]);
    let mut sig3 = [[0.0f64; 3]; 3];
    for a in 0..3 {
        for b in a..3 {
            let v = (0..3).map(|k| r64[a][k] * s64[k] * s64[k] * r64[b][k]).sum::<f64>();
            sig3[a][b] = v;
            sig3[b][a] = v;
        }
    }
    let z = p64[2];
    let (ux, uy) = (p64[0] / z, p64[1] / z);
    let cx_ = ux.clamp(cc.bound.lim_x[0], cc.bound.lim_x[1]);
    let cy_ = uy.clamp(cc.bound.lim_y[0], cc.bound.lim_y[1]);
    let clamped = [cx_ != ux, cy_ != uy];
    let (fx, fy) = (cam.fx, cam.fy);
    let j = [[fx / z, 0.0, -fx * cx_ / z], [0.0, fy / z, -fy * cy_ / z]];
    let wr = &cam.camera_from_world;
    let t: [[f64; 3]; 2] =
        std::array::from_fn(|a| std::array::from_fn(|b| j[a][0] * wr[0][b] + j[a][1] * wr[1][b] + j[a][2] * wr[2][b]));
    let ts: [[f64; 3]; 2] = std::array::from_fn(|a| {
        std::array::from_fn(|l| t[a][0] * sig3[0][l] + t[a][1] * sig3[1][l] + t[a][2] * sig3[2][l])
    });
    let dot3 = |u: &[f64; 3], v: &[f64; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    let (c00, c01, c11) = (dot3(&ts[0], &t[0]), dot3(&ts[0], &t[1]), dot3(&ts[1], &t[1]));
    let det0 = c00 * c11 - c01 * c01;
    let (a00, a11) = (c00 + EPS2D, c11 + EPS2D);
    let det = a00 * a11 - c01 * c01;
    if det.is_nan() || det <= 0.0 || !det.is_finite() {
        return None;
    }
    let sig = 1.0 / (1.0 + (-g.opacity_logits[i]).exp());
    let aa = if antialiased { (det0.max(0.0) / det).sqrt() } else { 1.0 };
    let opacity64 = sig * aa;
    if opacity64.is_nan() || opacity64 < ALPHA_MIN as f64 || opacity64 <= 0.0 {
        return None;
    }
    let opacity = opacity64 as f32;
    let r: [[f32; 3]; 3] = r64.map(|row| row.map(|v| v as f32));
    let s = s64.map(|v| v as f32);
    let conic = [(a11 / det) as f32, (-c01 / det) as f32, (a00 / det) as f32];
    let level = 2.0 * (255.0 * opacity64).ln().max(0.0);
    let extent64 = [(level * a00).sqrt(), (level * a11).sqrt()];
    let mean64 = [cam.fx * p64[0] / p64[2] + cam.cx, cam.fy * p64[1] / p64[2] + cam.cy];
    if !on_screen(mean64, extent64, cam) {
        return None;
    }
    let (extent, mean) = (extent64.map(|v| v as f32), mean64.map(|v| v as f32));
    let c = cc.center;
    let d = [m[0] - c[0], m[1] - c[1], m[2] - c[2]];
    let dn = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-12);
    let dir = [d[0] / dn, d[1] / dn, d[2] / dn];
    let b = basis(g.sh_degree, dir);
    let sh = g.sh_of(i);
    let kc = g.coeffs();
    let color: [f32; 3] = std::array::from_fn(|ch| (0.5 + (0..kc).map(|k| b[k] * sh[k * 3 + ch]).sum::<f64>()) as f32);
    let kmin = (0..3).min_by(|a, b| s64[*a].total_cmp(&s64[*b])).unwrap_or(0);
    let axis = [r64[0][kmin], r64[1][kmin], r64[2][kmin]];
    let n64: [f64; 3] = std::array::from_fn(|a| wr[a][0] * axis[0] + wr[a][1] * axis[1] + wr[a][2] * axis[2]);
    let flipped = n64[0] * p64[0] + n64[1] * p64[1] + n64[2] * p64[2] > 0.0;
    let mut n = n64.map(|v| v as f32);
    if flipped {
        n = n.map(|v| -v);
    }
    let power_min = (ALPHA_MIN / opacity).ln();
    let hot = Hot32 { mean, conic, opacity, extent, power_min, color, depth: p[2], normal: n };
    let ok = mean.iter().chain(&conic).chain(&color).chain(&n).chain(&extent).chain(&hot.span()).all(|v| v.is_finite());
    if !ok {
        return None;
    }
    let frame = Frame32 {
        p,
        r,
        s,
        sig3: sig3.map(|row| row.map(|v| v as f32)),
        t: t.map(|row| row.map(|v| v as f32)),
        clamped,
        cov0: [[c00 as f32, c01 as f32], [c01 as f32, c11 as f32]],
        cov: [[a00 as f32, c01 as f32], [c01 as f32, a11 as f32]],
        det0: det0 as f32,
        det: det as f32,
        sigmoid: sig as f32,
        aa: aa as f32,
        dir: dir.map(|v| v as f32),
        dist: dn as f32,
        kmin: kmin as u8,
        flipped,
    };
    Some((hot, frame))
}
