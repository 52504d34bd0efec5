//! EWA projection of 3D Gaussians into a camera (all in f64; the model stores f32).
//!
//! For a Gaussian with mean `m`, rotation `R_g`, scales `s` (exp of the log-scales):
//! `p = camera_from_world * m` (OpenCV axes); culled unless `near < p.z < far` and its screen box
//! (below) reaches the image ([`on_screen`]).
//! `Sigma3 = R_g diag(s^2) R_g^T`, `W` = the camera's rotation,
//! `J = [[fx/z, 0, -fx x/z^2], [0, fy/z, -fy y/z^2]]` with `x/z` and `y/z` clamped to 1.3x the
//! field of view on each side of the principal point (as gsplat does, for stability off-screen), `Sigma2 = J W Sigma3 W^T J^T`.
//! Low-pass: `Sigma2 += 0.3 I`; in antialiased mode the opacity is multiplied by
//! `sqrt(det Sigma2_before / det Sigma2_after)`. The screen `extent` is the bounding box of the
//! ellipse where alpha would fall below 1/255 (`d^T Sigma2^-1 d = 2 ln(255 o)`), so no pixel
//! beyond it can contribute and the tiled renderer equals a per-pixel brute-force one.

use crate::camera::Camera;
use crate::gaussians::{sigmoid, Gaussians};
use crate::sh::basis;

pub const EPS2D: f64 = 0.3;
pub const ALPHA_MIN: f64 = 1.0 / 255.0;

/// A Gaussian on screen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projected {
    pub index: usize,
    /// Pixel coordinates of the mean (pixel centres at integer + 0.5).
    pub mean: [f64; 2],
    /// Inverse 2D covariance `[a, b, c]` for `[[a, b], [b, c]]`.
    pub conic: [f64; 3],
    /// Camera-space depth (z).
    pub depth: f64,
    /// Opacity after activation (and the antialiasing factor).
    pub opacity: f64,
    /// Half-widths (x, y) of the bounding box of the ellipse where alpha >= 1/255:
    /// `sqrt(2 ln(255 o) Sigma2_xx)`, `sqrt(2 ln(255 o) Sigma2_yy)`.
    pub extent: [f64; 2],
    /// RGB from the SH at this view direction (before clamping at 0).
    pub color: [f64; 3],
    /// Unit normal in the camera frame: the axis of the smallest scale, facing the camera.
    pub normal: [f64; 3],
}

/// Rotation matrix (rows) of a quaternion `w x y z` (normalised here).
pub fn rotation(q: [f64; 4]) -> [[f64; 3]; 3] {
    let [w, x, y, z] = q;
    let n = (w * w + x * x + y * y + z * z).sqrt();
    let (w, x, y, z) = if n > 0.0 { (w / n, x / n, y / n, z / n) } else { (1.0, 0.0, 0.0, 0.0) };
    [
        [1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)],
        [2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)],
        [2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)],
    ]
}

/// What the backward pass needs from the forward projection of one Gaussian.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// Camera-space point.
    pub p: [f64; 3],
    /// Gaussian rotation (rows) and scales.
    pub r: [[f64; 3]; 3],
    pub s: [f64; 3],
    pub sig3: [[f64; 3]; 3],
    /// `T = J W` (2x3) and the Jacobian's clamped flags (x, y).
    pub t: [[f64; 3]; 2],
    pub clamped: [bool; 2],
    /// 2D covariance before and after the low-pass.
    pub cov0: [[f64; 2]; 2],
    pub cov: [[f64; 2]; 2],
    /// Sigmoid of the opacity logit, and the antialiasing factor (1 when off).
    pub sigmoid: f64,
    pub aa: f64,
    /// Unit view direction (world), its length, and the SH basis there.
    pub dir: [f64; 3],
    pub dist: f64,
    pub basis: [f64; 16],
    /// Axis of the smallest scale and whether the normal was flipped to face the camera.
    pub kmin: usize,
    pub flipped: bool,
}

/// Whether the alpha >= 1/255 box around `mean` (half-widths `extent`) reaches the image: a
/// Gaussian whose box misses it is culled, as 3DGS and gsplat do (no radius, not visible). It
/// could reach no pixel, and counting it as drawn would dilute the density statistics (their
/// mean gradient per view seen) by every view that merely had it in front of the camera. A
/// superset of the pixels `tiles::alpha_at` can accept (pixel centres lie in `[0.5, w - 0.5]`).
pub fn on_screen(mean: [f64; 2], extent: [f64; 2], cam: &Camera) -> bool {
    mean[0] + extent[0] >= 0.0
        && mean[0] - extent[0] < cam.width as f64
        && mean[1] + extent[1] >= 0.0
        && mean[1] - extent[1] < cam.height as f64
}

/// A cheap early form of [`on_screen`]'s cull, before the covariance: true only where the box
/// surely misses the image. The box's half-width along x is `sqrt(level (Sigma2_xx + 0.3))`, with
/// `level <= 2 ln 255` (opacity at most 1) and `Sigma2_xx = T_x Sigma3 T_x^T <= |T_x|^2 s_max^2`
/// (`T_x` the first row of `J W`, at the clamped `x / z` as in the projection; `Sigma3`'s largest
/// eigenvalue is `s_max^2`); likewise along y. Padded (relative 1e-6 and 1e-6 px) so rounding never
/// culls what the exact test keeps; NaN culls nothing here (the exact path decides).
pub fn surely_off_screen(p: [f64; 3], s_max: f64, cam: &Camera) -> bool {
    ScreenBound::of(cam).surely_off(p, s_max)
}

/// [`surely_off_screen`]'s per-camera constants (the clamp limits, the rotation, the
/// intrinsics), for a caller that tests every Gaussian of a model against one camera: the same
/// arithmetic, the four divisions of the limits done once.
#[derive(Clone, Copy, Debug)]
pub struct ScreenBound {
    /// `x / z` and `y / z` clamp limits: 1.3x the field of view on each side of the principal
    /// point (the projection's and the chain rule's too).
    pub lim_x: [f64; 2],
    pub lim_y: [f64; 2],
    rot: [[f64; 3]; 3],
    f: [f64; 2],
    c: [f64; 2],
    size: [f64; 2],
}

impl ScreenBound {
    pub fn of(cam: &Camera) -> Self {
        let (w_px, h_px) = (cam.width as f64, cam.height as f64);
        let w = &cam.camera_from_world;
        ScreenBound {
            lim_x: [-1.3 * cam.cx / cam.fx, 1.3 * (w_px - cam.cx) / cam.fx],
            lim_y: [-1.3 * cam.cy / cam.fy, 1.3 * (h_px - cam.cy) / cam.fy],
            rot: std::array::from_fn(|a| [w[a][0], w[a][1], w[a][2]]),
            f: [cam.fx, cam.fy],
            c: [cam.cx, cam.cy],
            size: [w_px, h_px],
        }
    }

    /// [`surely_off_screen`] for camera-frame mean `p` and largest scale `s_max`.
    pub fn surely_off(&self, p: [f64; 3], s_max: f64) -> bool {
        const LEVEL_MAX: f64 = 11.082_6; // 2 ln 255 = 11.08253, rounded up
        let z = p[2];
        let (ux, uy) = (p[0] / z, p[1] / z);
        let [w_px, h_px] = self.size;
        let cx_ = ux.clamp(self.lim_x[0], self.lim_x[1]);
        let cy_ = uy.clamp(self.lim_y[0], self.lim_y[1]);
        let w = &self.rot;
        // |T_row|^2 for J_row = (f / z) (e_axis - u e_z): (f / z)^2 |W_axis - u W_z|^2.
        let row = |f: f64, axis: usize, u: f64| {
            let v = [w[axis][0] - u * w[2][0], w[axis][1] - u * w[2][1], w[axis][2] - u * w[2][2]];
            (f / z) * (f / z) * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
        };
        let s2 = s_max * s_max;
        let bound = |t2: f64| (LEVEL_MAX * (t2 * s2 + EPS2D)).sqrt() * (1.0 + 1e-6) + 1e-6;
        let (bx, by) = (bound(row(self.f[0], 0, cx_)), bound(row(self.f[1], 1, cy_)));
        let (mx, my) = (self.f[0] * ux + self.c[0], self.f[1] * uy + self.c[1]);
        mx + bx < 0.0 || mx - bx >= w_px || my + by < 0.0 || my - by >= h_px
    }
}

/// Projects Gaussian `i`; `None` if culled or degenerate (never NaN out).
pub fn project(g: &Gaussians, i: usize, cam: &Camera, antialiased: bool) -> Option<Projected> {
    project_full(g, i, cam, antialiased, false).map(|(p, _)| p)
}

/// [`project`] with the intermediates; `smooth` keeps faint Gaussians (for gradient checks).
pub fn project_full(
    g: &Gaussians,
    i: usize,
    cam: &Camera,
    antialiased: bool,
    smooth: bool,
) -> Option<(Projected, Frame)> {
    let m = g.means[i];
    let p = cam.to_camera(m);
    if !(p[2] > cam.near && p[2] < cam.far) || p.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let s = g.log_scales[i].map(f64::exp);
    if s.iter().any(|v| !v.is_finite()) || (!smooth && surely_off_screen(p, s[0].max(s[1]).max(s[2]), cam)) {
        return None;
    }
    let r = rotation(g.rotations[i]);
    // Sigma3 = R diag(s^2) R^T
    let mut sig3 = [[0.0; 3]; 3];
    for a in 0..3 {
        for b in 0..3 {
            sig3[a][b] = (0..3).map(|k| r[a][k] * s[k] * s[k] * r[b][k]).sum();
        }
    }
    let w = &cam.camera_from_world;
    let wr: [[f64; 3]; 3] = std::array::from_fn(|a| [w[a][0], w[a][1], w[a][2]]);
    let z = p[2];
    let (w_px, h_px) = (cam.width as f64, cam.height as f64);
    let (ux, uy) = (p[0] / z, p[1] / z);
    let cx_ = ux.clamp(-1.3 * cam.cx / cam.fx, 1.3 * (w_px - cam.cx) / cam.fx);
    let cy_ = uy.clamp(-1.3 * cam.cy / cam.fy, 1.3 * (h_px - cam.cy) / cam.fy);
    let clamped = [cx_ != ux, cy_ != uy];
    let (tx, ty) = (cx_ * z, cy_ * z);
    let j = [[cam.fx / z, 0.0, -cam.fx * tx / (z * z)], [0.0, cam.fy / z, -cam.fy * ty / (z * z)]];
    // T = J W (2x3)
    let t: [[f64; 3]; 2] = std::array::from_fn(|a| std::array::from_fn(|b| (0..3).map(|k| j[a][k] * wr[k][b]).sum()));
    let mut cov = [[0.0; 2]; 2];
    for a in 0..2 {
        for b in 0..2 {
            cov[a][b] = (0..3).map(|k| (0..3).map(|l| t[a][k] * sig3[k][l] * t[b][l]).sum::<f64>()).sum();
        }
    }
    let det0 = cov[0][0] * cov[1][1] - cov[0][1] * cov[1][0];
    let cov0 = cov;
    cov[0][0] += EPS2D;
    cov[1][1] += EPS2D;
    let det = cov[0][0] * cov[1][1] - cov[0][1] * cov[1][0];
    if det.is_nan() || det <= 0.0 || !det.is_finite() {
        return None;
    }
    let sig = sigmoid(g.opacity_logits[i]);
    let aa = if antialiased { (det0.max(0.0) / det).sqrt() } else { 1.0 };
    let opacity = sig * aa;
    if opacity.is_nan() || (!smooth && opacity < ALPHA_MIN) || opacity <= 0.0 {
        return None;
    }
    let conic = [cov[1][1] / det, -cov[0][1] / det, cov[0][0] / det];
    let level = 2.0 * (255.0 * opacity).ln().max(0.0);
    let extent = [(level * cov[0][0]).sqrt(), (level * cov[1][1]).sqrt()];
    let mean = [cam.fx * p[0] / z + cam.cx, cam.fy * p[1] / z + cam.cy];
    if !smooth && !on_screen(mean, extent, cam) {
        return None;
    }
    // Colour from SH at the view direction (world frame, camera centre to mean).
    let c = cam.center();
    let d = [m[0] - c[0], m[1] - c[1], m[2] - c[2]];
    let dn = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt().max(1e-12);
    let b = basis(g.sh_degree, [d[0] / dn, d[1] / dn, d[2] / dn]);
    let sh = g.sh_of(i);
    let color: [f64; 3] = std::array::from_fn(|ch| 0.5 + (0..g.coeffs()).map(|k| b[k] * sh[k * 3 + ch]).sum::<f64>());
    // Normal: the rotation axis of the smallest scale, in camera axes, facing the camera.
    let kmin = (0..3).min_by(|a, b| s[*a].total_cmp(&s[*b])).unwrap_or(0);
    let axis = [r[0][kmin], r[1][kmin], r[2][kmin]];
    let mut n: [f64; 3] = std::array::from_fn(|a| (0..3).map(|k| wr[a][k] * axis[k]).sum());
    let flipped = n[0] * p[0] + n[1] * p[1] + n[2] * p[2] > 0.0;
    if flipped {
        n = n.map(|v| -v);
    }
    let ok = mean.iter().chain(&conic).chain(&color).chain(&n).all(|v| v.is_finite())
        && extent.iter().all(|v| v.is_finite());
    let frame = Frame {
        p,
        r,
        s,
        sig3,
        t,
        clamped,
        cov0,
        cov,
        sigmoid: sig,
        aa,
        dir: [d[0] / dn, d[1] / dn, d[2] / dn],
        dist: dn,
        basis: b,
        kmin,
        flipped,
    };
    ok.then_some((Projected { index: i, mean, conic, depth: z, opacity, extent, color, normal: n }, frame))
}
