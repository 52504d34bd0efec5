//! A measured silhouette for actor mask IoU on real logs: the convex hull of the LiDAR points a
//! sweep took on a vehicle, projected into a held-out view. Real logs have no instance masks, and
//! a logged box is not a car's outline (a car fills about two thirds of its box's hull; the two-box
//! profile of `eval_boxes` is a drawn shape, not a measured one). The points the sweep of the
//! view's own frame took inside the vehicle's box are the sensor's own record of its shape:
//! carried into the box frame at the sweep's time and out of it at the view's time (as the
//! renderer places the actor), their projected hull is where the car is in that image, up to the
//! parts the LiDAR did not hit (mostly under the bumpers and the wheels' lower halves).
//!
//! The reference exists only where the sweep measured the car: at least [`MIN_POINTS`] points
//! above the box floor (the lowest [`FLOOR_M`] of the box holds road returns), which on PandaSet
//! 002 is every moving car within about 35 m; a pair without one is counted, not scored.
//! `eval_boxes` projects the points and scores the mask as it does the box's.

use crate::pose::box_pose_at;
use scene::glam::DVec3;
use scene::{Scene, Track};

/// A silhouette needs at least this many points on the vehicle.
pub const MIN_POINTS: usize = 40;
/// Points this close (m) to the box's floor are taken as road, not car.
pub const FLOOR_M: f64 = 0.15;
/// Points within the box grown by this factor count as the vehicle's (label slack).
pub const BOX_SLACK: f64 = 1.05;

/// One frame's sweep in the world frame.
pub struct Sweep {
    pub frame: usize,
    pub time: f64,
    pub points_world: Vec<DVec3>,
}

impl Sweep {
    /// The sweep of frame `frame` if the frame has one of its own.
    pub fn load(scene_dir: &std::path::Path, scene: &Scene, frame: usize) -> Result<Option<Sweep>, scene::SceneError> {
        let Some(f) = scene.frames.get(frame) else { return Ok(None) };
        let Some(l) = &f.lidar else { return Ok(None) };
        let pts = scene::format::read_lidar(&scene_dir.join(&l.path))?;
        let points_world = pts
            .iter()
            .map(|p| f.world_from_ego.transform_point(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)))
            .collect();
        Ok(Some(Sweep { frame, time: f.timestamp_s, points_world }))
    }
}

/// The box-frame points of `sweep` on `track` (inside its box grown by [`BOX_SLACK`], above the
/// floor band), or `None` without a box at the sweep's time.
pub fn points_on(scene: &Scene, track: &Track, size_lwh: [f64; 3], sweep: &Sweep) -> Option<Vec<DVec3>> {
    let box_from_world = box_pose_at(scene, track, sweep.time)?.world_from_box().inverse();
    let half = size_lwh.map(|s| 0.5 * s * BOX_SLACK);
    let floor = -0.5 * size_lwh[2] + FLOOR_M;
    Some(
        sweep
            .points_world
            .iter()
            .map(|p| box_from_world.transform_point(*p))
            .filter(|b| b.x.abs() <= half[0] && b.y.abs() <= half[1] && b.z.abs() <= half[2] && b.z >= floor)
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::{Ego, EgoSizeSource, Frame, LoggedMotion, ObjectClass, Source, SourceKind, TrackState, Transform3};

    fn scene_with(track: Track) -> Scene {
        let frames = (0..2)
            .map(|i| Frame {
                index: i,
                timestamp_s: i as f64 * 0.1,
                world_from_ego: Transform3::from_yaw_translation(0.0, DVec3::ZERO),
                images: vec![],
                lidar: None,
            })
            .collect();
        Scene {
            format: scene::SCENE_FORMAT.into(),
            name: "t".into(),
            source: Source { kind: SourceKind::Synthetic, files: vec![], id: "t".into() },
            ego: Ego { size_lwh: [4.5, 2.0, 1.8], size_source: EgoSizeSource::Default, track_id: None },
            cameras: vec![],
            frames,
            tracks: vec![track],
            map: None,
        }
    }

    #[test]
    fn the_points_on_a_car_follow_its_box_and_leave_the_road_out() {
        let state = |frame: usize, x: f64| TrackState {
            frame,
            center: DVec3::new(x, 0.0, 0.75),
            heading: 0.0,
            size_lwh: [4.0, 2.0, 1.5],
            velocity: Some(DVec3::new(10.0, 0.0, 0.0)),
            valid: true,
            motion: Some(LoggedMotion::Moving),
        };
        let track =
            Track { id: "car".into(), class: ObjectClass::Vehicle, states: vec![state(0, 10.0), state(1, 11.0)] };
        let scene = scene_with(track.clone());
        // A grid on the car's rear face (x = 8), road points under it, and a point beside it.
        let mut pts: Vec<DVec3> = (0..10)
            .flat_map(|i| (0..8).map(move |k| DVec3::new(8.05, -0.9 + 0.2 * i as f64, 0.2 + 0.15 * k as f64)))
            .collect();
        pts.extend((0..10).map(|i| DVec3::new(9.0 + 0.1 * i as f64, 0.0, 0.05)));
        pts.push(DVec3::new(10.0, 3.0, 0.75));
        let sweep = Sweep { frame: 0, time: 0.0, points_world: pts };
        let on = points_on(&scene, &scene.tracks[0], [4.0, 2.0, 1.5], &sweep).unwrap();
        assert_eq!(on.len(), 80, "the rear face's grid, not the road or the point beside");
        assert!(on.iter().all(|b| (b.x + 1.95).abs() < 1e-9));
    }
}
