//! A timed reference path `[(t, x, y)]` on the scene clock: position, velocity and the
//! look-ahead point the lateral controller steers to.
//!
//! * Position: linear between points ([`Reference::new`]), or a cubic Hermite spline through
//!   smoothed states (position and velocity, [`Reference::smoothed`], see `smooth.rs`); outside
//!   the span it continues at the end velocity (so a controller near the end keeps a sensible
//!   heading instead of circling the last point).
//! * Velocity: for the linear reference the central difference of the position over
//!   `+-VELOCITY_HALF_WINDOW_S`, which is the reference's own timing (no hidden clock); for the
//!   smoothed reference the spline's derivative.
//! * Look-ahead: the reference point `lookahead_s` ahead in time, pushed further along the path
//!   until it is at least `min_distance` from the vehicle.

use crate::smooth::{smooth, Sample, Smoothed, SmoothingConfig};
use scene::glam::DVec2;

pub const VELOCITY_HALF_WINDOW_S: f64 = 0.05;
/// Below this smoothed speed (m/s) the initial heading is the logged one, not the velocity's.
pub const HEADING_MIN_SPEED: f64 = 1.0;
const LOOKAHEAD_SEARCH_STEP_S: f64 = 0.05;
const LOOKAHEAD_SEARCH_MAX_S: f64 = 5.0;

/// Where a rollout starts: the reference and the vehicle's initial speed (m/s) and heading (rad).
#[derive(Clone, Debug)]
pub struct Start {
    pub reference: Reference,
    pub speed: f64,
    pub heading: f64,
}

/// The reference for a timed path whose first `n_logged` points are logged positions and the rest
/// a plan's waypoints: smoothed (`smooth.rs`; logged points with the log sigma, or the still
/// sigma when the logged run never leaves a circle of the log sigma around its median point, plan
/// waypoints with the plan sigma) unless smoothing is off. The initial speed is the reference's speed at its start; the initial heading its
/// direction of motion there, or `logged_heading` below [`HEADING_MIN_SPEED`]. A start velocity
/// pointing behind the logged body (never a real motion: the model has no reverse gear) starts
/// the car at rest along `logged_heading`.
pub fn start_for_path(
    points: &[(f64, DVec2)],
    n_logged: usize,
    logged_heading: f64,
    cfg: &SmoothingConfig,
) -> Result<Start, String> {
    let reference = if cfg.enabled {
        let log_sigma = if is_still(&points[..n_logged.min(points.len())], cfg.log_sigma_m) {
            cfg.still_sigma_m
        } else {
            cfg.log_sigma_m
        };
        let samples: Vec<Sample> = points
            .iter()
            .enumerate()
            .map(|(i, (t, p))| Sample { t: *t, p: *p, sigma: if i < n_logged { log_sigma } else { cfg.plan_sigma_m } })
            .collect();
        Reference::smoothed(&smooth(&samples, cfg)?)?
    } else {
        Reference::new(points.to_vec())?
    };
    let v = reference.velocity(reference.start_time());
    let body = DVec2::new(logged_heading.cos(), logged_heading.sin());
    // The vehicle model only drives forwards: a smoothed start velocity against the logged body
    // (a parked car's jitter bent into a parabola by a plan that pulls away, say) is not a motion
    // the car had. Then the car starts along its body, at the forward part of that velocity.
    let forward = v.dot(body) > 0.0;
    let heading = if v.length() >= HEADING_MIN_SPEED && forward { v.y.atan2(v.x) } else { logged_heading };
    let speed = if forward { v.length() } else { 0.0 };
    Ok(Start { speed, heading, reference })
}

/// At least three logged points, all within `radius` of their (per-axis) median point.
fn is_still(points: &[(f64, DVec2)], radius: f64) -> bool {
    if points.len() < 3 {
        return false;
    }
    let median = |f: fn(&DVec2) -> f64| {
        let mut v: Vec<f64> = points.iter().map(|(_, p)| f(p)).collect();
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let m = DVec2::new(median(|p| p.x), median(|p| p.y));
    points.iter().all(|(_, p)| p.distance(m) <= radius)
}

#[derive(Clone, Debug)]
pub struct Reference {
    points: Vec<(f64, DVec2)>,
    /// Velocities at the points (smoothed reference): Hermite interpolation.
    velocities: Option<Vec<DVec2>>,
}

impl Reference {
    /// Needs at least two finite points with strictly increasing time.
    pub fn new(points: Vec<(f64, DVec2)>) -> Result<Self, String> {
        if points.len() < 2 {
            return Err(format!("a reference needs at least 2 points, got {}", points.len()));
        }
        for (i, (t, p)) in points.iter().enumerate() {
            if !t.is_finite() || !p.is_finite() {
                return Err(format!("reference point {i} is not finite"));
            }
            if i > 0 && *t <= points[i - 1].0 {
                return Err(format!(
                    "reference times must increase strictly (point {i}: {t} after {})",
                    points[i - 1].0
                ));
            }
        }
        Ok(Reference { points, velocities: None })
    }

    /// A spline through smoothed states (same requirements as [`Reference::new`]).
    pub fn smoothed(states: &[Smoothed]) -> Result<Self, String> {
        let mut r = Reference::new(states.iter().map(|s| (s.t, s.p)).collect())?;
        if states.iter().any(|s| !s.v.is_finite()) {
            return Err("smoothed reference: velocities must be finite".into());
        }
        r.velocities = Some(states.iter().map(|s| s.v).collect());
        Ok(r)
    }

    pub fn start_time(&self) -> f64 {
        self.points[0].0
    }

    pub fn end_time(&self) -> f64 {
        self.points[self.points.len() - 1].0
    }

    fn end_velocity(&self, first: bool) -> DVec2 {
        let n = self.points.len();
        if let Some(v) = &self.velocities {
            return if first { v[0] } else { v[n - 1] };
        }
        let ((t0, p0), (t1, p1)) =
            if first { (self.points[0], self.points[1]) } else { (self.points[n - 2], self.points[n - 1]) };
        (p1 - p0) / (t1 - t0)
    }

    pub fn position(&self, t: f64) -> DVec2 {
        let (ts, ps) = (self.start_time(), self.points[0].1);
        let (te, pe) = self.points[self.points.len() - 1];
        if t <= ts {
            return ps + self.end_velocity(true) * (t - ts);
        }
        if t >= te {
            return pe + self.end_velocity(false) * (t - te);
        }
        let i = self.points.partition_point(|(ti, _)| *ti <= t);
        let ((t0, p0), (t1, p1)) = (self.points[i - 1], self.points[i]);
        let s = (t - t0) / (t1 - t0);
        match &self.velocities {
            None => p0 + (p1 - p0) * s,
            Some(v) => {
                let h = t1 - t0;
                let (s2, s3) = (s * s, s * s * s);
                p0 * (2.0 * s3 - 3.0 * s2 + 1.0)
                    + v[i - 1] * (h * (s3 - 2.0 * s2 + s))
                    + p1 * (3.0 * s2 - 2.0 * s3)
                    + v[i] * (h * (s3 - s2))
            }
        }
    }

    pub fn velocity(&self, t: f64) -> DVec2 {
        if let Some(v) = &self.velocities {
            let (ts, te) = (self.start_time(), self.end_time());
            if t <= ts || t >= te {
                return self.end_velocity(t <= ts);
            }
            let i = self.points.partition_point(|(ti, _)| *ti <= t);
            let ((t0, p0), (t1, p1)) = (self.points[i - 1], self.points[i]);
            let h = t1 - t0;
            let s = (t - t0) / h;
            let s2 = s * s;
            return (p0 * (6.0 * s2 - 6.0 * s) + p1 * (6.0 * s - 6.0 * s2)) / h
                + v[i - 1] * (3.0 * s2 - 4.0 * s + 1.0)
                + v[i] * (3.0 * s2 - 2.0 * s);
        }
        let h = VELOCITY_HALF_WINDOW_S;
        (self.position(t + h) - self.position(t - h)) / (2.0 * h)
    }

    /// The point to steer to from `from` at time `t`.
    pub fn lookahead(&self, t: f64, from: DVec2, lookahead_s: f64, min_distance: f64) -> DVec2 {
        let mut tau = t + lookahead_s;
        let mut p = self.position(tau);
        while p.distance(from) < min_distance && tau < t + LOOKAHEAD_SEARCH_MAX_S {
            tau += LOOKAHEAD_SEARCH_STEP_S;
            p = self.position(tau);
        }
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn line() -> Reference {
        Reference::new((0..=10).map(|i| (i as f64 * 0.1, DVec2::new(i as f64, 0.0))).collect()).unwrap()
    }

    #[test]
    fn position_velocity_lookahead() {
        let r = line();
        assert!((r.position(0.25) - DVec2::new(2.5, 0.0)).length() < 1e-12);
        assert!((r.velocity(0.5) - DVec2::new(10.0, 0.0)).length() < 1e-9);
        // Past the end: continues at the end velocity.
        assert!((r.position(1.2) - DVec2::new(12.0, 0.0)).length() < 1e-9);
        // 0.2 s ahead is 2 m, below the 3 m minimum: pushed to 3 m.
        let p = r.lookahead(0.0, DVec2::ZERO, 0.2, 3.0);
        assert!((p.x - 3.0).abs() < 0.51 && p.x >= 3.0);
    }

    #[test]
    fn smoothed_reference_interpolates_position_and_velocity() {
        // Hermite through samples of p = (t^3, 2t): exact for cubics.
        let f = |t: f64| DVec2::new(t.powi(3), 2.0 * t);
        let df = |t: f64| DVec2::new(3.0 * t * t, 2.0);
        let states: Vec<Smoothed> =
            (0..=10).map(|i| i as f64 * 0.1).map(|t| Smoothed { t, p: f(t), v: df(t), a: DVec2::ZERO }).collect();
        let r = Reference::smoothed(&states).unwrap();
        for t in [0.05, 0.33, 0.71, 0.99] {
            assert!((r.position(t) - f(t)).length() < 1e-12, "{t}");
            assert!((r.velocity(t) - df(t)).length() < 1e-12, "{t}");
        }
        // Outside: continues at the end velocity.
        assert!((r.position(1.1) - (f(1.0) + df(1.0) * 0.1)).length() < 1e-12);
        assert!((r.velocity(-1.0) - df(0.0)).length() < 1e-12);
    }

    #[test]
    fn rejects_bad_points() {
        assert!(Reference::new(vec![(0.0, DVec2::ZERO)]).is_err());
        assert!(Reference::new(vec![(0.0, DVec2::ZERO), (0.0, DVec2::X)]).is_err());
        assert!(Reference::new(vec![(0.0, DVec2::ZERO), (0.1, DVec2::NAN)]).is_err());
    }
}
