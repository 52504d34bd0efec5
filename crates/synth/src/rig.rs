//! The camera rig: Waymo's camera names and roughly Waymo's layout (FRONT, FRONT_LEFT and
//! FRONT_RIGHT yawed +-45 degrees, SIDE_LEFT and SIDE_RIGHT +-90 degrees), all level, about
//! 2 m above the ground, pinhole with zero distortion and a 50 degree horizontal field of view.

use glam::DVec3;
use scene::{Camera, Distortion, Intrinsics, RollingShutter, Transform3};

/// Camera names in rig order; `--cameras n` takes the first `n`.
pub const CAMERA_NAMES: [&str; 5] = ["FRONT", "FRONT_LEFT", "FRONT_RIGHT", "SIDE_LEFT", "SIDE_RIGHT"];
/// Horizontal field of view of every camera (degrees).
pub const HFOV_DEG: f64 = 50.0;
/// Camera height above the ground (m); the ego origin is on the ground.
pub const CAMERA_HEIGHT: f64 = 2.0;

/// `(x, y, yaw in degrees)` of each camera on the ego.
const MOUNTS: [(f64, f64, f64); 5] =
    [(1.6, 0.0, 0.0), (1.5, 0.35, 45.0), (1.5, -0.35, -45.0), (1.2, 0.9, 90.0), (1.2, -0.9, -90.0)];

/// The first `count` cameras of the rig at `width` x `height` pixels (square pixels, principal
/// point at the image centre, global shutter: every pixel sees the same instant).
pub fn cameras(count: usize, width: u32, height: u32) -> Vec<Camera> {
    let f = (width as f64 / 2.0) / (HFOV_DEG.to_radians() / 2.0).tan();
    CAMERA_NAMES
        .iter()
        .zip(MOUNTS)
        .take(count)
        .map(|(name, (x, y, yaw))| Camera {
            name: (*name).to_string(),
            width,
            height,
            intrinsics: Intrinsics { fx: f, fy: f, cx: width as f64 / 2.0, cy: height as f64 / 2.0 },
            distortion: Distortion::default(),
            ego_from_camera: Transform3::from_yaw_translation(yaw.to_radians(), DVec3::new(x, y, CAMERA_HEIGHT)),
            rolling_shutter: RollingShutter::GlobalShutter,
        })
        .collect()
}
