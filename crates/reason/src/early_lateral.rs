//! A straight-line path that moves sideways early: the lateral part of the motion (across the
//! ego's heading at the target time) is done within the first [`LATERAL_FRACTION`] of the
//! duration, the longitudinal part over all of it. The per-axis quintic of
//! [`crate::quintic::Quintic`] spreads the sideways move over the whole approach, so a car
//! cutting in ahead or an oncoming car drifting over crosses the lane in between near the ego,
//! where its neighbours drive; moving over first and then driving in the target lane crosses it
//! farther away. The wider search ([`crate::sampling::Breadth::WIDE`]) tries it besides the
//! ordinary shape, for moving vehicles in scenes without lanes and end velocities along the
//! ego's heading. On the stress corpus (BENCHMARKS.md) it is the chosen shape of 8 cut-ins (5
//! verified) but did not change the verified count (other wide candidates verify the same
//! attempts), and it frees no opposing drift: in the KITTI scenes the lead and the car beside
//! the ego block every path of the oncoming car.

use crate::quintic::{End, Quintic};
use scene::glam::DVec2;
use scene::Waypoint;

/// The share of the duration within which the sideways move is done.
pub const LATERAL_FRACTION: f64 = 0.6;

/// Largest sideways end speed (m/s) for which the shape applies (its sideways motion stops).
pub const MAX_LATERAL_END_SPEED: f64 = 0.5;

#[derive(Clone, Debug)]
pub struct EarlyLateral {
    origin: DVec2,
    along: DVec2,
    across: DVec2,
    long: Quintic,
    lat: Quintic,
    pub duration: f64,
}

fn q1(x0: f64, v0: f64, x1: f64, v1: f64, duration: f64) -> Quintic {
    let e = |p: f64, v: f64| End { p: DVec2::new(p, 0.0), v: DVec2::new(v, 0.0), a: DVec2::ZERO };
    Quintic::new(e(x0, v0), e(x1, v1), duration)
}

impl EarlyLateral {
    /// From `p0` at velocity `v0` to `target` at `v_end` after `duration`, axes along `heading`;
    /// `None` if the end velocity has a sideways part above [`MAX_LATERAL_END_SPEED`].
    pub fn new(p0: DVec2, v0: DVec2, target: DVec2, v_end: DVec2, duration: f64, heading: f64) -> Option<Self> {
        let along = DVec2::from_angle(heading);
        let across = along.perp();
        if v_end.dot(across).abs() > MAX_LATERAL_END_SPEED || duration <= 0.0 {
            return None;
        }
        let d = target - p0;
        let long = q1(0.0, v0.dot(along), d.dot(along), v_end.dot(along), duration);
        let lat = q1(0.0, v0.dot(across), d.dot(across), 0.0, duration * LATERAL_FRACTION);
        Some(EarlyLateral { origin: p0, along, across, long, lat, duration })
    }

    pub fn position(&self, s: f64) -> DVec2 {
        let w = self.lat.position(s.min(self.lat.duration)).x;
        self.origin + self.along * self.long.position(s).x + self.across * w
    }

    pub fn velocity(&self, s: f64) -> DVec2 {
        let w = if s < self.lat.duration { self.lat.velocity(s).x } else { 0.0 };
        self.along * self.long.velocity(s).x + self.across * w
    }

    /// Waypoints at `t0 + k dt`, the last one exactly at the end point.
    pub fn waypoints(&self, t0: f64, dt: f64) -> Vec<Waypoint> {
        let n = (self.duration / dt).round() as usize;
        (0..=n)
            .map(|k| {
                let s = if k == n { self.duration } else { k as f64 * dt };
                let p = self.position(s);
                Waypoint { t: t0 + k as f64 * dt, x: p.x, y: p.y }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moves_over_first_then_drives_straight_to_the_target() {
        // Oncoming at 10 m/s, 7 m to the side, to a target 40 m ahead on the axis in 3 s.
        let (p0, v0) = (DVec2::new(40.0, 7.0), DVec2::new(-10.0, 0.0));
        let m = EarlyLateral::new(p0, v0, DVec2::ZERO, DVec2::new(-10.0, 0.0), 3.0, 0.0).unwrap();
        assert!(m.position(0.0).distance(p0) < 1e-9);
        assert!(m.position(3.0).distance(DVec2::ZERO) < 1e-9);
        // Done sideways at 60 % of the way (1.8 s) and level after it; a per-axis quintic is
        // still 1.1 m out at that time.
        for s in [1.8, 2.2, 2.6, 3.0] {
            assert!(m.position(s).y.abs() < 1e-9, "{s}: {}", m.position(s).y);
        }
        let q = Quintic::new(End { p: p0, v: v0, a: DVec2::ZERO }, End { p: DVec2::ZERO, v: v0, a: DVec2::ZERO }, 3.0);
        assert!(q.position(1.8).y > 1.0, "{}", q.position(1.8).y);
        assert!((m.velocity(3.0) - DVec2::new(-10.0, 0.0)).length() < 1e-9);
        // An end velocity with a sideways part is not this shape.
        assert!(EarlyLateral::new(p0, v0, DVec2::ZERO, DVec2::new(-10.0, 2.0), 3.0, 0.0).is_none());
    }
}
