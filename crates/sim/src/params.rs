//! Vehicle parameters for the CommonRoad single-track model. Defaults are CommonRoad's
//! parameter set `vehicle2` (BMW 320i) from `commonroad-vehicle-models` 3.0.2
//! (`parameters_vehicle2.yaml`, tyre `p_dy1`, `p_ky1` from `parameters_tire.yaml`), plus what
//! CommonRoad's ST model lacks: the road's friction coefficient and the tyre force limit
//! (`tyre.rs`). CommonRoad's `mu` only scales the cornering stiffness here; the friction limit
//! is `friction` (default 1.0, so `|a_lat| <= 1.0 g`).
//!
//! Three sets: [`VehicleParams::vehicle2_linear`] is the package's vehicle2 exactly (golden
//! parity); [`VehicleParams::vehicle2`] adds the friction-limited tyres; the default,
//! [`VehicleParams::carla_like`], also raises the steering-rate limit from CommonRoad's 0.4 rad/s
//! to [`CARLA_LIKE_STEER_RATE`]. CARLA itself puts no rate limit on the wheels beyond the PID's
//! 0.1 of steer per call (about 2 rad/s at a 0.05 s period); at 0.4 rad/s the PID loses real
//! 90 degree turns (8 to 9 of 55 clean 20 s windows of the KITTI paths diverge), at 2 rad/s it
//! drives the tyres into the friction limit (4 of 55), at 1 rad/s neither happens
//! (BENCHMARKS.md).

use crate::tyre::TyreModel;
use serde::{Deserialize, Serialize};

/// Steering limits: front-wheel angle (rad) and its rate (rad/s).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SteeringLimits {
    pub min: f64,
    pub max: f64,
    pub v_min: f64,
    pub v_max: f64,
}

/// Longitudinal limits: `a_max` (m/s^2), speed range (m/s) and `v_switch`, above which the
/// positive acceleration is power-limited to `a_max * v_switch / v`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LongitudinalLimits {
    pub a_max: f64,
    pub v_min: f64,
    pub v_max: f64,
    pub v_switch: f64,
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct VehicleParams {
    /// Body length and width (m).
    pub length: f64,
    pub width: f64,
    /// Distances from the centre of gravity to the front (`a`) and rear (`b`) axle (m).
    pub a: f64,
    pub b: f64,
    /// Total mass (kg) and yaw moment of inertia (kg m^2).
    pub m: f64,
    pub i_z: f64,
    /// Height of the centre of gravity used for load transfer (m), CommonRoad `h_s`.
    pub h_s: f64,
    /// CommonRoad's friction coefficient (`p_dy1`): it scales the linear tyre force
    /// `mu * C_S * F_z * alpha`, i.e. the cornering stiffness.
    pub mu: f64,
    /// Cornering stiffness coefficients (1/rad), `-p_ky1 / p_dy1` front and rear.
    pub c_sf: f64,
    pub c_sr: f64,
    pub steering: SteeringLimits,
    pub longitudinal: LongitudinalLimits,
    /// Below this speed (m/s) the kinematic single-track model is used (CommonRoad: 0.1).
    pub kinematic_below: f64,
    /// Tyre-road friction coefficient: the friction circle's radius is `friction * F_z`.
    #[serde(default = "default_friction")]
    pub friction: f64,
    /// How the lateral tyre forces are limited.
    #[serde(default)]
    pub tyre: TyreModel,
}

/// Steering-rate limit of the default vehicle (rad/s of front-wheel angle).
pub const CARLA_LIKE_STEER_RATE: f64 = 1.0;

fn default_friction() -> f64 {
    1.0
}

impl VehicleParams {
    /// CommonRoad vehicle2 (BMW 320i) with friction-limited tyres.
    pub fn vehicle2() -> Self {
        let c_s = 21.92 / 1.0489;
        VehicleParams {
            length: 4.508,
            width: 1.61,
            a: 1.1561957064,
            b: 1.4227170936,
            m: 1093.2952334674046,
            i_z: 1791.5995300122856,
            h_s: 0.61373004,
            mu: 1.0489,
            c_sf: c_s,
            c_sr: c_s,
            steering: SteeringLimits { min: -1.066, max: 1.066, v_min: -0.4, v_max: 0.4 },
            longitudinal: LongitudinalLimits { a_max: 11.5, v_min: -13.9, v_max: 50.8, v_switch: 7.319 },
            kinematic_below: 0.1,
            friction: default_friction(),
            tyre: TyreModel::default(),
        }
    }

    /// CommonRoad's vehicle2 exactly as the package models it: linear tyres, no friction limit
    /// on the lateral forces (golden parity tests).
    pub fn vehicle2_linear() -> Self {
        VehicleParams { tyre: TyreModel::Linear, ..Self::vehicle2() }
    }

    /// The rollouts' vehicle: [`VehicleParams::vehicle2`] steering at up to
    /// [`CARLA_LIKE_STEER_RATE`].
    pub fn carla_like() -> Self {
        let r = CARLA_LIKE_STEER_RATE;
        let v = Self::vehicle2();
        VehicleParams { steering: SteeringLimits { v_min: -r, v_max: r, ..v.steering }, ..v }
    }

    pub fn wheelbase(&self) -> f64 {
        self.a + self.b
    }
}

impl Default for VehicleParams {
    fn default() -> Self {
        Self::carla_like()
    }
}
