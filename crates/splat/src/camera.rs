//! The rasterizer's camera: pinhole intrinsics, `camera_from_world` in OpenCV axes (x right,
//! y down, z forward), image size and near/far clipping. JSON (serde) for `render-ply`:
//! `{"width": 480, "height": 320, "fx": 400, "fy": 400, "cx": 240, "cy": 160,
//!   "camera_from_world": [[r00, r01, r02, tx], [r10, ...], [r20, ...], [0, 0, 0, 1]],
//!   "near": 0.01, "far": 1000}` with the matrix row-major.

use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// Row-major 4x4 rigid transform from world to OpenCV camera axes.
    pub camera_from_world: [[f64; 4]; 4],
    #[serde(default = "default_near")]
    pub near: f64,
    #[serde(default = "default_far")]
    pub far: f64,
}

fn default_near() -> f64 {
    0.01
}

fn default_far() -> f64 {
    1e4
}

impl Camera {
    /// A camera at the world origin looking down +z (world = camera axes), square pixels of
    /// focal length `focal` (pixels), principal point at the image centre, default near/far.
    pub fn at_origin(width: u32, height: u32, focal: f64) -> Camera {
        Camera {
            width,
            height,
            fx: focal,
            fy: focal,
            cx: width as f64 / 2.0,
            cy: height as f64 / 2.0,
            camera_from_world: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]],
            near: default_near(),
            far: default_far(),
        }
    }

    /// World point to camera axes.
    pub fn to_camera(&self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.camera_from_world;
        std::array::from_fn(|r| m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3])
    }

    /// Camera centre in the world: `-R^T t`.
    pub fn center(&self) -> [f64; 3] {
        let m = &self.camera_from_world;
        std::array::from_fn(|c| -(m[0][c] * m[0][3] + m[1][c] * m[1][3] + m[2][c] * m[2][3]))
    }

    /// Checks the numbers a renderer relies on; the message names the field.
    pub fn validate(&self) -> Result<(), String> {
        if self.width == 0 || self.height == 0 {
            return Err("width and height must be positive".into());
        }
        if !(self.fx > 0.0 && self.fy > 0.0 && self.fx.is_finite() && self.fy.is_finite()) {
            return Err("fx and fy must be positive finite numbers".into());
        }
        if !(self.cx.is_finite() && self.cy.is_finite()) {
            return Err("cx and cy must be finite".into());
        }
        if !(self.near > 0.0 && self.far > self.near) {
            return Err(format!("need 0 < near ({}) < far ({})", self.near, self.far));
        }
        let m = &self.camera_from_world;
        if m[3] != [0.0, 0.0, 0.0, 1.0] || m.iter().flatten().any(|v| !v.is_finite()) {
            return Err("camera_from_world must be a finite rigid 4x4 matrix with last row 0 0 0 1".into());
        }
        for i in 0..3 {
            for j in 0..3 {
                let dot: f64 = (0..3).map(|k| m[k][i] * m[k][j]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                if (dot - want).abs() > 1e-3 {
                    return Err("camera_from_world's rotation is not orthonormal".into());
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn center_and_validation() {
        let cam = Camera {
            width: 4,
            height: 4,
            fx: 1.0,
            fy: 1.0,
            cx: 2.0,
            cy: 2.0,
            camera_from_world: [
                [1.0, 0.0, 0.0, -1.0],
                [0.0, 1.0, 0.0, 2.0],
                [0.0, 0.0, 1.0, 3.0],
                [0.0, 0.0, 0.0, 1.0],
            ],
            near: 0.01,
            far: 100.0,
        };
        assert_eq!(cam.center(), [1.0, -2.0, -3.0]);
        assert_eq!(cam.to_camera(cam.center()), [0.0, 0.0, 0.0]);
        assert!(cam.validate().is_ok());
        let bad = Camera { near: 0.0, ..cam };
        assert!(bad.validate().unwrap_err().contains("near"));
    }
}
