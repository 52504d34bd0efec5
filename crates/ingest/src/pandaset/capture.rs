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
//! A box is then carried to its frame's time along its velocity (`cuboids::tracks`), and so are
//! the sweep's points on it ([`carry_points`]): a sweep is stored as one instant, its frame's,
//! like its boxes. Before this, the points on a car passing at 10 m/s sat half a metre behind the
//! car's own box at the frame's time, so everything that reads a sweep through the boxes (the
//! actors' LiDAR start, the depth priors, the measured silhouettes) was off by that much.

use scene::frames::world_from_box;
use scene::glam::DVec3;
use scene::{Track, Transform3};

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

/// Boxes are grown by this factor when their sweep points are picked (label slack).
pub const POINT_SLACK: f64 = 1.05;

/// One box of a sweep's frame whose points move: where it was when the sweep saw it, and how far
/// it moved from then to the frame's time.
pub struct Carried {
    pub box_from_world: Transform3,
    pub half: [f64; 3],
    pub shift: DVec3,
}

/// The boxes of frame `k` (time `t`) that moved between their capture (`capture(k, centre)`) and
/// the frame's time, from the tracks' states (already on the frame's clock).
pub fn carried_boxes(tracks: &[Track], k: usize, t: f64, capture: &dyn Fn(usize, DVec3) -> f64) -> Vec<Carried> {
    tracks
        .iter()
        .filter_map(|tr| tr.state_at(k))
        .filter_map(|s| {
            let v = s.velocity.filter(|v| v.is_finite())?;
            let shift = v * (t - capture(k, s.center));
            (shift.length() > 1e-3).then(|| Carried {
                box_from_world: world_from_box(s.center - shift, s.heading).inverse(),
                half: s.size_lwh.map(|x| 0.5 * x * POINT_SLACK),
                shift,
            })
        })
        .collect()
}

/// Carries every world point (x, y, z, intensity) inside one of `boxes` along that box's shift
/// (the first box holding it); returns how many moved.
pub fn carry_points(points: &mut [[f32; 4]], boxes: &[Carried]) -> usize {
    let mut moved = 0;
    for p in points.iter_mut() {
        let w = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
        let hit = boxes.iter().find(|b| {
            let q = b.box_from_world.transform_point(w);
            q.x.abs() <= b.half[0] && q.y.abs() <= b.half[1] && q.z.abs() <= b.half[2]
        });
        if let Some(b) = hit {
            let c = w + b.shift;
            (p[0], p[1], p[2]) = (c.x as f32, c.y as f32, c.z as f32);
            moved += 1;
        }
    }
    moved
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
    fn points_on_a_moving_box_join_it_at_the_frame_time() {
        use scene::{LoggedMotion, ObjectClass, TrackState};
        // A car at 10 m/s along x, seen 50 ms before its frame's time: its state (frame time)
        // is 0.5 m ahead of where the sweep saw it.
        let state = TrackState {
            frame: 3,
            center: DVec3::new(10.5, 0.0, 0.75),
            heading: 0.0,
            size_lwh: [4.0, 2.0, 1.5],
            velocity: Some(DVec3::new(10.0, 0.0, 0.0)),
            valid: true,
            motion: Some(LoggedMotion::Moving),
        };
        let parked = TrackState { center: DVec3::new(0.0, 5.0, 0.75), velocity: Some(DVec3::ZERO), ..state.clone() };
        let tracks = vec![
            Track { id: "car".into(), class: ObjectClass::Vehicle, states: vec![state] },
            Track { id: "parked".into(), class: ObjectClass::Vehicle, states: vec![parked] },
        ];
        let boxes = carried_boxes(&tracks, 3, 1.0, &|_, _| 0.95);
        assert_eq!(boxes.len(), 1, "the parked car does not move");
        assert!((boxes[0].shift - DVec3::new(0.5, 0.0, 0.0)).length() < 1e-12);
        // The car's rear bumper as the sweep saw it (x = 8.0), a parked car's point and the road
        // beside the car.
        let mut pts = vec![[8.0, 0.0, 0.5, 1.0], [0.0, 5.0, 0.5, 2.0], [10.0, 3.0, 0.0, 3.0]];
        assert_eq!(carry_points(&mut pts, &boxes), 1);
        assert_eq!(pts[0], [8.5, 0.0, 0.5, 1.0], "on the car's rear face at the frame's time");
        assert_eq!(pts[1], [0.0, 5.0, 0.5, 2.0]);
        assert_eq!(pts[2], [10.0, 3.0, 0.0, 3.0]);
    }

    #[test]
    fn no_camera_means_no_offset() {
        let c = CaptureClock::from_cameras(&[(DVec3::Z, &[1.0])], &[1.0]);
        assert_eq!(c.offset_at(0.3), 0.0);
    }
}
