//! From a scene camera at a frame to the rasterizer's camera: `camera_from_world` in OpenCV axes
//! is `cv_from_ego * ego_from_world` (`scene::Camera::cv_from_ego` holds the axis change), and the
//! intrinsics scale with the image (`u' = s u` for the top-left-corner pixel origin). Also the
//! world ray through a pixel centre, which the sky looks up.

use crate::error::ReconError;
use scene::Transform3;

/// A camera-frame normal in Waymo camera axes (the scene's convention, used by priors and ground
/// truth) re-expressed in the OpenCV axes the rasterizer renders normals in, through
/// `scene::frames::cv_from_waymo_camera` (the one place that defines the axis change).
pub fn cv_normal_from_waymo(n: [f32; 3]) -> [f64; 3] {
    let v = scene::frames::cv_from_waymo_camera().transform_vector(scene::glam::DVec3::new(
        n[0] as f64,
        n[1] as f64,
        n[2] as f64,
    ));
    v.to_array()
}

/// The image size at `scale` (at least one pixel).
pub fn scaled_size(width: u32, height: u32, scale: f64) -> (u32, u32) {
    (((width as f64 * scale).round() as u32).max(1), ((height as f64 * scale).round() as u32).max(1))
}

/// Refuses a training `scale` that shrinks a camera's view below [`crate::budget::MIN_VIEW_SIDE`]
/// pixels on a side (a side already shorter must stay at full size), naming the camera.
pub fn check_scale(cameras: &[scene::Camera], scale: f64) -> Result<(), ReconError> {
    let min = crate::budget::MIN_VIEW_SIDE;
    for cam in cameras {
        let (w, h) = scaled_size(cam.width, cam.height, scale);
        if w < min.min(cam.width) || h < min.min(cam.height) {
            let least = min as f64 / cam.width.min(cam.height).max(1) as f64;
            return Err(ReconError::Camera {
                camera: cam.name.clone(),
                detail: format!(
                    "scale {scale:e} makes its {}x{} images {w}x{h} pixels: a view must keep at least {min} \
                     pixels on a side (scale >= {least:.4} for this camera, whose shorter side is {} pixels)",
                    cam.width,
                    cam.height,
                    cam.width.min(cam.height)
                ),
            });
        }
    }
    Ok(())
}

/// The rasterizer camera of `cam` on an ego at `world_from_ego`, at `scale` of the image size.
/// Refuses a distorted camera (undistort at ingest: the rasterizer is pinhole).
pub fn splat_camera(cam: &scene::Camera, world_from_ego: &Transform3, scale: f64) -> Result<splat::Camera, ReconError> {
    if !cam.distortion.is_zero() {
        return Err(ReconError::Camera {
            camera: cam.name.clone(),
            detail: "has lens distortion; the rasterizer is pinhole (undistort the images at ingest)".into(),
        });
    }
    let (w, h) = scaled_size(cam.width, cam.height, scale);
    let (sx, sy) = (w as f64 / cam.width as f64, h as f64 / cam.height as f64);
    let cv_from_world = cam.cv_from_ego() * world_from_ego.inverse();
    let k = cam.intrinsics;
    Ok(splat::Camera {
        width: w,
        height: h,
        fx: k.fx * sx,
        fy: k.fy * sy,
        cx: k.cx * sx,
        cy: k.cy * sy,
        camera_from_world: cv_from_world.to_row_major(),
        near: 0.05,
        far: 1e4,
    })
}

/// The unit world direction of the ray through pixel centre `(x + 0.5, y + 0.5)`.
#[inline]
pub fn pixel_ray(cam: &splat::Camera, x: usize, y: usize) -> [f64; 3] {
    let d = [(x as f64 + 0.5 - cam.cx) / cam.fx, (y as f64 + 0.5 - cam.cy) / cam.fy, 1.0];
    let m = &cam.camera_from_world;
    // world = R^T cam
    let w: [f64; 3] = std::array::from_fn(|c| (0..3).map(|r| m[r][c] * d[r]).sum());
    let n = (w[0] * w[0] + w[1] * w[1] + w[2] * w[2]).sqrt();
    w.map(|v| v / n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn waymo_normals_become_opencv_normals() {
        // Waymo forward is OpenCV +z, left is -x, up is -y.
        assert_eq!(cv_normal_from_waymo([1.0, 0.0, 0.0]), [0.0, 0.0, 1.0]);
        assert_eq!(cv_normal_from_waymo([0.0, 1.0, 0.0]), [-1.0, 0.0, 0.0]);
        assert_eq!(cv_normal_from_waymo([0.0, 0.0, 1.0]), [0.0, -1.0, 0.0]);
    }

    #[test]
    fn a_world_point_lands_where_the_scene_camera_projects_it() {
        let cam = scene::Camera {
            name: "FRONT".into(),
            width: 640,
            height: 480,
            intrinsics: scene::Intrinsics { fx: 500.0, fy: 510.0, cx: 320.0, cy: 240.0 },
            distortion: Default::default(),
            ego_from_camera: Transform3::from_yaw_translation(0.1, DVec3::new(1.5, 0.2, 1.8)),
            rolling_shutter: Default::default(),
        };
        let world_from_ego = Transform3::from_yaw_translation(1.2, DVec3::new(100.0, -40.0, 3.0));
        let p_world = world_from_ego.transform_point(DVec3::new(20.0, 3.0, 1.0));
        let uv = cam.project_ego(world_from_ego.inverse().transform_point(p_world)).unwrap();
        let sc = splat_camera(&cam, &world_from_ego, 0.5).unwrap();
        let pc = sc.to_camera(p_world.into());
        let (u, v) = (sc.fx * pc[0] / pc[2] + sc.cx, sc.fy * pc[1] / pc[2] + sc.cy);
        assert!((u - uv.x * 0.5).abs() < 1e-9 && (v - uv.y * 0.5).abs() < 1e-9);
        // The pixel ray through that point points at it.
        let ray = pixel_ray(&sc, u.floor() as usize, v.floor() as usize);
        let to = (p_world - DVec3::from(sc.center())).normalize();
        assert!(ray[0] * to.x + ray[1] * to.y + ray[2] * to.z > 0.9999);
    }

    #[test]
    fn a_scale_that_shrinks_a_view_below_eight_pixels_is_refused_naming_the_camera() {
        let cam = |name: &str, width, height| scene::Camera {
            name: name.into(),
            width,
            height,
            intrinsics: scene::Intrinsics { fx: 50.0, fy: 50.0, cx: 32.0, cy: 24.0 },
            distortion: Default::default(),
            ego_from_camera: Transform3::IDENTITY,
            rolling_shutter: Default::default(),
        };
        let cams = [cam("FRONT", 64, 48), cam("SIDE", 96, 64)];
        assert!(check_scale(&cams, 0.5).is_ok());
        assert!(check_scale(&cams, 8.0 / 48.0).is_ok());
        let e = check_scale(&cams, 1e-300).unwrap_err().to_string();
        assert!(e.starts_with("camera FRONT: scale 1e-300 makes its 64x48 images 1x1 pixels"), "{e}");
        assert!(check_scale(&cams, 0.1).unwrap_err().to_string().contains("camera FRONT"));
        // A camera already smaller than 8 pixels trains at full size only.
        assert!(check_scale(&[cam("TINY", 6, 4)], 1.0).is_ok());
        assert!(check_scale(&[cam("TINY", 6, 4)], 0.5).is_err());
    }
}
