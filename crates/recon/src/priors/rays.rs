//! Pixel rays of a scene camera: the undistorted normalised coordinates `(x/z, y/z)` (OpenCV
//! axes) of every pixel centre `(u + 0.5, v + 0.5)`, and back-projection of a z-depth map to
//! camera-frame points. Distorted cameras (Waymo) are inverted by fixed-point iteration.

use scene::glam::{DVec2, DVec3};
use scene::Camera;

/// Per-pixel normalised coordinates of one camera, row-major.
pub struct Rays {
    pub width: usize,
    pub height: usize,
    pub xy: Vec<[f64; 2]>,
}

impl Rays {
    pub fn of(camera: &Camera) -> Rays {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let k = camera.intrinsics;
        let d = camera.distortion;
        let xy = (0..w * h)
            .map(|i| {
                let m = DVec2::new(((i % w) as f64 + 0.5 - k.cx) / k.fx, ((i / w) as f64 + 0.5 - k.cy) / k.fy);
                let mut n = m;
                if !d.is_zero() {
                    for _ in 0..20 {
                        n += m - d.apply(n);
                    }
                }
                [n.x, n.y]
            })
            .collect();
        Rays { width: w, height: h, xy }
    }

    /// The camera-frame (OpenCV axes) point of pixel `i` at z-depth `z`.
    pub fn point(&self, i: usize, z: f32) -> DVec3 {
        let [x, y] = self.xy[i];
        DVec3::new(x, y, 1.0) * z as f64
    }

    /// Back-projects a depth map (0 = none) to OpenCV camera points (`None` where no depth).
    pub fn back_project(&self, depth: &[f32]) -> Vec<Option<DVec3>> {
        depth.iter().enumerate().map(|(i, &z)| (z > 0.0 && z.is_finite()).then(|| self.point(i, z))).collect()
    }
}
