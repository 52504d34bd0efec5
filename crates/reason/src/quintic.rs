//! Smooth time-parametrised trajectories: per axis a quintic polynomial `p(s)`, `s in [0, T]`,
//! matching position, velocity and acceleration at both ends (minimum-jerk boundary problem).
//! Used by the planner, the repair step and the local LLM's trajectory agent to produce
//! waypoints; [`limits`] measures them the same way validation does.

use scene::glam::DVec2;
use scene::Waypoint;

/// Boundary state of one end.
#[derive(Clone, Copy, Debug)]
pub struct End {
    pub p: DVec2,
    pub v: DVec2,
    pub a: DVec2,
}

/// Coefficients `c0..c5` for both axes.
#[derive(Clone, Debug)]
pub struct Quintic {
    c: [DVec2; 6],
    pub duration: f64,
}

impl Quintic {
    pub fn new(start: End, end: End, duration: f64) -> Self {
        let t = duration;
        let (t2, t3, t4, t5) = (t * t, t * t * t, t.powi(4), t.powi(5));
        let c0 = start.p;
        let c1 = start.v;
        let c2 = start.a / 2.0;
        // Solve for c3, c4, c5 from the end conditions.
        let d0 = end.p - (c0 + c1 * t + c2 * t2);
        let d1 = end.v - (c1 + 2.0 * c2 * t);
        let d2 = end.a - 2.0 * c2;
        let c3 = (d0 * 20.0 - d1 * (8.0 * t) + d2 * t2) / (2.0 * t3);
        let c4 = (d0 * -30.0 + d1 * (14.0 * t) - d2 * (2.0 * t2)) / (2.0 * t4);
        let c5 = (d0 * 12.0 - d1 * (6.0 * t) + d2 * t2) / (2.0 * t5);
        Quintic { c: [c0, c1, c2, c3, c4, c5], duration }
    }

    pub fn position(&self, s: f64) -> DVec2 {
        let c = &self.c;
        c[0] + s * (c[1] + s * (c[2] + s * (c[3] + s * (c[4] + s * c[5]))))
    }

    pub fn velocity(&self, s: f64) -> DVec2 {
        let c = &self.c;
        c[1] + s * (2.0 * c[2] + s * (3.0 * c[3] + s * (4.0 * c[4] + s * 5.0 * c[5])))
    }

    pub fn acceleration(&self, s: f64) -> DVec2 {
        let c = &self.c;
        2.0 * c[2] + s * (6.0 * c[3] + s * (12.0 * c[4] + s * 20.0 * c[5]))
    }

    /// Waypoints at `t0 + k dt` for `k = 0..=n` with `n dt = duration` (the last one exactly at
    /// the end point).
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

/// Speed, acceleration and jerk extremes of waypoints by finite differences, the way
/// validation measures them: speed from first differences, acceleration from second
/// differences, jerk from third differences.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Limits {
    pub max_speed: f64,
    pub max_accel: f64,
    pub max_jerk: f64,
    /// Smallest speed in the interior (a cusp shows as a near-zero speed with a reversal).
    pub reversal: bool,
}

pub fn limits(w: &[Waypoint]) -> Limits {
    let v: Vec<DVec2> =
        w.windows(2).map(|p| DVec2::new(p[1].x - p[0].x, p[1].y - p[0].y) / (p[1].t - p[0].t)).collect();
    let a: Vec<DVec2> =
        v.windows(2).zip(w.windows(3)).map(|(v, p)| (v[1] - v[0]) / ((p[2].t - p[0].t) / 2.0)).collect();
    let j: Vec<DVec2> =
        a.windows(2).zip(w.windows(4)).map(|(a, p)| (a[1] - a[0]) / ((p[3].t - p[0].t) / 3.0)).collect();
    let max = |xs: &[DVec2]| xs.iter().map(|x| x.length()).fold(0.0, f64::max);
    let reversal = v.windows(2).any(|p| p[0].length() > 0.2 && p[1].length() > 0.2 && p[0].dot(p[1]) < 0.0);
    Limits { max_speed: max(&v), max_accel: max(&a), max_jerk: max(&j), reversal }
}

/// Whether a car could follow waypoints: it never moves backwards relative to `heading0` (its
/// body heading at the start), and its yaw rate and path curvature (from the direction of
/// successive finite-difference velocities, where speed > 1 m/s, and from the geometry of the
/// path at any speed: [`path_curvature`]) stay within bounds.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Trackability {
    pub backward: bool,
    pub max_yaw_rate: f64,
    pub max_curvature: f64,
    /// Largest |d curvature / dt| (1/(m s)): what the steering-rate limit bounds.
    pub max_curvature_rate: f64,
}

pub fn trackability(w: &[Waypoint], heading0: f64) -> Trackability {
    let h0 = DVec2::new(heading0.cos(), heading0.sin());
    let v: Vec<(DVec2, f64)> = w
        .windows(2)
        .map(|p| (DVec2::new(p[1].x - p[0].x, p[1].y - p[0].y) / (p[1].t - p[0].t), p[1].t - p[0].t))
        .collect();
    let backward = v.iter().any(|(v, _)| v.length() > 0.3 && v.dot(h0) < 0.0);
    let (mut yaw, mut curv, mut curv_rate) = (0.0f64, 0.0f64, 0.0f64);
    // Signed curvature between successive velocity samples; its rate only where the speed is
    // above 2 m/s (below that, finite differences at dt are too noisy to judge steering).
    let mut last: Option<f64> = None;
    for p in v.windows(2) {
        let ((a, dt), (b, _)) = (p[0], p[1]);
        if a.length() > 1.0 && b.length() > 1.0 {
            let dpsi = a.perp_dot(b).atan2(a.dot(b));
            let k = dpsi / (0.5 * (a.length() + b.length()) * dt);
            yaw = yaw.max(dpsi.abs() / dt);
            curv = curv.max(k.abs());
            if a.length() > 2.0 && b.length() > 2.0 {
                if let Some(l) = last {
                    curv_rate = curv_rate.max((k - l).abs() / dt);
                }
                last = Some(k);
            } else {
                last = None;
            }
        }
    }
    let starts_at_rest = v.first().is_some_and(|(v, _)| v.length() < 1.0);
    let curv = curv.max(path_curvature(w, starts_at_rest.then_some(heading0)));
    Trackability { backward, max_yaw_rate: yaw, max_curvature: curv, max_curvature_rate: curv_rate }
}

/// Shortest chord between the points where [`path_curvature`] measures headings (m).
pub const CURVATURE_STEP_M: f64 = 0.5;

/// Largest geometric curvature (1/m) of the waypoints, at any speed: from the first waypoint,
/// the next one at least [`CURVATURE_STEP_M`] away is kept, and so on; the heading change between
/// successive chords divided by their mean length is the discrete curvature (exact for points
/// on a circle). Slow stretches, which the velocity-based measure skips, are where a path can
/// turn on the spot; no car can. With `start_heading` (a car at rest: its body heading) the first
/// chord is also compared with it over half its length, so a path that leaves sideways shows as
/// a sharp curvature.
pub fn path_curvature(w: &[Waypoint], start_heading: Option<f64>) -> f64 {
    let wrap = |a: f64| a.sin().atan2(a.cos());
    let mut chords: Vec<DVec2> = Vec::new();
    let mut anchor = match w.first() {
        Some(p) => DVec2::new(p.x, p.y),
        None => return 0.0,
    };
    for p in w.iter().skip(1) {
        let p = DVec2::new(p.x, p.y);
        if anchor.distance(p) >= CURVATURE_STEP_M {
            chords.push(p - anchor);
            anchor = p;
        }
    }
    let mut k = chords
        .windows(2)
        .map(|c| wrap(c[1].to_angle() - c[0].to_angle()).abs() / (0.5 * (c[0].length() + c[1].length())))
        .fold(0.0, f64::max);
    if let (Some(h0), Some(first)) = (start_heading, chords.first()) {
        k = k.max(wrap(first.to_angle() - h0).abs() / (0.5 * first.length()));
    }
    k
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meets_boundary_conditions() {
        let start = End { p: DVec2::new(1.0, 2.0), v: DVec2::new(10.0, 0.0), a: DVec2::new(0.5, 0.0) };
        let end = End { p: DVec2::new(30.0, 3.5), v: DVec2::new(4.0, 0.5), a: DVec2::ZERO };
        let q = Quintic::new(start, end, 3.0);
        for (got, want) in [
            (q.position(0.0), start.p),
            (q.velocity(0.0), start.v),
            (q.acceleration(0.0), start.a),
            (q.position(3.0), end.p),
            (q.velocity(3.0), end.v),
            (q.acceleration(3.0), end.a),
        ] {
            assert!((got - want).length() < 1e-9, "{got} vs {want}");
        }
        let w = q.waypoints(5.0, 0.1);
        assert_eq!(w.len(), 31);
        assert!((w[30].t - 8.0).abs() < 1e-9 && (DVec2::new(w[30].x, w[30].y) - end.p).length() < 1e-12);
    }

    #[test]
    fn trackability_of_turns_and_reversals() {
        // 10 m/s on a 20 m radius: yaw rate 0.5 rad/s, curvature 0.05 1/m.
        let w: Vec<Waypoint> = (0..=30)
            .map(|k| {
                let a = 0.5 * k as f64 * 0.1;
                Waypoint { t: k as f64 * 0.1, x: 20.0 * a.sin(), y: 20.0 * (1.0 - a.cos()) }
            })
            .collect();
        let t = trackability(&w, 0.0);
        assert!(!t.backward && (t.max_yaw_rate - 0.5).abs() < 1e-3 && (t.max_curvature - 0.05).abs() < 1e-3, "{t:?}");
        // The same path against a body facing the other way is backwards.
        assert!(trackability(&w, std::f64::consts::PI).backward);
    }

    #[test]
    fn path_curvature_at_walking_pace_and_from_rest() {
        // 0.5 m/s on a 4 m radius: the velocity measure skips it (speed < 1 m/s), geometry does not.
        let w: Vec<Waypoint> = (0..=200)
            .map(|k| {
                let a = 0.125 * k as f64 * 0.1;
                Waypoint { t: k as f64 * 0.1, x: 4.0 * a.sin(), y: 4.0 * (1.0 - a.cos()) }
            })
            .collect();
        assert!((path_curvature(&w, None) - 0.25).abs() < 0.01, "{}", path_curvature(&w, None));
        assert!(trackability(&w, 0.0).max_curvature > 0.24);
        // A straight path that leaves 35 degrees off the body of a car at rest turns on the spot.
        let dir = DVec2::from_angle(35f64.to_radians());
        let straight: Vec<Waypoint> = (0..=30)
            .map(|k| {
                let t = k as f64 * 0.1;
                let p = dir * (0.5 * 2.0 * t * t);
                Waypoint { t, x: p.x, y: p.y }
            })
            .collect();
        assert!(path_curvature(&straight, None) < 1e-9);
        // The first kept point is the first at least 0.5 m out: 0.64 m (t = 0.8 s).
        let k = path_curvature(&straight, Some(0.0));
        assert!((k - 35f64.to_radians() / 0.32).abs() < 1e-9, "{k}");
        assert!((trackability(&straight, 0.0).max_curvature - k).abs() < 1e-12);
    }

    #[test]
    fn limits_by_finite_differences() {
        // Constant deceleration 3 m/s^2 from 12 m/s, sampled exactly.
        let w: Vec<Waypoint> = (0..=30)
            .map(|k| {
                let t = k as f64 * 0.1;
                Waypoint { t, x: 12.0 * t - 1.5 * t * t, y: 0.0 }
            })
            .collect();
        let l = limits(&w);
        assert!((l.max_speed - 11.85).abs() < 1e-9);
        assert!((l.max_accel - 3.0).abs() < 1e-9);
        assert!(l.max_jerk < 1e-6 && !l.reversal);
        let back: Vec<Waypoint> =
            (0..=10).map(|k| Waypoint { t: k as f64 * 0.1, x: -((k as f64 - 5.0).powi(2)), y: 0.0 }).collect();
        assert!(limits(&back).reversal);
    }
}
