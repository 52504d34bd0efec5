//! The ego's route: the logged ego path as a polyline (points about a metre apart), extended
//! straight past its end, with arc length. A policy keeps its lane by following it; the
//! built-in policies project the ego and the objects onto it (arc length along, signed offset
//! across, + = left).

use scene::glam::DVec2;
use scene::Scene;

/// Spacing of the route's points (m).
const SPACING_M: f64 = 1.0;
/// How far the route runs on straight past the log's end (m).
const EXTENSION_M: f64 = 200.0;

#[derive(Clone, Debug, PartialEq)]
pub struct Route {
    points: Vec<DVec2>,
    /// Arc length at each point (m).
    s: Vec<f64>,
}

impl Route {
    /// The logged ego path of `scene` from `t_from` on (a stretch without motion is one
    /// point); heading `heading_at_start` where the log never moves.
    pub fn from_log(scene: &Scene, t_from: f64) -> Route {
        let series = scene.ego_series();
        let mut pts: Vec<DVec2> = Vec::new();
        let start = crate::world::logged_ego(scene, t_from).0;
        pts.push(start.position());
        for p in series.iter().filter(|p| p.t > t_from) {
            if p.position().distance(*pts.last().unwrap()) >= SPACING_M {
                pts.push(p.position());
            }
        }
        let dir = match pts.len() {
            1 => DVec2::new(start.heading.cos(), start.heading.sin()),
            n => (pts[n - 1] - pts[n - 2]).normalize_or(DVec2::X),
        };
        let end = *pts.last().unwrap();
        pts.push(end + dir * EXTENSION_M);
        Route::new(pts)
    }

    /// A route through `points` (at least one; consecutive duplicates are dropped).
    pub fn new(points: Vec<DVec2>) -> Route {
        let mut pts: Vec<DVec2> = Vec::with_capacity(points.len());
        for p in points {
            if pts.last().is_none_or(|q: &DVec2| q.distance(p) > 1e-6) {
                pts.push(p);
            }
        }
        if pts.len() == 1 {
            pts.push(pts[0] + DVec2::X * EXTENSION_M);
        }
        let mut s = vec![0.0];
        for w in pts.windows(2) {
            s.push(s[s.len() - 1] + w[0].distance(w[1]));
        }
        Route { points: pts, s }
    }

    pub fn points(&self) -> &[DVec2] {
        &self.points
    }

    pub fn length(&self) -> f64 {
        self.s[self.s.len() - 1]
    }

    /// The arc length of the point of the route nearest to `p`, and the signed offset of `p`
    /// from it (m, + = left of the route's direction).
    pub fn project(&self, p: DVec2) -> (f64, f64) {
        let mut best = (f64::INFINITY, 0.0, 0.0);
        for (i, w) in self.points.windows(2).enumerate() {
            let d = w[1] - w[0];
            let len2 = d.length_squared();
            let u = if len2 > 0.0 { ((p - w[0]).dot(d) / len2).clamp(0.0, 1.0) } else { 0.0 };
            let q = w[0] + d * u;
            let dist = p.distance(q);
            if dist < best.0 {
                let side = d.perp_dot(p - w[0]).signum();
                best = (dist, self.s[i] + u * len2.sqrt(), side * dist);
            }
        }
        (best.1, best.2)
    }

    /// The point at arc length `s` (clamped to the route).
    pub fn at(&self, s: f64) -> DVec2 {
        let s = s.clamp(0.0, self.length());
        let i = self.s.partition_point(|x| *x <= s).clamp(1, self.points.len() - 1);
        let (a, b) = (self.points[i - 1], self.points[i]);
        let seg = self.s[i] - self.s[i - 1];
        if seg <= 0.0 {
            return a;
        }
        a + (b - a) * ((s - self.s[i - 1]) / seg)
    }

    /// The unit direction of the route at arc length `s`.
    pub fn direction(&self, s: f64) -> DVec2 {
        let s = s.clamp(0.0, self.length());
        let i = self.s.partition_point(|x| *x <= s).clamp(1, self.points.len() - 1);
        (self.points[i] - self.points[i - 1]).normalize_or(DVec2::X)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projects_along_and_across() {
        let r = Route::new(vec![DVec2::ZERO, DVec2::new(10.0, 0.0), DVec2::new(10.0, 10.0)]);
        assert_eq!(r.length(), 20.0);
        let (s, d) = r.project(DVec2::new(4.0, 1.5));
        assert!((s - 4.0).abs() < 1e-12 && (d - 1.5).abs() < 1e-12);
        let (s, d) = r.project(DVec2::new(11.0, 5.0));
        assert!((s - 15.0).abs() < 1e-12 && (d + 1.0).abs() < 1e-12, "{s} {d}");
        assert!(r.at(15.0).distance(DVec2::new(10.0, 5.0)) < 1e-12);
        assert!(r.direction(15.0).distance(DVec2::Y) < 1e-12);
    }
}
