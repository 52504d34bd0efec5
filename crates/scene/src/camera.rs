//! Cameras: pinhole intrinsics, OpenCV radial/tangential distortion, rolling-shutter direction
//! and the `ego_from_camera` extrinsic (Waymo camera axes, see `frames`).
//!
//! Projection follows Waymo's model exactly: a camera-frame point (x fwd, y left, z up) has
//! normalised coordinates `xn = -y/x`, `yn = -z/x` (equivalently OpenCV `x/z`, `y/z`), then
//! `r2 = xn^2 + yn^2`, `d = 1 + k1 r2 + k2 r2^2 + k3 r2^3`,
//! `xd = d xn + 2 p1 xn yn + p2 (r2 + 2 xn^2)`, `yd = d yn + p1 (r2 + 2 yn^2) + 2 p2 xn yn`,
//! `u = fx xd + cx`, `v = fy yd + cy` (pixels, origin at the top-left pixel's corner).

use crate::frames::cv_from_waymo_camera;
use crate::transform::Transform3;
use glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};

/// Pinhole intrinsics in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

/// OpenCV distortion coefficients (k1, k2, p1, p2, k3).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Distortion {
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    pub k3: f64,
}

impl Distortion {
    /// Applies the distortion to normalised coordinates.
    pub fn apply(&self, n: DVec2) -> DVec2 {
        let r2 = n.length_squared();
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        DVec2::new(
            radial * n.x + 2.0 * self.p1 * n.x * n.y + self.p2 * (r2 + 2.0 * n.x * n.x),
            radial * n.y + self.p1 * (r2 + 2.0 * n.y * n.y) + 2.0 * self.p2 * n.x * n.y,
        )
    }

    pub fn is_zero(&self) -> bool {
        *self == Self::default()
    }
}

/// Rolling-shutter read-out direction (Waymo `RollingShutterReadOutDirection`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RollingShutter {
    #[default]
    Unknown,
    TopToBottom,
    LeftToRight,
    BottomToTop,
    RightToLeft,
    GlobalShutter,
}

/// One camera rig member. `ego_from_camera` uses Waymo camera axes (x forward, y left, z up).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub intrinsics: Intrinsics,
    #[serde(default)]
    pub distortion: Distortion,
    pub ego_from_camera: Transform3,
    #[serde(default)]
    pub rolling_shutter: RollingShutter,
}

/// Most pixels a camera may have: 4096 x 4096 (16.8 Mpx). Driving-log cameras are 0.5-8 Mpx
/// (Waymo 1920 x 1280, PandaSet 1920 x 1080, 4K 8.3 Mpx); training keeps about 100 bytes per
/// pixel per view and the priors a few more, so a calibration claiming 100000 x 100000 pixels
/// would ask for terabytes. Every reader checks a camera against this before allocating.
pub const MAX_CAMERA_PIXELS: u64 = 4096 * 4096;
/// Longest side of a camera in pixels (a 16384 x 1024 panorama is within the pixel budget).
pub const MAX_CAMERA_SIDE: u64 = 16384;

/// `width x height` must have pixels, each side at most [`MAX_CAMERA_SIDE`] and at most
/// [`MAX_CAMERA_PIXELS`] in all; the message says which limit was passed.
pub fn check_camera_size(width: u64, height: u64) -> Result<(), String> {
    let pixels = width.saturating_mul(height);
    if pixels == 0 {
        return Err(format!("{width}x{height} has no pixels"));
    }
    if width.max(height) > MAX_CAMERA_SIDE {
        return Err(format!("{width}x{height}: a side longer than the {MAX_CAMERA_SIDE} pixels a camera may have"));
    }
    if pixels > MAX_CAMERA_PIXELS {
        return Err(format!(
            "{width}x{height} is {pixels} pixels, more than the {MAX_CAMERA_PIXELS} (4096 x 4096) a camera may have"
        ));
    }
    Ok(())
}

/// Intrinsics must be finite with positive focal lengths.
pub fn check_intrinsics(k: &Intrinsics) -> Result<(), String> {
    if [k.fx, k.fy, k.cx, k.cy].iter().any(|v| !v.is_finite()) {
        return Err(format!("fx, fy, cx, cy must be finite, got {}, {}, {}, {}", k.fx, k.fy, k.cx, k.cy));
    }
    if !(k.fx > 0.0 && k.fy > 0.0) {
        return Err(format!("focal lengths must be positive, got fx = {}, fy = {}", k.fx, k.fy));
    }
    Ok(())
}

/// Points closer than this along the optical axis are treated as behind the camera.
pub const MIN_DEPTH: f64 = 1e-6;

impl Camera {
    /// `cv_from_ego`: ego-frame points to OpenCV camera axes.
    pub fn cv_from_ego(&self) -> Transform3 {
        cv_from_waymo_camera() * self.ego_from_camera.inverse()
    }

    /// Projects a point in OpenCV camera axes to pixels; `None` if it is not in front.
    pub fn project_cv(&self, p: DVec3) -> Option<DVec2> {
        if p.z.is_nan() || p.z <= MIN_DEPTH {
            return None;
        }
        let d = self.distortion.apply(DVec2::new(p.x / p.z, p.y / p.z));
        let k = &self.intrinsics;
        Some(DVec2::new(k.fx * d.x + k.cx, k.fy * d.y + k.cy))
    }

    /// Projects an ego-frame point to pixels; `None` if it is behind the camera.
    pub fn project_ego(&self, p_ego: DVec3) -> Option<DVec2> {
        self.project_cv(self.cv_from_ego().transform_point(p_ego))
    }

    pub fn contains_pixel(&self, uv: DVec2) -> bool {
        uv.x >= 0.0 && uv.y >= 0.0 && uv.x <= self.width as f64 && uv.y <= self.height as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> Camera {
        Camera {
            name: "FRONT".into(),
            width: 1920,
            height: 1280,
            intrinsics: Intrinsics { fx: 2000.0, fy: 2000.0, cx: 960.0, cy: 640.0 },
            distortion: Distortion::default(),
            ego_from_camera: Transform3::from_yaw_translation(0.0, DVec3::new(1.5, 0.0, 2.0)),
            rolling_shutter: RollingShutter::TopToBottom,
        }
    }

    #[test]
    fn projects_like_waymo() {
        let cam = camera();
        // 20 m ahead of the camera, 1 m left, 0.5 m up (camera at x=1.5, z=2 on the ego).
        let uv = cam.project_ego(DVec3::new(21.5, 1.0, 2.5)).unwrap();
        // xn = -y/x = -0.05, yn = -z/x = -0.025.
        assert!((uv - DVec2::new(960.0 - 100.0, 640.0 - 50.0)).length() < 1e-9);
        assert!(cam.project_ego(DVec3::new(-5.0, 0.0, 2.0)).is_none());
    }

    #[test]
    fn camera_budget() {
        check_camera_size(1920, 1280).unwrap();
        check_camera_size(16384, 1024).unwrap();
        assert!(check_camera_size(100_000, 100_000).unwrap_err().contains("a side longer than the 16384"));
        assert!(check_camera_size(4097, 4097).unwrap_err().contains("16785409 pixels, more than the 16777216"));
        assert!(check_camera_size(2147483647, 2147483647).is_err() && check_camera_size(0, 48).is_err());
        check_intrinsics(&camera().intrinsics).unwrap();
        let bad = Intrinsics { fx: -1.0, ..camera().intrinsics };
        assert!(check_intrinsics(&bad).unwrap_err().contains("fx = -1"));
        assert!(check_intrinsics(&Intrinsics { cy: f64::NAN, ..bad }).unwrap_err().contains("finite"));
    }

    #[test]
    fn distortion_matches_hand_values() {
        let d = Distortion { k1: 0.1, k2: 0.01, p1: 0.001, p2: -0.002, k3: 0.0 };
        let n = DVec2::new(0.2, -0.1);
        let r2: f64 = 0.05;
        let radial = 1.0 + 0.1 * r2 + 0.01 * r2 * r2;
        let xd = radial * 0.2 + 2.0 * 0.001 * 0.2 * -0.1 + -0.002 * (r2 + 2.0 * 0.04);
        let yd = radial * -0.1 + 0.001 * (r2 + 2.0 * 0.01) + 2.0 * -0.002 * 0.2 * -0.1;
        let out = d.apply(n);
        assert!((out - DVec2::new(xd, yd)).length() < 1e-15);
    }
}
