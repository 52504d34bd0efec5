//! Every conversion between carla-gs's world frame and CARLA's, in one place.
//!
//! carla-gs's world frame is right-handed (x, y in the ground plane, z up), headings in radians
//! counter-clockwise from +x, SI units. CARLA's is **left-handed** (x forward, y right, z up): the
//! same physical point has its y negated, and a yaw (CARLA: degrees, positive turning from +x
//! towards +y, i.e. clockwise seen from above) is the heading negated. Speeds stay m/s.
//! CARLA's interface demands degrees for `Rotation` and for angular velocities (deg/s) and wheel
//! steer angles; `VehicleControl.steer` is positive to the right. Nothing else converts: the
//! bridge (`tools/carla_bridge.py`) passes CARLA's numbers through unchanged.
//!
//! A [`CarlaFrame`] also moves the origin: CARLA (Unreal) keeps positions in single precision, so
//! the bridge puts the world point `origin` at CARLA's (0, 0, 0). The same origin is subtracted
//! when the OpenDRIVE map is written, so the road and the actors line up.

use scene::glam::{DVec2, DVec3};
use serde::{Deserialize, Serialize};

/// A planar pose in CARLA's left-handed frame in the PID's units: x forward, y right, yaw
/// clockwise (rad).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CarlaPose {
    pub x: f64,
    pub y: f64,
    pub yaw: f64,
}

/// Our right-handed world (x, y, heading counter-clockwise) to CARLA's left-handed frame, in
/// radians (the PID's lateral error is computed there). No origin shift: angles only need the axes.
pub fn to_carla(x: f64, y: f64, heading: f64) -> CarlaPose {
    CarlaPose { x, y: -y, yaw: -heading }
}

/// A `carla.Transform` without pitch and roll as it crosses the wire: location (m) and yaw
/// (**degrees**, CARLA's unit).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct CarlaTransform {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    #[serde(rename = "yaw")]
    pub yaw_deg: f64,
}

/// carla-gs world <-> CARLA, with CARLA's origin at the world point `origin`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CarlaFrame {
    pub origin: DVec3,
}

impl CarlaFrame {
    /// CARLA's origin at `origin`, rounded to whole metres (so the OpenDRIVE file's origin and
    /// every shifted coordinate are exact decimal numbers).
    pub fn around(origin: DVec3) -> Self {
        CarlaFrame { origin: origin.round() }
    }

    /// A world pose (position of the reference point, heading in rad) as a CARLA transform.
    pub fn carla_from_world(&self, p: DVec3, heading: f64) -> CarlaTransform {
        let q = p - self.origin;
        CarlaTransform { x: q.x, y: -q.y, z: q.z, yaw_deg: (-heading).to_degrees() }
    }

    /// A CARLA transform as a world position and heading (rad, wrapped to (-pi, pi]).
    pub fn world_from_carla(&self, t: &CarlaTransform) -> (DVec3, f64) {
        let p = DVec3::new(t.x, -t.y, t.z) + self.origin;
        (p, scene::frames::wrap_angle(-t.yaw_deg.to_radians()))
    }

    /// A CARLA vector (velocity m/s, acceleration m/s^2) as a world vector: y flips, no origin.
    pub fn world_from_carla_vector(v: [f64; 3]) -> DVec3 {
        DVec3::new(v[0], -v[1], v[2])
    }

    /// A world vector as a CARLA vector.
    pub fn carla_from_world_vector(v: DVec3) -> [f64; 3] {
        [v.x, -v.y, v.z]
    }

    /// CARLA's yaw rate (deg/s about its z, clockwise positive) as ours (rad/s, counter-clockwise).
    pub fn world_yaw_rate_from_carla(deg_per_s: f64) -> f64 {
        -deg_per_s.to_radians()
    }

    /// A CARLA wheel steer angle (deg, positive = right) as our steering angle (rad, left).
    pub fn world_steering_from_carla(deg: f64) -> f64 {
        -deg.to_radians()
    }
}

/// The planar components of a world vector along and across a heading: (forward, left).
pub fn body_from_world(v: DVec3, heading: f64) -> DVec2 {
    let f = DVec2::from_angle(heading);
    DVec2::new(v.truncate().dot(f), v.truncate().dot(f.perp()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn a_known_pose() {
        // 10 m east and 5 m north of the origin, facing north (our +y, heading +90 deg): in
        // CARLA that is 5 m to the *right* of x (y = -5) with yaw -90 deg.
        let f = CarlaFrame { origin: DVec3::new(100.0, 200.0, 3.0) };
        let t = f.carla_from_world(DVec3::new(110.0, 205.0, 4.5), FRAC_PI_2);
        assert_eq!(t, CarlaTransform { x: 10.0, y: -5.0, z: 1.5, yaw_deg: -90.0 });
        // Moving along the heading: +y in our world is -y in CARLA's.
        assert_eq!(CarlaFrame::carla_from_world_vector(DVec3::new(0.0, 3.0, 0.0)), [0.0, -3.0, 0.0]);
        // Turning left (counter-clockwise) is a negative yaw rate in CARLA; steering left is a
        // negative wheel angle.
        assert!((CarlaFrame::world_yaw_rate_from_carla(-90.0) - FRAC_PI_2).abs() < 1e-12);
        assert!((CarlaFrame::world_steering_from_carla(-30.0) - 30f64.to_radians()).abs() < 1e-12);
        // The PID's frame agrees with the transform's (same y and yaw flips).
        let p = to_carla(10.0, 5.0, FRAC_PI_2);
        assert_eq!((p.x, p.y, p.yaw.to_degrees()), (10.0, -5.0, -90.0));
    }

    #[test]
    fn round_trips() {
        let f = CarlaFrame::around(DVec3::new(8123.4, -2044.6, 17.2));
        assert_eq!(f.origin, DVec3::new(8123.0, -2045.0, 17.0));
        for k in 0..40 {
            let h = -3.1 + 0.155 * k as f64;
            let p = DVec3::new(8100.0 + k as f64 * 3.7, -2050.0 + k as f64, 16.0 + 0.1 * k as f64);
            let (q, g) = f.world_from_carla(&f.carla_from_world(p, h));
            assert!((q - p).length() < 1e-9, "{q} vs {p}");
            assert!(scene::frames::wrap_angle(g - h).abs() < 1e-12, "{g} vs {h}");
            let v = DVec3::new(h, 2.0 * h, 0.5);
            assert_eq!(CarlaFrame::world_from_carla_vector(CarlaFrame::carla_from_world_vector(v)), v);
        }
        // A velocity along a heading is all forward in the body frame.
        let b = body_from_world(DVec3::new(3.0 * 0.7f64.cos(), 3.0 * 0.7f64.sin(), 0.0), 0.7);
        assert!((b - DVec2::new(3.0, 0.0)).length() < 1e-12);
    }
}
