//! Frame conventions: the one place that says which way every axis points.
//!
//! * **World**: the log's own fixed frame (Waymo global / WOMD map frame), right-handed, z up.
//! * **Ego** (Waymo "vehicle" frame): origin at the ego's reference point, x forward, y left, z up.
//!   `world_from_ego` is Waymo's frame `pose`.
//! * **Waymo camera**: x forward (optical axis), y left, z up. Calibrations give `ego_from_camera`.
//! * **OpenCV camera** (`cv`): x right, y down, z forward. Projection and rendering use it.
//!   KITTI's rectified cameras use these axes (`waymo_camera_from_kitti_camera`).
//! * **OpenGL / NeRF camera** (`opengl`): x right, y up, z backward (instant-ngp, nerfstudio
//!   `transforms.json`).
//! * **KITTI world**: the left camera at frame 0 (x right, y down, z forward); `world_from_kitti_world`
//!   turns it z-up with the origin on the road below that camera.
//! * **NeRF world** (instant-ngp `transforms.json`): already z-up (colmap2nerf rotates the mean
//!   camera up to +z); `world_from_nerf_world` is the identity, units are the file's own.
//! * **PandaSet LiDAR** (`pandaset_lidar`): the roof LiDAR's pose, which PandaSet gives in place
//!   of a vehicle frame; z up, the vehicle's forward axis is +y (established from the motion by
//!   `ingest::pandaset`). The ego origin is on the road below it. PandaSet's world is the LiDAR
//!   at frame 0 (z up, metres) and is used as is. A PandaSet cuboid's `yaw` is 0 when its length
//!   points along world +y (`heading_from_pandaset_yaw`).
//! * **Box**: a tracked object's frame: origin at the box centre, x along its length (heading),
//!   y left, z up. `world_from_box` comes from the centre and the heading (yaw about world z).
//!
//! Headings are radians, counter-clockwise about +z, wrapped to (-pi, pi].

use crate::transform::Transform3;
use glam::{DMat3, DVec3};

/// Rotation taking Waymo camera axes (x fwd, y left, z up) to OpenCV axes (x right, y down,
/// z fwd): `x_cv = -y_w`, `y_cv = -z_w`, `z_cv = x_w`.
pub fn cv_from_waymo_camera() -> Transform3 {
    Transform3::from_rotation_translation(
        DMat3::from_cols(
            DVec3::new(0.0, 0.0, 1.0),  // image of waymo +x
            DVec3::new(-1.0, 0.0, 0.0), // image of waymo +y
            DVec3::new(0.0, -1.0, 0.0), // image of waymo +z
        ),
        DVec3::ZERO,
    )
}

/// `waymo_camera_from_cv`, the inverse of [`cv_from_waymo_camera`].
pub fn waymo_camera_from_cv() -> Transform3 {
    cv_from_waymo_camera().inverse()
}

/// `waymo_camera_from_kitti_camera`: KITTI camera axes are OpenCV's (x right, y down, z forward).
pub fn waymo_camera_from_kitti_camera() -> Transform3 {
    waymo_camera_from_cv()
}

/// KITTI's documented height of the left camera above the road (m).
pub const KITTI_CAMERA_HEIGHT_M: f64 = 1.65;

/// `world_from_kitti_world`: KITTI odometry's world is the left camera at frame 0 (OpenCV axes,
/// y down). Our world has x = KITTI z (forward at frame 0), y = -KITTI x (left), z = -KITTI y (up)
/// and its origin `camera_height_m` below that camera, so the road at frame 0 is near z = 0.
pub fn world_from_kitti_world(camera_height_m: f64) -> Transform3 {
    Transform3::from_rotation_translation(waymo_camera_from_cv().rotation(), DVec3::new(0.0, 0.0, camera_height_m))
}

/// Rotation taking OpenGL/NeRF camera axes (x right, y up, z backward) to Waymo camera axes
/// (x forward, y left, z up): `x_w = -z_gl`, `y_w = -x_gl`, `z_w = y_gl`.
pub fn waymo_camera_from_opengl_camera() -> Transform3 {
    Transform3::from_rotation_translation(
        DMat3::from_cols(
            DVec3::new(0.0, -1.0, 0.0), // image of gl +x (right)
            DVec3::new(0.0, 0.0, 1.0),  // image of gl +y (up)
            DVec3::new(-1.0, 0.0, 0.0), // image of gl +z (backward)
        ),
        DVec3::ZERO,
    )
}

/// `world_from_nerf_world`: instant-ngp / nerfstudio worlds written by colmap2nerf are z-up
/// already, so this is the identity (kept as a named step; units stay the file's own).
pub fn world_from_nerf_world() -> Transform3 {
    Transform3::IDENTITY
}

/// `pandaset_lidar_from_ego`: the ego frame (x forward, y left, z up, origin on the road) in the
/// frame of PandaSet's LiDAR pose, given the LiDAR-frame unit vector the vehicle drives along
/// (horizontal: +x, -x, +y or -y) and the height of the LiDAR pose's origin above the road.
pub fn pandaset_lidar_from_ego(forward_in_lidar: DVec3, lidar_above_road_m: f64) -> Transform3 {
    let up = DVec3::Z;
    let x = forward_in_lidar.normalize();
    let y = up.cross(x);
    Transform3::from_rotation_translation(DMat3::from_cols(x, y, up), DVec3::new(0.0, 0.0, -lidar_above_road_m))
}

/// The forward axis of PandaSet's LiDAR pose as established on the shared sequence 002 (the
/// ego's motion runs along +y to within 1.5 degrees on every frame).
pub const PANDASET_LIDAR_FORWARD: DVec3 = DVec3::Y;

/// Our box heading (yaw of the length axis from world +x) from a PandaSet cuboid `yaw` (0 when
/// the length points along world +y, counter-clockwise positive): `yaw + pi/2`, wrapped.
pub fn heading_from_pandaset_yaw(yaw: f64) -> f64 {
    wrap_angle(yaw + std::f64::consts::FRAC_PI_2)
}

/// `world_from_box` for a box with centre `center` and heading `heading` (yaw about world z).
pub fn world_from_box(center: DVec3, heading: f64) -> Transform3 {
    Transform3::from_yaw_translation(heading, center)
}

/// Wraps an angle to (-pi, pi].
pub fn wrap_angle(a: f64) -> f64 {
    let two_pi = std::f64::consts::TAU;
    let mut w = a.rem_euclid(two_pi);
    if w > std::f64::consts::PI {
        w -= two_pi;
    }
    w
}

/// Re-expresses a heading measured in `source` (about its z axis) in `target`: the yaw of the
/// source-frame direction `(cos h, sin h, 0)` after rotation, projected on the target's xy plane.
pub fn heading_in(target_from_source: &Transform3, heading: f64) -> f64 {
    let d = target_from_source.transform_vector(DVec3::new(heading.cos(), heading.sin(), 0.0));
    d.y.atan2(d.x)
}

/// A road vehicle's silhouette as two boxes in its box frame, for judging where a vehicle is
/// drawn on real images: a car is not its bounding box (the box's hull, seen at an angle, holds
/// the air over the bonnet and boot and beside the cabin). The lower body is the whole footprint
/// up to [`PROFILE_BELT`] of the height; the cabin above it spans [`PROFILE_CABIN_X`] of the
/// length (front, back, as fractions from the centre) and [`PROFILE_CABIN_WIDTH`] of the width.
/// Returns the eight corners of each, in the box frame.
pub fn vehicle_profile_corners(size_lwh: [f64; 3]) -> [[DVec3; 8]; 2] {
    let [l, w, h] = size_lwh;
    let belt = -h / 2.0 + PROFILE_BELT * h;
    let sub = |x: (f64, f64), hw: f64, z: (f64, f64)| -> [DVec3; 8] {
        std::array::from_fn(|i| {
            DVec3::new(
                if i & 1 == 0 { x.1 } else { x.0 },
                if i & 2 == 0 { hw } else { -hw },
                if i & 4 == 0 { z.1 } else { z.0 },
            )
        })
    };
    [
        sub((-l / 2.0, l / 2.0), w / 2.0, (-h / 2.0, belt)),
        sub((-PROFILE_CABIN_X.1 * l, PROFILE_CABIN_X.0 * l), PROFILE_CABIN_WIDTH * w / 2.0, (belt, h / 2.0)),
    ]
}

/// Belt line of [`vehicle_profile_corners`], as a fraction of the height from the bottom.
pub const PROFILE_BELT: f64 = 0.55;
/// The cabin's reach from the box centre towards the front and the back, as fractions of the length.
pub const PROFILE_CABIN_X: (f64, f64) = (0.25, 0.4);
/// The cabin's width as a fraction of the box's.
pub const PROFILE_CABIN_WIDTH: f64 = 0.85;

/// The eight corners of a box (length along x, width along y, height along z) in the box frame.
pub fn box_corners(size_lwh: [f64; 3]) -> [DVec3; 8] {
    let [l, w, h] = size_lwh.map(|v| v / 2.0);
    let mut out = [DVec3::ZERO; 8];
    for (i, c) in out.iter_mut().enumerate() {
        *c = DVec3::new(
            if i & 1 == 0 { l } else { -l },
            if i & 2 == 0 { w } else { -w },
            if i & 4 == 0 { h } else { -h },
        );
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pandaset_lidar_frame_round_trip() {
        let lidar_from_ego = pandaset_lidar_from_ego(PANDASET_LIDAR_FORWARD, 0.35);
        // Ego forward (+x) is the LiDAR's +y, ego left (+y) its -x, up stays up.
        assert!((lidar_from_ego.transform_vector(DVec3::X) - DVec3::Y).length() < 1e-15);
        assert!((lidar_from_ego.transform_vector(DVec3::Y) - DVec3::NEG_X).length() < 1e-15);
        assert!((lidar_from_ego.transform_vector(DVec3::Z) - DVec3::Z).length() < 1e-15);
        // The ego origin is on the road, 0.35 m below the LiDAR pose's origin.
        assert!((lidar_from_ego.transform_point(DVec3::ZERO) - DVec3::new(0.0, 0.0, -0.35)).length() < 1e-15);
        assert!((lidar_from_ego.rotation().determinant() - 1.0).abs() < 1e-15);
        let world_from_lidar = Transform3::from_rotation_translation(
            DMat3::from_euler(glam::EulerRot::ZYX, -0.79, 0.03, 0.01),
            DVec3::new(3.0, -4.0, 0.2),
        );
        let world_from_ego = world_from_lidar * lidar_from_ego;
        let p = DVec3::new(12.0, -3.0, 1.0);
        let back = (world_from_ego * lidar_from_ego.inverse() * world_from_lidar.inverse()).transform_point(p);
        assert!((back - p).length() < 1e-12);
        // A cuboid yaw of 0 points along world +y: heading pi/2; yaw pi/2 points along -x.
        assert!((heading_from_pandaset_yaw(0.0) - std::f64::consts::FRAC_PI_2).abs() < 1e-15);
        assert!((heading_from_pandaset_yaw(std::f64::consts::FRAC_PI_2).abs() - std::f64::consts::PI).abs() < 1e-12);
    }

    #[test]
    fn waymo_forward_is_cv_depth() {
        let cv_from_w = cv_from_waymo_camera();
        // A point 10 m ahead, 2 m to the left and 1 m up in Waymo camera axes ...
        let p = cv_from_w.transform_point(DVec3::new(10.0, 2.0, 1.0));
        // ... is at depth 10, left of centre (negative x) and above centre (negative y) in OpenCV.
        assert_eq!(p, DVec3::new(-2.0, -1.0, 10.0));
        // Normalised coordinates agree with Waymo's xn = -y/x, yn = -z/x.
        assert!((p.x / p.z - (-2.0 / 10.0)).abs() < 1e-15);
        assert!((p.y / p.z - (-1.0 / 10.0)).abs() < 1e-15);
    }

    #[test]
    fn cv_round_trip() {
        let p = DVec3::new(0.3, -7.0, 2.5);
        let q = waymo_camera_from_cv().transform_point(cv_from_waymo_camera().transform_point(p));
        assert!((p - q).length() < 1e-15);
        assert!(cv_from_waymo_camera().orthonormality_error() < 1e-15);
        // It is a proper rotation (right-handed to right-handed).
        assert!((cv_from_waymo_camera().rotation().determinant() - 1.0).abs() < 1e-15);
    }

    #[test]
    fn box_and_ego_round_trip() {
        let world_from_ego = Transform3::from_rotation_translation(
            DMat3::from_euler(glam::EulerRot::ZYX, 2.5, 0.02, -0.01),
            DVec3::new(1000.0, -200.0, 5.0),
        );
        let ego_from_world = world_from_ego.inverse();
        let center_ego = DVec3::new(12.0, -3.0, 0.8);
        let heading_ego = 0.4;
        let center_world = world_from_ego.transform_point(center_ego);
        let heading_world = heading_in(&world_from_ego, heading_ego);
        assert!((ego_from_world.transform_point(center_world) - center_ego).length() < 1e-9);
        assert!((heading_in(&ego_from_world, heading_world) - heading_ego).abs() < 1e-3);
        // With no pitch/roll the heading round trip is exact.
        let flat = Transform3::from_yaw_translation(2.5, DVec3::new(3.0, 4.0, 0.0));
        let hw = heading_in(&flat, heading_ego);
        assert!((wrap_angle(hw - 2.5 - heading_ego)).abs() < 1e-12);
        assert!((heading_in(&flat.inverse(), hw) - heading_ego).abs() < 1e-12);
    }

    #[test]
    fn box_corners_span_the_size() {
        let c = box_corners([4.0, 2.0, 1.5]);
        let max = c.iter().fold(DVec3::splat(f64::MIN), |m, p| m.max(*p));
        let min = c.iter().fold(DVec3::splat(f64::MAX), |m, p| m.min(*p));
        assert_eq!(max - min, DVec3::new(4.0, 2.0, 1.5));
        let wb = world_from_box(DVec3::new(5.0, 0.0, 0.0), std::f64::consts::FRAC_PI_2);
        // The box's front (+x) points along world +y after a 90 degree heading.
        let front = wb.transform_point(DVec3::new(2.0, 0.0, 0.0));
        assert!((front - DVec3::new(5.0, 2.0, 0.0)).length() < 1e-12);
    }

    #[test]
    fn kitti_axes_land_z_up() {
        let w = world_from_kitti_world(KITTI_CAMERA_HEIGHT_M);
        // 10 m ahead of the frame-0 camera (KITTI +z) is world +x at camera height.
        assert!((w.transform_point(DVec3::new(0.0, 0.0, 10.0)) - DVec3::new(10.0, 0.0, 1.65)).length() < 1e-12);
        // The road 1.65 m below the camera (KITTI +y is down) is world z = 0.
        assert!(w.transform_point(DVec3::new(0.0, 1.65, 0.0)).length() < 1e-12);
        // KITTI +x (right) is world -y.
        assert!((w.transform_vector(DVec3::X) - DVec3::new(0.0, -1.0, 0.0)).length() < 1e-12);
        let c = waymo_camera_from_kitti_camera();
        assert!((c.transform_point(DVec3::new(1.0, 2.0, 5.0)) - DVec3::new(5.0, -1.0, -2.0)).length() < 1e-12);
        assert!((c.rotation().determinant() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn opengl_camera_axes() {
        let r = waymo_camera_from_opengl_camera();
        // OpenGL cameras look down -z: that is Waymo +x; up is +y in both (Waymo z).
        assert!((r.transform_vector(DVec3::new(0.0, 0.0, -1.0)) - DVec3::X).length() < 1e-12);
        assert!((r.transform_vector(DVec3::Y) - DVec3::Z).length() < 1e-12);
        assert!((r.transform_vector(DVec3::X) - DVec3::new(0.0, -1.0, 0.0)).length() < 1e-12);
        assert!((r.rotation().determinant() - 1.0).abs() < 1e-12);
        assert_eq!(world_from_nerf_world(), Transform3::IDENTITY);
    }

    #[test]
    fn wrap_angle_range() {
        assert!((wrap_angle(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap_angle(-0.5) + 0.5).abs() < 1e-15);
        assert!((wrap_angle(7.0) - (7.0 - std::f64::consts::TAU)).abs() < 1e-12);
    }
}
