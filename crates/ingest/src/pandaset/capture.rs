//! When a PandaSet cuboid was seen, so that its box can be put on the frame's clock.
//!
//! Cuboids are drawn on a LiDAR sweep, and the sweep turns through 360 degrees in a frame
//! period: a box shows where its object was when the beam crossed the object's azimuth, not at
//! the frame's time. The cameras are fired as the sweep passes them, so the capture time at an
//! azimuth is read off the rig: each camera gives one point (the azimuth of its optical axis in
//! the ego frame, the mean offset of its image times from the frame times). On PandaSet 002 the
//! front camera fires 49.8 ms before the frame time, the front-left (+57.8 degrees) 60.6 ms and
//! the front-right (-57.8 degrees) 39.1 ms before it: the sweep turns clockwise seen from above.
//! Projected as they are, the LiDAR points of the car passing on the left at frame 40 cover it in
//! the front image up to its bumper; carried to the frame time they fall 0.4 m short of it, so boxes
//! belong to the capture time, not the frame time (docs/pandaset.md).
//!
//! The clock is linear in azimuth between neighbouring cameras and holds the nearest end
//! camera's offset outside them (behind the car, where no camera looks, nothing better is known).
//! A box is then carried to its frame's time along its velocity (`cuboids::tracks`).

use scene::glam::DVec3;

/// Capture-time offsets from the frame time (s) at camera azimuths (rad, counter-clockwise from
/// the ego's forward axis), sorted by azimuth.
#[derive(Clone, Debug, PartialEq)]
pub struct CaptureClock {
    points: Vec<(f64, f64)>,
}

impl CaptureClock {
    /// From each camera's optical axis in the ego frame and its image times, against the
    /// frames' times (`image_times[c][k]` belongs to frame k). Cameras pointing straight up or
    /// down (no azimuth) are left out; without any camera the offset is zero everywhere.
    pub fn from_cameras(cameras: &[(DVec3, &[f64])], frame_times: &[f64]) -> CaptureClock {
        let mut points: Vec<(f64, f64)> = cameras
            .iter()
            .filter(|(axis, times)| axis.truncate().length() > 1e-6 && !times.is_empty())
            .map(|(axis, times)| {
                let n = times.len().min(frame_times.len());
                let mean = (0..n).map(|k| times[k] - frame_times[k]).sum::<f64>() / n.max(1) as f64;
                (axis.y.atan2(axis.x), mean)
            })
            .collect();
        points.sort_by(|a, b| a.0.total_cmp(&b.0));
        CaptureClock { points }
    }

    /// The capture time's offset from the frame time (s) for an object at `azimuth` (rad).
    pub fn offset_at(&self, azimuth: f64) -> f64 {
        let p = &self.points;
        match p.iter().position(|(a, _)| *a >= azimuth) {
            None => p.last().map_or(0.0, |q| q.1),
            Some(0) => p[0].1,
            Some(i) => {
                let ((a0, t0), (a1, t1)) = (p[i - 1], p[i]);
                let w = if a1 > a0 { (azimuth - a0) / (a1 - a0) } else { 0.0 };
                t0 + w * (t1 - t0)
            }
        }
    }

    /// The offset for a point `ego` in the ego frame of its frame.
    pub fn offset_of(&self, ego: DVec3) -> f64 {
        if ego.truncate().length() < 1e-9 {
            return self.offset_at(0.0);
        }
        self.offset_at(ego.y.atan2(ego.x))
    }

    /// (azimuth in degrees, offset in ms) per camera, for logs and docs.
    pub fn table(&self) -> Vec<(f64, f64)> {
        self.points.iter().map(|(a, t)| (a.to_degrees(), t * 1e3)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn clock() -> CaptureClock {
        let deg = |d: f64| DVec3::new(d.to_radians().cos(), d.to_radians().sin(), 0.0);
        let frames = [10.0, 10.1];
        let (front, left, right) = ([9.95, 10.05], [9.94, 10.04], [9.96, 10.06]);
        CaptureClock::from_cameras(&[(deg(0.0), &front), (deg(60.0), &left), (deg(-60.0), &right)], &frames)
    }

    #[test]
    fn linear_between_cameras_and_held_outside() {
        let c = clock();
        let ms = |a: f64| c.offset_at(a.to_radians()) * 1e3;
        assert!((ms(0.0) + 50.0).abs() < 1e-6);
        assert!((ms(30.0) + 55.0).abs() < 1e-6, "{}", ms(30.0));
        assert!((ms(-30.0) + 45.0).abs() < 1e-6);
        assert!((ms(170.0) + 60.0).abs() < 1e-6, "the left camera's offset behind it");
        assert!((ms(-170.0) + 40.0).abs() < 1e-6);
        // A point straight ahead of the ego, and one to its left.
        assert!((c.offset_of(DVec3::new(20.0, 0.0, 1.0)) + 0.05).abs() < 1e-9);
        assert!((c.offset_of(DVec3::new(0.0, 5.0, 0.0)) + 0.06).abs() < 1e-9);
        let table = c.table();
        assert_eq!(table.len(), 3);
        assert!((table[0].0 + 60.0).abs() < 1e-9 && (table[0].1 + 40.0).abs() < 1e-6);
    }

    #[test]
    fn no_camera_means_no_offset() {
        let c = CaptureClock::from_cameras(&[(DVec3::Z, &[1.0])], &[1.0]);
        assert_eq!(c.offset_at(0.3), 0.0);
    }
}
