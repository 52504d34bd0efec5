//! Planar motion over the scene clock: `Pose2` samples, interpolation of logged poses
//! (ego and tracks) at any time, and resampling of time series.
//!
//! Interpolation is linear in position and along the shortest arc in heading between the two
//! nearest samples. A track is present at `t` only between two valid states no further apart
//! than [`MAX_GAP_S`] (a longer gap means the object was not seen; we do not invent motion).

use crate::frames::wrap_angle;
use crate::model::Scene;
use crate::track::Track;
use glam::DVec2;
use serde::{Deserialize, Serialize};

/// The longest gap between valid states that replay interpolates across (s).
pub const MAX_GAP_S: f64 = 1.0;

/// A planar pose at a time: world-frame position (m) and heading (rad) at `t` (s).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pose2 {
    pub t: f64,
    pub x: f64,
    pub y: f64,
    pub heading: f64,
}

impl Pose2 {
    pub fn position(&self) -> DVec2 {
        DVec2::new(self.x, self.y)
    }

    /// Interpolates between `a` (at `a.t`) and `b` at time `t`.
    pub fn lerp(a: &Pose2, b: &Pose2, t: f64) -> Pose2 {
        let span = b.t - a.t;
        let s = if span > 0.0 { ((t - a.t) / span).clamp(0.0, 1.0) } else { 0.0 };
        Pose2 {
            t,
            x: a.x + s * (b.x - a.x),
            y: a.y + s * (b.y - a.y),
            heading: wrap_angle(a.heading + s * wrap_angle(b.heading - a.heading)),
        }
    }

    /// `p` (world) expressed in this pose's frame (x forward, y left).
    pub fn to_local(&self, p: DVec2) -> DVec2 {
        let d = p - self.position();
        let (s, c) = self.heading.sin_cos();
        DVec2::new(c * d.x + s * d.y, -s * d.x + c * d.y)
    }

    /// A point given in this pose's frame, in the world.
    pub fn to_world(&self, local: DVec2) -> DVec2 {
        let (s, c) = self.heading.sin_cos();
        self.position() + DVec2::new(c * local.x - s * local.y, s * local.x + c * local.y)
    }
}

/// The paper's centre time to collision at constant velocity, capped at `cap` seconds:
/// `r = p_adv - p_ego`, `closing = -(r . (v_adv - v_ego)) / |r|`, `TTC = |r| / closing` if
/// `closing > 0`, else `cap` (0 if the centres coincide).
pub fn center_ttc(p_ego: DVec2, v_ego: DVec2, p_adv: DVec2, v_adv: DVec2, cap: f64) -> f64 {
    let r = p_adv - p_ego;
    let d = r.length();
    if d == 0.0 {
        return 0.0;
    }
    let closing = -r.dot(v_adv - v_ego) / d;
    if closing > 0.0 {
        (d / closing).min(cap)
    } else {
        cap
    }
}

/// Samples a time-sorted pose series at `t`; `None` outside its span.
pub fn sample_series(series: &[Pose2], t: f64) -> Option<Pose2> {
    let first = series.first()?;
    let last = series.last()?;
    if t < first.t - 1e-9 || t > last.t + 1e-9 {
        return None;
    }
    let i = series.partition_point(|p| p.t <= t);
    Some(match i {
        0 => Pose2 { t, ..*first },
        i if i >= series.len() => Pose2 { t, ..*last },
        i => Pose2::lerp(&series[i - 1], &series[i], t),
    })
}

/// Resamples a series on a uniform grid `t0, t0 + dt, ...` within its span.
pub fn resample(series: &[Pose2], dt: f64) -> Vec<Pose2> {
    let (Some(first), Some(last)) = (series.first(), series.last()) else { return Vec::new() };
    let n = ((last.t - first.t) / dt + 1e-9).floor() as usize;
    (0..=n).filter_map(|k| sample_series(series, first.t + k as f64 * dt)).collect()
}

impl Scene {
    /// The ego's logged poses, one per frame.
    pub fn ego_series(&self) -> Vec<Pose2> {
        self.frames
            .iter()
            .map(|f| {
                let p = f.world_from_ego.translation();
                Pose2 { t: f.timestamp_s, x: p.x, y: p.y, heading: f.world_from_ego.yaw() }
            })
            .collect()
    }

    /// Valid states of a track as runs of poses without gaps longer than [`MAX_GAP_S`].
    pub fn track_segments(&self, track: &Track) -> Vec<Vec<Pose2>> {
        let mut runs: Vec<Vec<Pose2>> = Vec::new();
        for s in track.valid_states() {
            let p = Pose2 { t: self.frames[s.frame].timestamp_s, x: s.center.x, y: s.center.y, heading: s.heading };
            match runs.last_mut() {
                Some(run) if p.t - run.last().map_or(f64::MIN, |q| q.t) <= MAX_GAP_S => run.push(p),
                _ => runs.push(vec![p]),
            }
        }
        runs
    }

    /// A track's interpolated pose at `t`, if it is present then.
    pub fn track_pose_at(&self, track: &Track, t: f64) -> Option<Pose2> {
        self.track_segments(track).iter().find_map(|run| sample_series(run, t))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_heading_along_the_short_arc() {
        let a = Pose2 { t: 0.0, x: 0.0, y: 0.0, heading: 3.0 };
        let b = Pose2 { t: 1.0, x: 2.0, y: 0.0, heading: -3.0 };
        let m = Pose2::lerp(&a, &b, 0.5);
        assert!((m.x - 1.0).abs() < 1e-12);
        assert!((wrap_angle(m.heading - std::f64::consts::PI)).abs() < 1e-12);
    }

    #[test]
    fn local_world_round_trip() {
        let p = Pose2 { t: 0.0, x: 3.0, y: -1.0, heading: 0.8 };
        let w = DVec2::new(7.0, 2.0);
        assert!((p.to_world(p.to_local(w)) - w).length() < 1e-12);
        let ahead = Pose2 { heading: std::f64::consts::FRAC_PI_2, ..p }.to_local(DVec2::new(3.0, 4.0));
        assert!((ahead - DVec2::new(5.0, 0.0)).length() < 1e-12);
    }

    #[test]
    fn sampling_and_resampling() {
        let s: Vec<Pose2> = (0..5).map(|i| Pose2 { t: i as f64 * 0.1, x: i as f64, y: 0.0, heading: 0.0 }).collect();
        assert!(sample_series(&s, -0.01).is_none());
        assert!((sample_series(&s, 0.25).unwrap().x - 2.5).abs() < 1e-12);
        assert!((sample_series(&s, 0.4).unwrap().x - 4.0).abs() < 1e-12);
        let r = resample(&s, 0.05);
        assert_eq!(r.len(), 9);
        assert!((r[3].x - 1.5).abs() < 1e-12);
    }
}
