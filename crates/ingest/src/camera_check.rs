//! Camera calibrations checked at ingest, before any image is decoded or undistorted: the size
//! against the pixel budget ([`scene::camera::MAX_CAMERA_PIXELS`]), the intrinsics (finite,
//! positive focal lengths), and the distortion coefficients. Distortion must keep the
//! undistortion map usable: over a grid covering the image, every output pixel's source in the
//! distorted image lies within [`MAX_REACH`] image sizes beyond the border (`k1 = 1e6` sends
//! every pixel kilometres away and the image comes out black), and the map does not fold
//! (its Jacobian determinant stays positive: a polynomial past its turning point shows one
//! scene point twice).

use crate::undistort::source_position_at;
use scene::{Distortion, Intrinsics};

/// How far beyond the image a source position may lie, in image widths / heights.
pub const MAX_REACH: f64 = 1.0;
/// Grid intervals per side at which the map is checked.
const GRID: usize = 32;

/// The name and value of the largest coefficient, to name in errors.
pub fn dominant_coefficient(d: &Distortion) -> (&'static str, f64) {
    let all = [("k1", d.k1), ("k2", d.k2), ("k3", d.k3), ("p1", d.p1), ("p2", d.p2)];
    all.into_iter().fold(("k1", d.k1), |best, c| if c.1.abs() > best.1.abs() { c } else { best })
}

/// Refuses distortion that sends pixels far outside the image or folds the map; the message
/// names the pixel and where it would come from.
pub fn check_distortion(k: &Intrinsics, d: &Distortion, width: u32, height: u32) -> Result<(), String> {
    let all = [d.k1, d.k2, d.k3, d.p1, d.p2];
    if all.iter().any(|v| !v.is_finite()) {
        return Err("distortion coefficients must be finite".into());
    }
    if d.is_zero() {
        return Ok(());
    }
    let (w, h) = (f64::from(width), f64::from(height));
    let inside = |x: f64, lo: f64, hi: f64| x.is_finite() && x >= lo && x <= hi;
    let eps = 0.5;
    for i in 0..=GRID {
        for j in 0..=GRID {
            let (u, v) = (i as f64 * w / GRID as f64, j as f64 * h / GRID as f64);
            let s = source_position_at(k, d, u, v);
            if !(inside(s.x, -MAX_REACH * w, (1.0 + MAX_REACH) * w)
                && inside(s.y, -MAX_REACH * h, (1.0 + MAX_REACH) * h))
            {
                return Err(format!(
                    "pixel ({u:.0}, {v:.0}) of the undistorted {width}x{height} image would come from ({:.3e}, {:.3e}), \
                     more than {MAX_REACH} image size outside the image (the undistorted image would be black)",
                    s.x, s.y
                ));
            }
            let du = source_position_at(k, d, u + eps, v) - s;
            let dv = source_position_at(k, d, u, v + eps) - s;
            if du.x * dv.y - du.y * dv.x <= 0.0 {
                return Err(format!(
                    "the distortion folds the image over itself near pixel ({u:.0}, {v:.0}) (the undistortion map is \
                     not one-to-one there)"
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const K: Intrinsics = Intrinsics { fx: 50.0, fy: 50.0, cx: 32.0, cy: 24.0 };

    #[test]
    fn usual_distortion_passes_and_degenerate_is_refused() {
        check_distortion(&K, &Distortion::default(), 64, 48).unwrap();
        // Waymo FRONT-like and a strong wide-angle barrel.
        let waymo = Distortion { k1: 0.04, k2: -0.3, p1: 0.0005, p2: -0.0003, k3: 0.0 };
        let wf = Intrinsics { fx: 2060.0, fy: 2060.0, cx: 960.0, cy: 640.0 };
        check_distortion(&wf, &waymo, 1920, 1280).unwrap();
        check_distortion(&K, &Distortion { k1: -0.25, k2: 0.08, ..Default::default() }, 64, 48).unwrap();
        let huge = Distortion { k1: 1e6, ..Default::default() };
        let e = check_distortion(&K, &huge, 64, 48).unwrap_err();
        assert!(e.contains("would come from") && e.contains("black"), "{e}");
        assert_eq!(dominant_coefficient(&huge), ("k1", 1e6));
        // k1 = -2 turns the radial factor negative inside the image: a fold.
        let fold = Distortion { k1: -2.0, ..Default::default() };
        let e = check_distortion(&K, &fold, 64, 48).unwrap_err();
        assert!(e.contains("folds"), "{e}");
        assert!(check_distortion(&K, &Distortion { p1: f64::NAN, ..Default::default() }, 64, 48).is_err());
    }
}
