//! The mirrored scene: the world reflected in its x-z plane, `M = diag(1, -1, 1)` (y -> -y).
//!
//! Points (track centres, map polylines, ego positions) and vectors (velocities) are multiplied by
//! `M`; a box heading `h` becomes `-h` (not wrapped again, so that the copy is exact). A reflection turns a right-handed frame into a left-handed
//! one, so a rigid pose `world_from_ego = [R | t]` becomes `[M R M | M t]`: the conjugation keeps
//! the ego frame right-handed with x forward (the mirrored forward), y left (the left of the
//! mirrored car) and z up, and its yaw becomes `-yaw`. Lane polylines keep their point order, so
//! lanes keep their direction of travel.
//!
//! For driving this swaps the side of the road: a log of right-hand traffic (the US logs of WOMD
//! and PandaSet) becomes left-hand traffic (as in the UK or Japan), oncoming traffic passes on the
//! ego's left becomes on its right, kerb-side parking moves to the other side. Mirroring twice is
//! the identity (exactly: negation is exact in floating point).

use super::copy::without_sensors;
use scene::glam::{DMat3, DVec3};
use scene::{Scene, Transform3};

/// `M`, the reflection y -> -y.
pub const MIRROR: DMat3 = DMat3::from_cols(DVec3::X, DVec3::NEG_Y, DVec3::Z);

fn point(p: DVec3) -> DVec3 {
    DVec3::new(p.x, -p.y, p.z)
}

/// The mirrored rigid transform `M T M` (a proper rotation again).
pub fn mirror_transform(t: &Transform3) -> Transform3 {
    Transform3::from_rotation_translation(MIRROR * t.rotation() * MIRROR, point(t.translation()))
}

/// The mirrored copy of `s`, named `<name>-mirror` (twice: `<name>-mirror-mirror`).
pub fn mirror(s: &Scene) -> Scene {
    let mut out = without_sensors(s, "mirror");
    for f in &mut out.frames {
        f.world_from_ego = mirror_transform(&f.world_from_ego);
    }
    for t in &mut out.tracks {
        for st in &mut t.states {
            st.center = point(st.center);
            st.heading = -st.heading;
            st.velocity = st.velocity.map(point);
        }
    }
    if let Some(m) = &mut out.map {
        for l in m.lanes.iter_mut().chain(&mut m.road_edges).chain(&mut m.road_lines) {
            for p in &mut l.points {
                *p = point(*p);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stress::fixture::street;
    use scene::frames::wrap_angle;

    #[test]
    fn twice_is_the_identity() {
        let s = street();
        let mut twice = mirror(&mirror(&s));
        assert_eq!(twice.name, "street-mirror-mirror");
        twice.name = s.name.clone();
        assert_eq!(twice, s);
    }

    #[test]
    fn frames_stay_right_handed_and_sides_swap() {
        let s = street();
        let m = mirror(&s);
        for f in &m.frames {
            assert!((f.world_from_ego.rotation().determinant() - 1.0).abs() < 1e-12);
            assert!(f.world_from_ego.orthonormality_error() < 1e-12);
        }
        // A turning pose: yaw 0.3 becomes -0.3, the left axis is the mirrored car's left.
        let t = Transform3::from_yaw_translation(0.3, DVec3::new(1.0, 2.0, 0.5));
        let mt = mirror_transform(&t);
        assert!((mt.yaw() + 0.3).abs() < 1e-12);
        let fwd = mt.transform_vector(DVec3::X);
        let left = mt.transform_vector(DVec3::Y);
        assert!((fwd.cross(left) - DVec3::Z).length() < 1e-12);
        assert!((mt.translation() - DVec3::new(1.0, -2.0, 0.5)).length() < 1e-12);
        // The car in the left lane is now on the ego's right; the oncoming car still heads -x.
        let left_car = m.track("left").unwrap().state_at(0).unwrap();
        assert!(left_car.center.y < 0.0);
        let oncoming = m.track("oncoming").unwrap().state_at(0).unwrap();
        assert!((wrap_angle(oncoming.heading - std::f64::consts::PI)).abs() < 1e-12);
        let walker = m.track("walker").unwrap().state_at(5).unwrap();
        assert!(walker.velocity.unwrap().y < 0.0 && (walker.heading + std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        // Lanes keep their direction of travel.
        let lane = &m.map.as_ref().unwrap().lanes[0].points;
        assert!(lane[1].x > lane[0].x);
    }
}
