//! The ego frame of a PandaSet log, which has none of its own: the vehicle's forward axis in
//! the LiDAR frame, from the LiDAR's motion, and the LiDAR's height above the road, from the
//! sweeps' ground points (`scene::frames::pandaset_lidar_from_ego` combines the two). Kept apart
//! from the file reading because both are estimates with their own failure modes (no horizontal
//! motion, motion along no axis, no ground in view), each handled here.

use scene::frames::PANDASET_LIDAR_FORWARD;
use scene::glam::DVec3;
use scene::Transform3;

/// Below this much horizontal driving (m, in the LiDAR's x-y plane) the forward axis cannot be
/// told from the motion.
pub const MIN_PATH_FOR_AXIS_M: f64 = 1.0;
/// Below this mean resultant length of the step directions (1: every step the same way, 0:
/// as much back as forth) the motion has no direction to take the forward axis from.
pub const MIN_MEAN_RESULTANT: f64 = 0.1;

/// The vehicle's forward axis in the LiDAR frame, from the motion (nearest of +-x, +-y).
pub fn forward_axis(world_from_lidar: &[Transform3]) -> Result<DVec3, String> {
    let mut sum = DVec3::ZERO;
    let mut path = 0.0;
    let mut steps = 0usize;
    for w in world_from_lidar.windows(2) {
        let d = w[1].translation() - w[0].translation();
        if d.length() > 0.02 {
            let local = w[0].inverse().transform_vector(d);
            sum += local.normalize();
            path += local.truncate().length();
            steps += 1;
        }
    }
    if !(sum.is_finite() && path.is_finite()) {
        return Err(format!("the LiDAR poses give a motion that is not finite ({sum}, {path} m)"));
    }
    if path < MIN_PATH_FOR_AXIS_M {
        tracing::warn!(
            path_m = path,
            "the ego barely moves horizontally; taking PandaSet's documented forward axis (+y)"
        );
        return Ok(PANDASET_LIDAR_FORWARD);
    }
    let horizontal = DVec3::new(sum.x, sum.y, 0.0);
    let resultant = horizontal.length() / steps as f64;
    if resultant.is_nan() || resultant < MIN_MEAN_RESULTANT {
        return Err(format!(
            "the ego's {steps} steps ({path:.1} m) have no mean direction (mean resultant length {resultant:.3} < \
             {MIN_MEAN_RESULTANT}: as much back as forth), so its forward axis cannot be told"
        ));
    }
    let mean = horizontal.normalize();
    let axes = [DVec3::X, DVec3::NEG_X, DVec3::Y, DVec3::NEG_Y];
    let best = axes.into_iter().max_by(|a, b| a.dot(mean).total_cmp(&b.dot(mean))).unwrap_or(DVec3::Y);
    let along = best.dot(mean);
    if along.is_nan() || along < 30f64.to_radians().cos() {
        return Err(format!("the ego's mean motion {mean:.3} (LiDAR frame) runs along no LiDAR axis"));
    }
    if best != PANDASET_LIDAR_FORWARD {
        tracing::warn!(axis = %best, "the ego drives along a LiDAR axis other than PandaSet's usual +y");
    }
    Ok(best)
}

const LOWEST_M: f64 = -4.0;
const BIN_M: f64 = 0.05;
const BINS: usize = 100; // -4.0 .. +1.0 m

/// The height bin of `z` (m, LiDAR frame), if it is in -4 .. +1 m. The index is clamped: for z
/// just below 1 m, `(z + 4) / 0.05` rounds to 100.
fn bin_of(z: f64) -> Option<usize> {
    (z > LOWEST_M && z < LOWEST_M + BINS as f64 * BIN_M).then(|| (((z - LOWEST_M) / BIN_M) as usize).min(BINS - 1))
}

/// Height of the LiDAR pose's origin above the road in one sweep: the mode (5 cm bins) of the
/// heights of the points within 3 m sideways and 15 m along the forward axis.
pub fn lidar_height_in(points_lidar: impl IntoIterator<Item = DVec3>, forward: DVec3) -> Option<f64> {
    let side = DVec3::Z.cross(forward);
    let mut bins = [0usize; BINS];
    for p in points_lidar {
        if p.dot(forward).abs() < 15.0 && p.dot(side).abs() < 3.0 {
            if let Some(i) = bin_of(p.z) {
                bins[i] += 1;
            }
        }
    }
    let (i, n) = bins.iter().enumerate().max_by_key(|(_, n)| **n)?;
    (*n >= 50).then(|| -(LOWEST_M + (i as f64 + 0.5) * BIN_M))
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::glam::DMat3;

    #[test]
    fn height_bins_hold_every_height_in_range() {
        let top = 1.0 - 2f64.powi(-53);
        assert_eq!(bin_of(top), Some(BINS - 1), "(z + 4) / 0.05 = {}", (top + 4.0) / 0.05);
        assert_eq!(bin_of(-4.0 + 1e-15), Some(0));
        for z in [1.0, -4.0, f64::MAX, -f64::MAX, f64::INFINITY, f64::NEG_INFINITY, f64::NAN] {
            assert_eq!(bin_of(z), None, "{z}");
        }
        let pts = (0..60).map(|i| DVec3::new(0.01 * i as f64, 1.0, top));
        let h = lidar_height_in(pts, DVec3::Y).unwrap();
        assert!((h + 0.975).abs() < 1e-12, "{h}");
    }

    fn at(p: [f64; 3]) -> Transform3 {
        Transform3::from_rotation_translation(DMat3::IDENTITY, DVec3::from(p))
    }

    #[test]
    fn forward_axis_needs_horizontal_motion_with_a_direction() {
        let along_y: Vec<_> = (0..5).map(|k| at([0.0, k as f64, 0.0])).collect();
        assert_eq!(forward_axis(&along_y), Ok(DVec3::Y));
        let along_neg_x: Vec<_> = (0..5).map(|k| at([-(k as f64), 0.1, 0.0])).collect();
        assert_eq!(forward_axis(&along_neg_x), Ok(DVec3::NEG_X));
        // Straight up: no horizontal motion, the documented axis (the mean was NaN before).
        let up: Vec<_> = (0..5).map(|k| at([0.0, 0.0, k as f64])).collect();
        assert_eq!(forward_axis(&up), Ok(PANDASET_LIDAR_FORWARD));
        let back_and_forth = [at([0.0, 0.0, 0.0]), at([0.0, 2.0, 0.0]), at([0.0, 0.0, 0.0])];
        let e = forward_axis(&back_and_forth).unwrap_err();
        assert!(e.contains("no mean direction"), "{e}");
        let diagonal: Vec<_> = (0..5).map(|k| at([k as f64, k as f64, 0.0])).collect();
        assert!(forward_axis(&diagonal).unwrap_err().contains("no LiDAR axis"));
        let broken = [at([0.0, 0.0, 0.0]), at([0.0, f64::INFINITY, 0.0])];
        assert!(forward_axis(&broken).unwrap_err().contains("not finite"));
    }
}
