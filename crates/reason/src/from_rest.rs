//! Trajectories of a vehicle that starts (almost) at rest: path first, then speed.
//!
//! A per-axis quintic in time (see [`crate::quintic`]) fixes the start velocity; at rest that is
//! zero, so nothing ties the first metres of the path to the car's body. The minimum-jerk
//! solution then leaves sideways towards the target (WOMD track 654, a parked car asked to pull
//! out: its path started 35 degrees off its body, and the PID swung it into the tyre limit).
//! A car can only leave along its body, so here the geometry and the timing are separate:
//!
//! * the **path** is a quintic Hermite curve in a parameter `u in [0, 1]` from the start point,
//!   tangent to the body heading, to the target, tangent to the end velocity (or to the chord when
//!   the end speed is near zero), tangent lengths equal to the chord, zero second derivative at
//!   both ends;
//! * the **speed** is a minimum-jerk profile of arc length `s(t)` from 0 (start speed and
//!   acceleration given) to the path length at `duration` (end speed given, zero acceleration);
//! * `p(t) = path(u(s(t)))` through an arc-length table.
//!
//! A profile that would run backwards along the path is refused (`None`): a car does not
//! reverse into a corner case.

use crate::quintic::{End, Quintic};
use scene::glam::DVec2;
use scene::Waypoint;

/// Samples of the arc-length table along the path.
const TABLE_SAMPLES: usize = 400;

/// A path with a separate speed profile; `position(s)` and `velocity(s)` take the time since
/// the start (s), like [`Quintic`].
#[derive(Clone, Debug)]
pub struct FromRest {
    path: Quintic,
    /// `(u, arc length)` at `TABLE_SAMPLES + 1` evenly spaced `u`.
    table: Vec<(f64, f64)>,
    /// Arc length against time, in its `x` component.
    speed: Quintic,
    pub duration: f64,
}

impl FromRest {
    /// The trajectory from `start` (position; `speed >= 0` and `accel` along `heading`, rad) to
    /// `target` reached at `duration` (s) with velocity `v_end`. `None` when the profile would
    /// move backwards along the path or the input is degenerate.
    pub fn new(
        start: DVec2,
        heading: f64,
        speed: f64,
        accel: f64,
        target: DVec2,
        v_end: DVec2,
        duration: f64,
    ) -> Option<Self> {
        let chord = target - start;
        let l = chord.length();
        if !(duration > 0.0 && l > 1e-3 && speed >= 0.0) {
            return None;
        }
        let body = DVec2::new(heading.cos(), heading.sin());
        let end_dir = v_end.try_normalize().filter(|_| v_end.length() > 0.5).unwrap_or(chord / l);
        let path = Quintic::new(
            End { p: start, v: body * l, a: DVec2::ZERO },
            End { p: target, v: end_dir * l, a: DVec2::ZERO },
            1.0,
        );
        let mut table = Vec::with_capacity(TABLE_SAMPLES + 1);
        let mut arc = 0.0;
        let mut last = start;
        for i in 0..=TABLE_SAMPLES {
            let u = i as f64 / TABLE_SAMPLES as f64;
            let p = path.position(u);
            arc += p.distance(last);
            last = p;
            table.push((u, arc));
        }
        let speed_profile = Quintic::new(
            End { p: DVec2::ZERO, v: DVec2::new(speed, 0.0), a: DVec2::new(accel, 0.0) },
            End { p: DVec2::new(arc, 0.0), v: DVec2::new(v_end.length(), 0.0), a: DVec2::ZERO },
            duration,
        );
        // Never backwards: s'(t) >= 0 on a fine grid (a slight negative from rounding is allowed).
        let backwards = (0..=200).any(|k| speed_profile.velocity(duration * k as f64 / 200.0).x < -1e-6);
        (!backwards).then_some(FromRest { path, table, speed: speed_profile, duration })
    }

    /// Path parameter at arc length `s` (linear in the table).
    fn u_at(&self, s: f64) -> f64 {
        let s = s.clamp(0.0, self.table.last().map_or(0.0, |p| p.1));
        let i = self.table.partition_point(|p| p.1 < s).clamp(1, self.table.len() - 1);
        let ((u0, s0), (u1, s1)) = (self.table[i - 1], self.table[i]);
        if s1 > s0 {
            u0 + (s - s0) / (s1 - s0) * (u1 - u0)
        } else {
            u0
        }
    }

    pub fn position(&self, t: f64) -> DVec2 {
        self.path.position(self.u_at(self.speed.position(t).x))
    }

    pub fn velocity(&self, t: f64) -> DVec2 {
        let tangent = self.path.velocity(self.u_at(self.speed.position(t).x));
        tangent.try_normalize().unwrap_or(DVec2::ZERO) * self.speed.velocity(t).x
    }

    /// Waypoints at `t0 + k dt`, `k = 0..=n`, `n dt = duration` (the last exactly at the target).
    pub fn waypoints(&self, t0: f64, dt: f64) -> Vec<Waypoint> {
        let n = (self.duration / dt).round() as usize;
        (0..=n)
            .map(|k| {
                let p = if k == n { self.path.position(1.0) } else { self.position(k as f64 * dt) };
                Waypoint { t: t0 + k as f64 * dt, x: p.x, y: p.y }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn leaves_along_the_body_and_arrives_on_time() {
        // Parked facing +y; the target is 10 m ahead and 6 m to the right (35 degrees off the body).
        let target = DVec2::new(6.0, 10.0);
        let v_end = DVec2::new(0.0, 6.0);
        let m = FromRest::new(DVec2::ZERO, FRAC_PI_2, 0.0, 2.0, target, v_end, 3.0).expect("feasible");
        let w = m.waypoints(1.0, 0.1);
        assert_eq!(w.len(), 31);
        assert!((w[30].t - 4.0).abs() < 1e-9 && DVec2::new(w[30].x, w[30].y).distance(target) < 1e-9);
        // The first 0.3 m leave within 3 degrees of the body heading.
        let first = w.iter().map(|p| DVec2::new(p.x, p.y)).find(|p| p.length() > 0.3).expect("moves");
        assert!(first.x.atan2(first.y).abs() < 3f64.to_radians(), "leaves at {:?}", first);
        // The end velocity is met.
        assert!((m.velocity(3.0) - v_end).length() < 0.05, "{}", m.velocity(3.0));
        // Time-ordered progress: never backwards along the path.
        for p in w.windows(2) {
            let d = DVec2::new(p[1].x - p[0].x, p[1].y - p[0].y);
            assert!(d.dot(m.velocity(p[0].t - 1.0 + 0.05)) >= -1e-9);
        }
    }

    #[test]
    fn refuses_a_profile_that_runs_backwards() {
        // Reaching a target 1 m away in 5 s while arriving at 10 m/s needs s to go negative first.
        assert!(FromRest::new(DVec2::ZERO, 0.0, 0.0, 0.0, DVec2::new(1.0, 0.0), DVec2::new(10.0, 0.0), 5.0).is_none());
    }
}
