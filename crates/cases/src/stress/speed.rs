//! Faster traffic: every road user but the ego drives exactly its logged path, `factor` times as
//! fast; the ego keeps its logged poses and the log's clock (the frames' timestamps) unchanged.
//!
//! What "faster" means physically: a road user's state at scene time `t` is its logged state at
//! source time `tau = t_a + factor (t - t_a)`, with velocities multiplied by `factor` (so
//! accelerations scale by `factor^2` and lateral accelerations on the same curves too: a harder
//! world for the planner, not a different geometry). The anchor `t_a` is the log's middle, so the
//! configuration there is the logged one and the traffic of the whole log is squeezed into the
//! middle `1/factor` of it: a moving road user is present at `t` only while `tau` lies inside one
//! of its logged runs (runs end at gaps longer than `scene::motion::MAX_GAP_S`; no motion is
//! invented). A road user that never moves (every logged speed and displacement below
//! [`STILL_M`]) is unchanged, so parked cars do not vanish at the ends of the log.
//!
//! Scaling the whole clock instead (ego included) would also be consistent, but it changes the
//! ego's log and shortens it; this copy keeps the ego as recorded, like the corner cases do.

use super::copy::{without_sensors, StressError};
use scene::frames::wrap_angle;
use scene::glam::DVec3;
use scene::motion::MAX_GAP_S;
use scene::{Scene, Track, TrackState};

/// The corpus's speed factor.
pub const CORPUS_FACTOR: f64 = 1.5;

/// A road user that moves less than this (m, and m/s) over its whole log counts as still.
pub const STILL_M: f64 = 0.5;

fn is_still(t: &Track) -> bool {
    let v: Vec<&TrackState> = t.valid_states().collect();
    let Some(first) = v.first() else { return true };
    let moved = v.iter().any(|x| (x.center - first.center).truncate().length() > STILL_M);
    let fast = v.iter().any(|x| x.velocity.is_some_and(|u| u.truncate().length() > STILL_M));
    !moved && !fast
}

/// Valid states grouped into runs without gaps longer than `MAX_GAP_S`, with their times.
fn runs<'a>(s: &Scene, t: &'a Track) -> Vec<Vec<(f64, &'a TrackState)>> {
    let mut out: Vec<Vec<(f64, &TrackState)>> = Vec::new();
    for st in t.valid_states() {
        let Some(time) = s.frames.get(st.frame).map(|f| f.timestamp_s) else { continue };
        match out.last_mut() {
            Some(r) if time - r.last().map_or(f64::MIN, |x| x.0) <= MAX_GAP_S => r.push((time, st)),
            _ => out.push(vec![(time, st)]),
        }
    }
    out
}

/// The state of a run at source time `tau`, interpolated (position linear, heading along the
/// short arc); velocity from the run's positions (or the source's) times `factor`.
fn sample(run: &[(f64, &TrackState)], tau: f64, factor: f64, frame: usize) -> Option<TrackState> {
    let (first, last) = (run.first()?, run.last()?);
    if tau < first.0 - 1e-9 || tau > last.0 + 1e-9 {
        return None;
    }
    let i = run.partition_point(|x| x.0 <= tau).clamp(1, run.len().max(1));
    let (a, b) = if run.len() == 1 { (first, first) } else { (&run[i - 1], &run[i.min(run.len() - 1)]) };
    let span = b.0 - a.0;
    let w = if span > 0.0 { ((tau - a.0) / span).clamp(0.0, 1.0) } else { 0.0 };
    let center = a.1.center.lerp(b.1.center, w);
    let heading = wrap_angle(a.1.heading + w * wrap_angle(b.1.heading - a.1.heading));
    let from_positions = (span > 0.0).then(|| (b.1.center - a.1.center) / span);
    let logged = match (a.1.velocity, b.1.velocity) {
        (Some(u), Some(v)) => Some(u.lerp(v, w)),
        _ => None,
    };
    let velocity = logged.or(from_positions.filter(|_| a.1.velocity.is_some())).map(|v: DVec3| v * factor);
    let nearest = if w < 0.5 { a.1 } else { b.1 };
    Some(TrackState {
        frame,
        center,
        heading,
        size_lwh: nearest.size_lwh,
        velocity,
        valid: true,
        motion: nearest.motion,
    })
}

/// A copy of `s` whose road users (not the ego) are `factor` times as fast; `factor` must be a
/// finite number in (0, 10].
pub fn speed_up(s: &Scene, factor: f64) -> Result<Scene, StressError> {
    if !(factor.is_finite() && factor > 0.0 && factor <= 10.0) {
        return Err(StressError::Parameter { name: "speed factor", value: factor, why: "must be in (0, 10]" });
    }
    let mut out = without_sensors(s, "speed");
    let (Some(f0), Some(f1)) = (s.frames.first(), s.frames.last()) else { return Ok(out) };
    let anchor = 0.5 * (f0.timestamp_s + f1.timestamp_s);
    for (k, t) in s.tracks.iter().enumerate() {
        if s.ego.track_id.as_deref() == Some(t.id.as_str()) || is_still(t) {
            continue;
        }
        let rs = runs(s, t);
        out.tracks[k].states = s
            .frames
            .iter()
            .enumerate()
            .filter_map(|(fi, f)| {
                let tau = anchor + factor * (f.timestamp_s - anchor);
                rs.iter().find_map(|r| sample(r, tau, factor, fi))
            })
            .collect();
    }
    out.tracks.retain(|t| !t.states.is_empty());
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stress::fixture::street;

    #[test]
    fn paths_kept_speeds_scaled_ego_unchanged() {
        let s = street();
        let f = speed_up(&s, CORPUS_FACTOR).unwrap();
        assert_eq!(
            f.frames.iter().map(|x| (x.timestamp_s, x.world_from_ego)).collect::<Vec<_>>(),
            s.frames.iter().map(|x| (x.timestamp_s, x.world_from_ego)).collect::<Vec<_>>()
        );
        assert_eq!(f.track("sdc"), s.track("sdc"));
        assert_eq!(f.track("kerb"), s.track("kerb"), "a parked car stays");
        let left = f.track("left").unwrap();
        // At the anchor (t = 4 s, frame 40) the logged state; 11 m/s becomes 16.5 m/s.
        let mid = left.state_at(40).unwrap();
        assert!((mid.center.x - (5.0 + 11.0 * 4.0)).abs() < 1e-9);
        for st in left.valid_states() {
            assert!((st.velocity.unwrap().x - 16.5).abs() < 1e-9);
            assert_eq!(st.center.y, 3.6);
        }
        // Present only while the source time is logged: the middle 1/1.5 of the log.
        let span = (left.states.first().unwrap().frame, left.states.last().unwrap().frame);
        assert!(span.0 >= 13 && span.0 <= 14 && span.1 >= 66 && span.1 <= 67, "{span:?}");
        // Positions advance 1.5x as fast between frames.
        let (a, b) = (left.state_at(30).unwrap(), left.state_at(31).unwrap());
        assert!(((b.center.x - a.center.x) - 1.65).abs() < 1e-9);
    }

    #[test]
    fn factor_one_is_the_log_and_bad_factors_are_refused() {
        let s = street();
        let f = speed_up(&s, 1.0).unwrap();
        for (a, b) in s.tracks.iter().zip(&f.tracks) {
            for (x, y) in a.states.iter().zip(&b.states) {
                assert!((x.center - y.center).length() < 1e-9 && (x.heading - y.heading).abs() < 1e-12);
            }
        }
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY, 11.0] {
            assert!(speed_up(&s, bad).is_err());
        }
    }
}
