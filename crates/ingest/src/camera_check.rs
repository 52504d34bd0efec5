//! Camera calibrations checked at ingest, before any image is decoded or undistorted: the size
//! against the pixel budget ([`scene::camera::MAX_CAMERA_PIXELS`]), the intrinsics
//! ([`check_intrinsics`]: finite focal lengths between [`MIN_FOCAL_PER_WIDTH`] and
//! [`MAX_FOCAL_PER_WIDTH`] image widths, the principal point within an image size of the
//! image), and the distortion coefficients. Distortion must keep the
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

/// The smallest focal length accepted (fx and fy), in image widths: 1e-2 is a field of view of
/// 178 degrees, beyond any pinhole camera.
pub const MIN_FOCAL_PER_WIDTH: f64 = 1e-2;
/// The largest focal length accepted (fx and fy), in image widths: 1e3 is a field of view of
/// 0.06 degrees, a telescope.
pub const MAX_FOCAL_PER_WIDTH: f64 = 1e3;

/// Refuses implausible pinhole intrinsics for a `width` x `height` image: `fx`, `fy` finite and
/// within [[`MIN_FOCAL_PER_WIDTH`], [`MAX_FOCAL_PER_WIDTH`]] times the width, `cx` within
/// [-width, 2 width] and `cy` within [-height, 2 height]. The error is the field (`"fx"`, `"fy"`,
/// `"cx"`, `"cy"`) and a message with its value and the allowed range.
pub fn check_intrinsics(k: &Intrinsics, width: u32, height: u32) -> Result<(), (&'static str, String)> {
    let (w, h) = (f64::from(width), f64::from(height));
    let (f_lo, f_hi) = (MIN_FOCAL_PER_WIDTH * w, MAX_FOCAL_PER_WIDTH * w);
    let focal = format!("1e-2 to 1e3 times the image width {width} px");
    let checks = [
        ("fx", k.fx, f_lo, f_hi, focal.clone()),
        ("fy", k.fy, f_lo, f_hi, focal),
        ("cx", k.cx, -w, 2.0 * w, format!("-1 to 2 times the image width {width} px")),
        ("cy", k.cy, -h, 2.0 * h, format!("-1 to 2 times the image height {height} px")),
    ];
    for (field, v, lo, hi, why) in checks {
        if !(v.is_finite() && v >= lo && v <= hi) {
            return Err((
                field,
                format!("{field} = {v:?} px is outside the allowed range [{lo:?}, {hi:?}] px ({why})"),
            ));
        }
    }
    Ok(())
}

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
    fn implausible_intrinsics_are_refused_naming_the_field_value_and_range() {
        check_intrinsics(&K, 64, 48).unwrap();
        // KITTI 06 and PandaSet 002's front camera.
        check_intrinsics(&Intrinsics { fx: 707.0912, fy: 707.0912, cx: 601.8873, cy: 183.1104 }, 1226, 370).unwrap();
        check_intrinsics(&Intrinsics { fx: 985.00655, fy: 985.00455, cx: 485.0001, cy: 241.6494 }, 960, 540).unwrap();
        let k = |fx, fy, cx, cy| Intrinsics { fx, fy, cx, cy };
        let (f, m) = check_intrinsics(&k(1e-300, 500.0, 480.0, 270.0), 960, 540).unwrap_err();
        assert_eq!(f, "fx");
        assert!(m.contains("1e-300") && m.contains("[9.6, 960000.0]"), "{m}");
        let (f, m) = check_intrinsics(&k(500.0, 500.0, -900000.0, 270.0), 960, 540).unwrap_err();
        assert_eq!(f, "cx");
        assert!(m.contains("-900000.0") && m.contains("[-960.0, 1920.0]"), "{m}");
        assert_eq!(check_intrinsics(&k(500.0, f64::NAN, 480.0, 270.0), 960, 540).unwrap_err().0, "fy");
        assert_eq!(check_intrinsics(&k(500.0, 1e7, 480.0, 270.0), 960, 540).unwrap_err().0, "fy");
        assert_eq!(check_intrinsics(&k(500.0, 500.0, 480.0, 1081.0), 960, 540).unwrap_err().0, "cy");
        // The bounds themselves pass.
        check_intrinsics(&k(9.6, 960000.0, -960.0, 1080.0), 960, 540).unwrap();
    }

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
