//! A timed reference path `[(t, x, y)]` on the scene clock: position, velocity and the
//! look-ahead point the lateral controller steers to.
//!
//! * Position: linear between points; outside the span it continues at the end velocity
//!   (so a controller near the end keeps a sensible heading instead of circling the last point).
//! * Velocity: central difference of the position over `+-VELOCITY_HALF_WINDOW_S`, which is
//!   the reference's own timing (no hidden clock).
//! * Look-ahead: the reference point `lookahead_s` ahead in time, pushed further along the path
//!   until it is at least `min_distance` from the vehicle.

use scene::glam::DVec2;

pub const VELOCITY_HALF_WINDOW_S: f64 = 0.05;
const LOOKAHEAD_SEARCH_STEP_S: f64 = 0.05;
const LOOKAHEAD_SEARCH_MAX_S: f64 = 5.0;

#[derive(Clone, Debug)]
pub struct Reference {
    points: Vec<(f64, DVec2)>,
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
        Ok(Reference { points })
    }

    pub fn start_time(&self) -> f64 {
        self.points[0].0
    }

    pub fn end_time(&self) -> f64 {
        self.points[self.points.len() - 1].0
    }

    fn end_velocity(&self, first: bool) -> DVec2 {
        let n = self.points.len();
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
        p0 + (p1 - p0) * ((t - t0) / (t1 - t0))
    }

    pub fn velocity(&self, t: f64) -> DVec2 {
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
    fn rejects_bad_points() {
        assert!(Reference::new(vec![(0.0, DVec2::ZERO)]).is_err());
        assert!(Reference::new(vec![(0.0, DVec2::ZERO), (0.0, DVec2::X)]).is_err());
        assert!(Reference::new(vec![(0.0, DVec2::ZERO), (0.1, DVec2::NAN)]).is_err());
    }
}
