//! Time for video: the frame times of a clip on the scene clock, and the logged ego pose at any
//! time between two logged frames.
//!
//! A video runs at its own rate (default 24 fps), not the log's (10 Hz for Waymo and the
//! synthetic street), so the ego is interpolated: translation linearly, rotation by slerp of the
//! two frames' rotations (the log's ego may pitch and roll a little; slerp keeps it rigid).
//! Outside the log the nearest frame's pose is held. Actors are interpolated by `recon::pose`
//! and the adversary by `backproject`, both on the same clock.

use crate::RenderError;
use scene::{Executed, Scene, Transform3};

/// The logged ego pose at time `t` (scene clock, seconds): [`Scene::world_from_ego_at`].
pub fn world_from_ego_at(scene: &Scene, t: f64) -> Transform3 {
    scene.world_from_ego_at(t)
}

/// The frame times of a clip: `start + k / fps` for every k with a time not after `end`.
#[derive(Clone, Debug, PartialEq)]
pub struct Timeline {
    pub fps: f64,
    pub times: Vec<f64>,
}

/// At most this many frames in one clip (an hour at 24 fps): a guard against a wrong clock.
pub const MAX_FRAMES: usize = 86_400;

impl Timeline {
    pub fn new(start: f64, end: f64, fps: f64) -> Result<Self, RenderError> {
        let bad = |detail: String| Err(RenderError::Settings { what: "video timeline".into(), detail });
        if !(fps.is_finite() && fps > 0.0) {
            return bad(format!("--fps must be a positive rate in Hz, got {fps}"));
        }
        if !(start.is_finite() && end.is_finite() && end >= start) {
            return bad(format!("needs a finite span with end >= start, got {start} .. {end} s"));
        }
        let n = ((end - start) * fps + 1e-9).floor() as usize + 1;
        if n > MAX_FRAMES {
            return bad(format!("{n} frames from {start:.2} to {end:.2} s at {fps} fps is more than {MAX_FRAMES}"));
        }
        Ok(Timeline { fps, times: (0..n).map(|k| start + k as f64 / fps).collect() })
    }

    /// The clip of a corner case: from `lead_in_s` before the plan's start (not before the log)
    /// to the last executed step.
    pub fn for_case(scene: &Scene, executed: &Executed, fps: f64, lead_in_s: f64) -> Result<Self, RenderError> {
        let log_start = scene.frames[0].timestamp_s;
        let start = (executed.plan.start_time_s - lead_in_s.max(0.0)).max(log_start);
        let end = executed.steps.last().map_or(start, |s| s.t);
        Timeline::new(start, end, fps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_times_cover_the_span_at_the_rate() {
        let tl = Timeline::new(1.0, 2.0, 24.0).unwrap();
        assert_eq!(tl.times.len(), 25);
        assert!((tl.times[24] - 2.0).abs() < 1e-12);
        assert!(Timeline::new(2.0, 1.0, 24.0).is_err());
        assert!(Timeline::new(0.0, 1.0, 0.0).is_err());
        assert!(Timeline::new(0.0, 1e9, 24.0).is_err());
    }
}
