//! Time to collision at constant velocity, two ways:
//!
//! * **Centre TTC** (the paper's): `r = p_adv - p_ego`, `closing = -(r . v_rel) / |r|`,
//!   `TTC = |r| / closing` if `closing > 0`, else infinite; capped at [`TTC_CAP_S`].
//!   It ignores the vehicles' extent, so it overstates the time to contact.
//! * **Box TTC**: the exact time at which the two oriented boxes, each moving at its constant
//!   velocity (no rotation), first touch (parry2d shape casting, separating-axis based), 0 if
//!   they already overlap, capped at [`TTC_CAP_S`].

use parry2d_f64::math::{Pose2 as PPose, Vector};
use parry2d_f64::query::{cast_shapes, intersection_test, ShapeCastOptions};
use parry2d_f64::shape::Cuboid;
use scene::glam::DVec2;
use scene::motion::Pose2;

pub const TTC_CAP_S: f64 = 5.0;

/// Paper centre TTC for one instant, capped at [`TTC_CAP_S`] (`scene::motion::center_ttc`).
pub fn center_ttc(p_ego: DVec2, v_ego: DVec2, p_adv: DVec2, v_adv: DVec2) -> f64 {
    scene::motion::center_ttc(p_ego, v_ego, p_adv, v_adv, TTC_CAP_S)
}

/// A box footprint: pose and (length, width).
#[derive(Clone, Copy, Debug)]
pub struct Footprint {
    pub pose: Pose2,
    pub length: f64,
    pub width: f64,
}

impl Footprint {
    fn parry(&self) -> (PPose, Cuboid) {
        (
            PPose::new(Vector::new(self.pose.x, self.pose.y), self.pose.heading),
            Cuboid::new(Vector::new(self.length / 2.0, self.width / 2.0)),
        )
    }

    pub fn overlaps(&self, other: &Footprint) -> bool {
        let ((p1, c1), (p2, c2)) = (self.parry(), other.parry());
        intersection_test(&p1, &c1, &p2, &c2).map(|h| h.intersecting).unwrap_or(false)
    }
}

/// Box TTC for one instant (capped): first contact of `a` moving at `va` and `b` at `vb`.
pub fn box_ttc(a: &Footprint, va: DVec2, b: &Footprint, vb: DVec2) -> f64 {
    if a.overlaps(b) {
        return 0.0;
    }
    let ((p1, c1), (p2, c2)) = (a.parry(), b.parry());
    let options = ShapeCastOptions::with_max_time_of_impact(TTC_CAP_S);
    match cast_shapes(&p1, Vector::new(va.x, va.y), &c1, &p2, Vector::new(vb.x, vb.y), &c2, options) {
        Ok(Some(hit)) => hit.time_of_impact.min(TTC_CAP_S),
        _ => TTC_CAP_S,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fp(x: f64, y: f64, heading: f64) -> Footprint {
        Footprint { pose: Pose2 { t: 0.0, x, y, heading }, length: 4.5, width: 2.0 }
    }

    #[test]
    fn head_on() {
        // 50 m apart, closing at 20 m/s: centres meet at 2.5 s, fronts touch at (50 - 4.5) / 20.
        let (ve, va) = (DVec2::new(10.0, 0.0), DVec2::new(-10.0, 0.0));
        assert!((center_ttc(DVec2::ZERO, ve, DVec2::new(50.0, 0.0), va) - 2.5).abs() < 1e-12);
        let t = box_ttc(&fp(0.0, 0.0, 0.0), ve, &fp(50.0, 0.0, std::f64::consts::PI), va);
        assert!((t - 2.275).abs() < 1e-6, "{t}");
    }

    #[test]
    fn receding_parallel_and_overlapping() {
        let v = DVec2::new(10.0, 0.0);
        assert_eq!(center_ttc(DVec2::ZERO, v, DVec2::new(20.0, 0.0), v), TTC_CAP_S);
        assert_eq!(center_ttc(DVec2::ZERO, v, DVec2::new(-20.0, 0.0), DVec2::ZERO), TTC_CAP_S);
        assert_eq!(box_ttc(&fp(0.0, 0.0, 0.0), v, &fp(20.0, 0.0, 0.0), v), TTC_CAP_S);
        assert_eq!(box_ttc(&fp(0.0, 0.0, 0.0), v, &fp(3.0, 1.0, 0.3), DVec2::ZERO), 0.0);
        // Side by side 3 m apart laterally, adversary drifting in at 1 m/s: boxes touch after 1 s,
        // centres would need 3 s.
        let drift = DVec2::new(0.0, -1.0);
        assert!((center_ttc(DVec2::ZERO, DVec2::ZERO, DVec2::new(0.0, 3.0), drift) - 3.0).abs() < 1e-12);
        assert!((box_ttc(&fp(0.0, 0.0, 0.0), DVec2::ZERO, &fp(0.0, 3.0, 0.0), drift) - 1.0).abs() < 1e-6);
    }
}
