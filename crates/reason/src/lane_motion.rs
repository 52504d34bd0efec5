//! Map-aware adversary motion: where the scene has lanes, a planned trajectory follows the
//! adversary's lane ([`crate::lanes`]) in Frenet coordinates instead of a straight line.
//!
//! * **Along the lane**, arc length `s(t)` is a quintic from the vehicle's state at t0 (speed
//!   along the lane, zero acceleration) to the target's arc length with the end velocity's
//!   component along the lane (zero acceleration), like [`crate::quintic`] per axis.
//! * **Across it**, the lateral offset `d` (+ left of the lane centre) is a function of arc
//!   length, so that the path's shape does not depend on the speed (a car stopping at its target
//!   arrives along the lane, not sideways): a move of more than [`LANE_CHANGE_M`] (a cut-in onto
//!   the next lane, a drift over the centre line, a side pass closing in) first follows the lane,
//!   converging on its centreline, then changes lane over the stretch it drives in the last
//!   [`LANE_CHANGE_S`] (at least [`LANE_CHANGE_MIN_M`]), with a quintic lateral profile (zero slope and curvature at both ends, or
//!   the end velocity's slope); a smaller move (the target in the vehicle's own lane: braking,
//!   tailgating) is one quintic over the whole plan.
//! * A vehicle slower than 1 m/s starts along its body, path first ([`crate::from_rest`]), the
//!   path built in `(s, d)`, so that it too bends with the road.
//!
//! The last waypoint is exactly the collision target; timing (t0 + k dt, the end at t0 + TTC) is
//! the same as for straight-line plans. `Err` says why no lane plan exists (no lane near the
//! vehicle, target behind it along the lane or too far off it); the planner then uses a
//! straight-line quintic and records which path it used.

use crate::frenet::LanePath;
use crate::from_rest::FromRest;
use crate::lanes::Lanes;
use crate::quintic::{End, Quintic};
use crate::world::Vehicle;
use scene::glam::DVec2;
use scene::Waypoint;

/// A lateral move larger than this (m) is a lane change, made at the end of the plan.
pub const LANE_CHANGE_M: f64 = 1.0;
/// Duration of a lane change (s); shorter plans change lane over their whole length.
pub const LANE_CHANGE_S: f64 = 2.5;
/// Shortest stretch of road a lane change takes (m): 3.6 m across in 20 m peaks at a curvature
/// of 0.05 1/m (3.3 m/s^2 at 8 m/s).
pub const LANE_CHANGE_MIN_M: f64 = 20.0;
/// A target farther than this from the adversary's lane centre (m, 2.5 lanes) is not a lane move.
pub const MAX_TARGET_OFFSET_M: f64 = 9.0;
/// Below this speed (m/s) the vehicle starts along its body heading.
const AT_REST: f64 = 1.0;

/// `x` from `(x0, v0, 0)` to `(x1, v1, 0)` over `duration` (a quintic in the `x` component;
/// "duration" is time for `s(t)` and arc length for `d(s)`).
fn quintic_1d(x0: f64, v0: f64, x1: f64, v1: f64, duration: f64) -> Quintic {
    let e = |p: f64, v: f64| End { p: DVec2::new(p, 0.0), v: DVec2::new(v, 0.0), a: DVec2::ZERO };
    Quintic::new(e(x0, v0), e(x1, v1), duration)
}

#[derive(Clone, Debug)]
enum Frenet {
    /// `s(t)`; `d(s)` as `keep(s - s0)` on `[s0, sa]`, then `change(s - sa)` from `sa` on.
    Split { long: Quintic, keep: Option<Quintic>, change: Quintic, s0: f64, sa: f64 },
    /// From rest: a path in the `(s, d)` plane with its own speed profile.
    FromRest(FromRest),
}

/// A trajectory along a lane: Frenet motion on a [`LanePath`].
#[derive(Clone, Debug)]
pub struct LaneMotion {
    pub path: LanePath,
    frenet: Frenet,
    target: DVec2,
    pub duration: f64,
}

impl LaneMotion {
    /// The motion of `v` from its state at t0 to `target`, reached after `duration` (s) with
    /// world velocity `v_end`; `start_accel` (m/s^2) for a vehicle at rest.
    pub fn new(
        lanes: &Lanes,
        v: &Vehicle,
        target: DVec2,
        v_end: DVec2,
        duration: f64,
        start_accel: f64,
    ) -> Result<LaneMotion, String> {
        let moving = v.now.speed() >= AT_REST;
        let heading = if moving { v.now.v.to_angle() } else { v.now.heading };
        let Some((lane, _)) = lanes.lane_of(v.now.p, heading) else {
            return Err("no lane centre within 2 m heading within 30 degrees of the vehicle".into());
        };
        let ahead = v.now.p.distance(target) * 1.5 + 20.0;
        let path = lanes.chain(lane, v.now.p, target, ahead).ok_or("its lane has no length")?;
        let (f0, f1) = (path.frenet(v.now.p), path.frenet(target));
        if f1.x <= f0.x + 0.5 {
            return Err("the target is not ahead of the vehicle along its lane".into());
        }
        if f1.y.abs() > MAX_TARGET_OFFSET_M {
            return Err(format!("the target is {:.1} m from its lane centre", f1.y.abs()));
        }
        let fv1 = path.frenet_velocity(f1, v_end);
        let frenet = if moving {
            let fv0 = path.frenet_velocity(f0, v.now.v);
            let long = quintic_1d(f0.x, fv0.x, f1.x, fv1.x, duration);
            // Lateral slopes dd/ds at both ends (level where the motion along the lane is slow).
            let slope = |f: DVec2| if f.x > 0.5 { (f.y / f.x).clamp(-0.5, 0.5) } else { 0.0 };
            let (k0, k1) = (slope(fv0), slope(fv1));
            // The lane change covers what the car drives in the last LANE_CHANGE_S, at least
            // LANE_CHANGE_MIN_M (a car slowing to its target would otherwise swerve in metres).
            let sa = long.position((duration - LANE_CHANGE_S).max(0.0)).x.min(f1.x - LANE_CHANGE_MIN_M);
            if (f1.y - f0.y).abs() > LANE_CHANGE_M && duration > LANE_CHANGE_S && sa > f0.x + 1.0 && sa < f1.x - 1.0 {
                Frenet::Split {
                    long,
                    keep: Some(quintic_1d(f0.y, k0, 0.0, 0.0, sa - f0.x)),
                    change: quintic_1d(0.0, 0.0, f1.y, k1, f1.x - sa),
                    s0: f0.x,
                    sa,
                }
            } else {
                let change = quintic_1d(f0.y, k0, f1.y, k1, f1.x - f0.x);
                Frenet::Split { long, keep: None, change, s0: f0.x, sa: f0.x }
            }
        } else {
            let body = DVec2::from_angle(v.now.heading);
            let rel = path.tangent(f0.x).perp_dot(body).atan2(path.tangent(f0.x).dot(body));
            let speed = v.now.v.dot(body).max(0.0);
            let fr = FromRest::new(f0, rel, speed, start_accel, f1, fv1, duration)
                .ok_or("from rest, the speed profile would run backwards")?;
            Frenet::FromRest(fr)
        };
        Ok(LaneMotion { path, frenet, target, duration })
    }

    /// `(s, d)` at time `t` after t0 (s).
    fn frenet_at(&self, t: f64) -> DVec2 {
        match &self.frenet {
            Frenet::Split { long, keep, change, s0, sa } => {
                let s = long.position(t).x;
                let d = match keep {
                    Some(k) if s < *sa => k.position(s - s0).x,
                    _ => change.position((s - sa).min(change.duration)).x,
                };
                DVec2::new(s, d)
            }
            Frenet::FromRest(m) => m.position(t),
        }
    }

    pub fn position(&self, t: f64) -> DVec2 {
        let f = self.frenet_at(t.clamp(0.0, self.duration));
        self.path.world(f.x, f.y)
    }

    /// World velocity at `t`: the Frenet rates along the lane's interpolated tangent and normal.
    pub fn velocity(&self, t: f64) -> DVec2 {
        let t = t.clamp(0.0, self.duration);
        let rate = match &self.frenet {
            Frenet::Split { long, keep, change, s0, sa } => {
                let (s, ds) = (long.position(t).x, long.velocity(t).x);
                let slope = match keep {
                    Some(k) if s < *sa => k.velocity(s - s0).x,
                    _ if s - sa > change.duration => 0.0,
                    _ => change.velocity(s - sa).x,
                };
                DVec2::new(ds, slope * ds)
            }
            Frenet::FromRest(m) => m.velocity(t),
        };
        self.path.world_velocity(self.frenet_at(t), rate)
    }

    /// Waypoints at `t0 + k dt`, `k = 0..=n`, `n dt = duration`; the last exactly at the target.
    pub fn waypoints(&self, t0: f64, dt: f64) -> Vec<Waypoint> {
        let n = (self.duration / dt).round() as usize;
        (0..=n)
            .map(|k| {
                let p = if k == n { self.target } else { self.position(k as f64 * dt) };
                Waypoint { t: t0 + k as f64 * dt, x: p.x, y: p.y }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::world::Kin;
    use scene::glam::DVec3;
    use scene::map::{Map, Polyline};
    use std::f64::consts::FRAC_PI_2;

    /// A left-hand curve (counter-clockwise about the origin), lanes of 10 m at radii `radii`.
    fn curve(radii: &[f64]) -> Map {
        let mut lanes = Vec::new();
        for (j, r) in radii.iter().enumerate() {
            let n = (2.5 * r / 0.5) as usize;
            let pts: Vec<DVec3> = (0..=n)
                .map(|k| -0.5 + 2.5 * k as f64 / n as f64)
                .map(|a| DVec3::new(r * a.cos(), r * a.sin(), 0.0))
                .collect();
            for (i, c) in pts.windows(21).step_by(20).enumerate() {
                lanes.push(Polyline { id: (100 * j + i) as i64, points: c.to_vec() });
            }
        }
        Map { lanes, ..Default::default() }
    }

    fn car_on(r: f64, angle: f64, speed: f64) -> Vehicle {
        let p = DVec2::new(r * angle.cos(), r * angle.sin());
        let h = angle + FRAC_PI_2;
        Vehicle {
            id: "a".into(),
            length: 4.5,
            width: 2.0,
            class: scene::ObjectClass::Vehicle,
            run: vec![],
            now: Kin { t: 0.0, p, v: DVec2::from_angle(h) * speed, heading: h },
        }
    }

    #[test]
    fn cut_in_keeps_its_lane_then_changes_onto_the_next_centreline() {
        let map = curve(&[28.2, 31.8]);
        let v = car_on(31.8, 0.0, 10.0);
        // Target on the left lane 1.3 rad further on, arriving along it at 2 m/s.
        let a1 = 1.3;
        let target = DVec2::new(28.2 * f64::cos(a1), 28.2 * f64::sin(a1));
        let v_end = DVec2::from_angle(a1 + FRAC_PI_2) * 2.0;
        let m =
            LaneMotion::new(&Lanes::from_lanes(map.clone()).unwrap(), &v, target, v_end, 4.0, 2.0).expect("on a lane");
        let w = m.waypoints(1.0, 0.1);
        assert_eq!(w.len(), 41);
        assert!((w[40].t - 5.0).abs() < 1e-9 && DVec2::new(w[40].x, w[40].y).distance(target) < 1e-12);
        let r = |k: usize| DVec2::new(w[k].x, w[k].y).length();
        // The first 1.5 s on its own lane's centre, then onto the left lane's; always between
        // the two lane centres (a straight chord would cut inside the curve).
        for (k, p) in w.iter().enumerate() {
            if k <= 15 {
                assert!((r(k) - 31.8).abs() < 0.05, "t {:.1}: r {:.2}", p.t, r(k));
            }
            assert!(r(k) > 28.2 - 0.05 && r(k) < 31.8 + 0.05, "t {:.1}: r {:.2}", p.t, r(k));
        }
        assert!((r(40) - 28.2).abs() < 0.01 && (r(39) - 28.2).abs() < 0.05);
        // Velocity matches at both ends.
        assert!((m.velocity(0.0) - v.now.v).length() < 0.05, "{}", m.velocity(0.0));
        assert!((m.velocity(4.0) - v_end).length() < 0.05, "{}", m.velocity(4.0));
    }

    #[test]
    fn no_lane_plan_off_the_lanes_the_wrong_way_or_behind() {
        let map = curve(&[30.0]);
        let target = DVec2::new(30.0 * 0.8f64.cos(), 30.0 * 0.8f64.sin());
        let ok = LaneMotion::new(
            &Lanes::from_lanes(map.clone()).unwrap(),
            &car_on(30.0, 0.0, 8.0),
            target,
            DVec2::ZERO,
            3.0,
            2.0,
        );
        assert!(ok.is_ok());
        let off = LaneMotion::new(
            &Lanes::from_lanes(map.clone()).unwrap(),
            &car_on(33.0, 0.0, 8.0),
            target,
            DVec2::ZERO,
            3.0,
            2.0,
        );
        assert!(off.unwrap_err().contains("no lane centre within 2 m"));
        let mut back = car_on(30.0, 0.0, 8.0);
        back.now.v = -back.now.v;
        back.now.heading += std::f64::consts::PI;
        assert!(
            LaneMotion::new(&Lanes::from_lanes(map.clone()).unwrap(), &back, target, DVec2::ZERO, 3.0, 2.0).is_err()
        );
        let behind = DVec2::new(30.0 * (-0.3f64).cos(), 30.0 * (-0.3f64).sin());
        let e = LaneMotion::new(
            &Lanes::from_lanes(map.clone()).unwrap(),
            &car_on(30.0, 0.0, 8.0),
            behind,
            DVec2::ZERO,
            3.0,
            2.0,
        )
        .unwrap_err();
        assert!(e.contains("not ahead"), "{e}");
    }

    #[test]
    fn from_rest_it_leaves_along_the_lane() {
        let map = curve(&[30.0]);
        let a1 = 0.9;
        let target = DVec2::new(30.0 * f64::cos(a1), 30.0 * f64::sin(a1));
        let m = LaneMotion::new(
            &Lanes::from_lanes(map.clone()).unwrap(),
            &car_on(30.0, 0.0, 0.0),
            target,
            DVec2::from_angle(a1 + FRAC_PI_2) * 6.0,
            4.0,
            2.0,
        )
        .expect("at rest on a lane");
        for w in m.waypoints(0.0, 0.1) {
            let r = DVec2::new(w.x, w.y).length();
            assert!((r - 30.0).abs() < 0.05, "t {:.1}: r {r:.3}", w.t);
        }
    }
}

#[cfg(test)]
mod drift_tests {
    use super::*;
    use crate::world::Kin;
    use scene::glam::DVec3;
    use scene::map::{Map, Polyline};

    #[test]
    fn an_oncoming_drift_keeps_its_lane_then_crosses_into_the_opposing_one() {
        // A straight two-way road along x: lane +x at y = -1.8, lane -x at y = +1.8, in 10 m pieces.
        let mut lanes = Vec::new();
        for k in 0..20 {
            let x0 = -100.0 + 10.0 * k as f64;
            let line = |y: f64, xs: [f64; 2]| xs.iter().map(|x| DVec3::new(*x, y, 0.0)).collect::<Vec<_>>();
            lanes.push(Polyline { id: k, points: line(-1.8, [x0, x0 + 10.0]) });
            lanes.push(Polyline { id: 100 + k, points: line(1.8, [x0 + 10.0, x0]) });
        }
        let map = Map { lanes, ..Default::default() };
        let car = Vehicle {
            class: scene::ObjectClass::Vehicle,
            id: "o".into(),
            length: 4.5,
            width: 2.0,
            run: vec![],
            now: Kin { t: 0.0, p: DVec2::new(60.0, 1.8), v: DVec2::new(-10.0, 0.0), heading: std::f64::consts::PI },
        };
        // Head-on target in the other lane, 36 m on, reached in 4 s at 8 m/s.
        let target = DVec2::new(24.0, -1.8);
        let m =
            LaneMotion::new(&Lanes::from_lanes(map.clone()).unwrap(), &car, target, DVec2::new(-8.0, 0.0), 4.0, 2.0)
                .unwrap();
        assert!(m.path.lane_ids.windows(2).any(|w| w == [115, 114]), "{:?}", m.path.lane_ids);
        let w = m.waypoints(0.0, 0.1);
        // In its lane until the last 2.5 s (about 21 m from the target), then across.
        for p in w.iter().filter(|p| p.x > 47.0) {
            assert!((p.y - 1.8).abs() < 1e-6, "at x {:.1}: y {:.3}", p.x, p.y);
        }
        assert!(w.iter().any(|p| p.x < 44.0 && p.y < 1.7));
        let last = w.last().unwrap();
        assert!((last.y + 1.8).abs() < 1e-9 && (last.x - 24.0).abs() < 1e-9);
        assert!(w.windows(2).all(|p| p[1].y <= p[0].y + 1e-9), "moves towards the opposing lane only");
    }
}
