//! Motion limits of the road users that are not cars, shared by the planner (`reason`, its
//! feasibility check) and the simulator (`sim`, which enforces them while executing a plan), so
//! that both use one set of numbers. Vehicles have none here: their limits are the planner's
//! trackability bounds and the vehicle model's (`sim::params`).
//!
//! All values are SI and deliberately round; the sources they are read from:
//!
//! * **Pedestrian** (point mass, may turn on the spot): walking at about 1.4 m/s (Knoblauch,
//!   Pietrucha, Nitzburg, "Field studies of pedestrian walking speed and start-up time", TRR 1538,
//!   1996: mean crossing speeds 1.25 to 1.51 m/s; Euro NCAP's AEB VRU protocol moves its adult
//!   target at 5 km/h and its running adult at 8 km/h); running out at up to 3.5 m/s (jogging
//!   pace; a sprint is faster, a child darting out slower); |acceleration| <= 2.5 m/s^2 (gait
//!   initiation reaches walking speed in about one second, a running start somewhat harder).
//! * **Cyclist** (kinematic single track: moves along its heading, turns with bounded curvature):
//!   up to 10 m/s (36 km/h, a fast urban rider; Euro NCAP's cyclist target rides at 15 to
//!   20 km/h); +2 m/s^2 accelerating and -3 m/s^2 braking (AASHTO's Guide for the Development of
//!   Bicycle Facilities, 2012, designs stopping sight distance for about 3 m/s^2 on wet pavement);
//!   lateral acceleration <= 3 m/s^2 (a lean of about 17 degrees: tan(17 deg) g); curvature
//!   <= 0.3 1/m (a turning radius of about 3.3 m).

use crate::track::ObjectClass;
use serde::{Deserialize, Serialize};

/// How a road user may move (SI units).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct MotionLimits {
    /// Top speed (m/s).
    pub max_speed: f64,
    /// Largest acceleration along the direction of motion (m/s^2); for a point mass, the largest
    /// |acceleration| in any direction.
    pub max_accel: f64,
    /// Largest deceleration (m/s^2, positive).
    pub max_decel: f64,
    /// Largest lateral (centripetal) acceleration (m/s^2).
    pub max_lat_accel: f64,
    /// Largest path curvature (1/m); `None`: turns on the spot (a point mass).
    pub max_curvature: Option<f64>,
}

/// A pedestrian's usual walking speed (m/s; Knoblauch et al. 1996, see above).
pub const WALKING_SPEED: f64 = 1.4;

/// A walking or running pedestrian (see the module documentation for the sources).
pub const PEDESTRIAN: MotionLimits =
    MotionLimits { max_speed: 3.5, max_accel: 2.5, max_decel: 2.5, max_lat_accel: 2.5, max_curvature: None };

/// A cyclist (see the module documentation for the sources).
pub const CYCLIST: MotionLimits =
    MotionLimits { max_speed: 10.0, max_accel: 2.0, max_decel: 3.0, max_lat_accel: 3.0, max_curvature: Some(0.3) };

impl ObjectClass {
    /// The class's own motion limits: pedestrians and cyclists; `None` for vehicles (the vehicle
    /// model's) and for classes that cannot move (signs, other).
    pub fn motion_limits(self) -> Option<MotionLimits> {
        match self {
            ObjectClass::Pedestrian => Some(PEDESTRIAN),
            ObjectClass::Cyclist => Some(CYCLIST),
            ObjectClass::Vehicle | ObjectClass::Sign | ObjectClass::Other => None,
        }
    }

    /// Whether the class is a pedestrian or a cyclist.
    pub fn is_vulnerable(self) -> bool {
        matches!(self, ObjectClass::Pedestrian | ObjectClass::Cyclist)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_by_class() {
        let p = ObjectClass::Pedestrian.motion_limits().unwrap();
        let c = ObjectClass::Cyclist.motion_limits().unwrap();
        assert!(p.max_speed < c.max_speed && p.max_curvature.is_none() && c.max_curvature.is_some());
        assert!(ObjectClass::Vehicle.motion_limits().is_none() && ObjectClass::Sign.motion_limits().is_none());
        assert!(ObjectClass::Cyclist.is_vulnerable() && !ObjectClass::Vehicle.is_vulnerable());
    }
}
