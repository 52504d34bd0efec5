//! Actor placement in time: `world_from_box` at any time `t` (real log seconds), interpolated
//! between the two nearest valid track states (centre linearly, heading along the shorter arc).
//! Boxes are upright in the world (yaw only, see `scene::frames`), so the pose is a yaw and a
//! translation. Outside the track's valid lifespan there is no pose: the actor is not drawn,
//! except within the scene's image-time spread of its first or last state, where the pose is
//! carried along the state's velocity: an image taken before its frame's time (PandaSet's front
//! camera fires 50 ms before the LiDAR's frame time) still shows the boxes of its frame.
//! (Street Gaussians composes `world_from_ego * ego_from_box`; our tracks are already stored in
//! the world frame, which is that product.)

use scene::frames::{world_from_box, wrap_angle};
use scene::glam::DVec3;
use scene::{Scene, Track, TrackState, Transform3};

/// A yaw-and-translation pose of a box in the world.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoxPose {
    pub center: [f64; 3],
    pub heading: f64,
}

impl BoxPose {
    pub fn world_from_box(&self) -> Transform3 {
        world_from_box(self.center.into(), self.heading)
    }
}

/// The pose of `track` at time `t`, or `None` outside its valid states (a 1 ms tolerance at the
/// ends, so frame times hit their own state exactly, widened to the scene's image-time spread).
pub fn box_pose_at(scene: &Scene, track: &Track, t: f64) -> Option<BoxPose> {
    let time = |frame: usize| scene.frames.get(frame).map(|f| f.timestamp_s);
    let edge = || scene.image_time_spread() + 1e-3;
    let carried = |s: &TrackState, ts: f64| {
        let v = s.velocity.filter(|v| v.is_finite()).unwrap_or(DVec3::ZERO);
        BoxPose { center: (s.center + v * (t - ts)).into(), heading: s.heading }
    };
    let mut prev: Option<(f64, BoxPose, &TrackState)> = None;
    for s in track.valid_states() {
        let ts = time(s.frame)?;
        let pose = BoxPose { center: s.center.into(), heading: s.heading };
        if (ts - t).abs() <= 1e-3 {
            return Some(pose);
        }
        if ts > t {
            let Some((t0, p0, _)) = prev else {
                return (ts - t <= edge()).then(|| carried(s, ts));
            };
            let w = (t - t0) / (ts - t0);
            let c = std::array::from_fn(|k| p0.center[k] + w * (pose.center[k] - p0.center[k]));
            let heading = wrap_angle(p0.heading + w * wrap_angle(pose.heading - p0.heading));
            return Some(BoxPose { center: c, heading });
        }
        prev = Some((ts, pose, s));
    }
    let (t0, _, last) = prev?;
    (t - t0 <= edge()).then(|| carried(last, t0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use scene::{Ego, EgoSizeSource, Frame, ObjectClass, Source, SourceKind, TrackState};

    fn scene_with(states: Vec<TrackState>) -> Scene {
        let frames = (0..4)
            .map(|i| Frame {
                index: i,
                timestamp_s: 10.0 + 0.1 * i as f64,
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
            tracks: vec![Track { id: "a".into(), class: ObjectClass::Vehicle, states }],
            map: None,
        }
    }

    fn state(frame: usize, x: f64, heading: f64) -> TrackState {
        TrackState {
            frame,
            center: DVec3::new(x, 1.0, 0.5),
            heading,
            size_lwh: [4.0, 2.0, 1.5],
            velocity: None,
            valid: true,
            motion: None,
        }
    }

    #[test]
    fn interpolates_between_states_and_across_the_wrap() {
        let pi = std::f64::consts::PI;
        let sc = scene_with(vec![state(1, 0.0, pi - 0.1), state(3, 4.0, -pi + 0.1)]);
        let tr = &sc.tracks[0];
        assert!(box_pose_at(&sc, tr, 10.0).is_none(), "before the first state");
        assert!(box_pose_at(&sc, tr, 10.35).is_none(), "after the last state");
        let exact = box_pose_at(&sc, tr, 10.1).unwrap();
        assert_eq!(exact.center, [0.0, 1.0, 0.5]);
        let mid = box_pose_at(&sc, tr, 10.2).unwrap();
        assert!((mid.center[0] - 2.0).abs() < 1e-9);
        // Halfway along the short arc through pi, not through 0.
        assert!((wrap_angle(mid.heading - pi)).abs() < 1e-9, "heading {}", mid.heading);
    }

    #[test]
    fn images_before_their_frame_see_its_boxes_carried_along_the_velocity() {
        let mut first = state(1, 0.0, 0.0);
        first.velocity = Some(DVec3::new(10.0, 0.0, 0.0));
        let mut sc = scene_with(vec![first, state(2, 1.0, 0.0)]);
        let tr = sc.tracks[0].clone();
        // Images at their frame's time: nothing is drawn 50 ms before the first state.
        assert!(box_pose_at(&sc, &tr, 10.05).is_none());
        // An image of frame 1 taken 50 ms before the frame's time.
        sc.frames[1].images.push(scene::ImageRef {
            camera: "front".into(),
            path: "x.jpg".into(),
            timestamp_s: Some(10.05),
        });
        let early = box_pose_at(&sc, &tr, 10.05).unwrap();
        assert!((early.center[0] + 0.5).abs() < 1e-9, "carried back 0.5 m: {:?}", early.center);
        // Within the spread after the last state (no velocity: held), not beyond it.
        assert_eq!(box_pose_at(&sc, &tr, 10.24).unwrap().center[0], 1.0);
        assert!(box_pose_at(&sc, &tr, 10.3).is_none());
    }
}
