//! CARLA's `VehiclePIDController` (agents/navigation/controller.py, 0.9.x), rule for rule.
//!
//! * Each PID keeps the last 10 errors. With at least two, `de = (e[-1] - e[-2]) / dt` and
//!   `ie = sum(buffer) * dt`, else both are 0. Output `clip(Kp e + Kd de + Ki ie, -1, 1)`.
//! * Longitudinal error: `target_speed - speed`, both **km/h** (CARLA's interface unit; the
//!   conversion from m/s happens in [`VehiclePidController::run_step`]'s caller contract).
//!   `u >= 0`: throttle `min(u, max_throttle)`, brake 0; else brake `min(|u|, max_brake)`.
//! * Lateral error: angle between the forward vector and the vector to the waypoint (z dropped),
//!   `acos(clip(v.w / (|v||w|), -1, 1))`, or 1 rad if either vector is zero; negative when
//!   `cross(v, w).z < 0`. All of this runs in **CARLA's left-handed frame** (x forward, y right),
//!   where positive means steer right: callers convert poses with [`to_carla`].
//! * Steering may change by at most 0.1 per call, then is clamped to `+-max_steering`.
//! * `dt` is the real control period, never a hidden constant.

use crate::actuation::Control;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// Errors remembered by each PID (CARLA: `deque(maxlen=10)`).
pub const BUFFER_LEN: usize = 10;
/// Largest steering change per call.
pub const MAX_STEER_CHANGE: f64 = 0.1;

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PidGains {
    pub k_p: f64,
    pub k_d: f64,
    pub k_i: f64,
}

impl PidGains {
    /// The paper's gains for both loops: K_P = 2.0, K_D = 0.2, K_I = 0.
    pub const PAPER: PidGains = PidGains { k_p: 2.0, k_d: 0.2, k_i: 0.0 };
}

/// One PID loop with CARLA's 10-sample error buffer.
#[derive(Clone, Debug)]
pub struct Pid {
    gains: PidGains,
    dt: f64,
    errors: VecDeque<f64>,
}

impl Pid {
    pub fn new(gains: PidGains, dt: f64) -> Self {
        Pid { gains, dt, errors: VecDeque::with_capacity(BUFFER_LEN) }
    }

    pub fn step(&mut self, error: f64) -> f64 {
        if self.errors.len() == BUFFER_LEN {
            self.errors.pop_front();
        }
        self.errors.push_back(error);
        let (de, ie) = if self.errors.len() >= 2 {
            let n = self.errors.len();
            ((self.errors[n - 1] - self.errors[n - 2]) / self.dt, self.errors.iter().sum::<f64>() * self.dt)
        } else {
            (0.0, 0.0)
        };
        (self.gains.k_p * error + self.gains.k_d * de + self.gains.k_i * ie).clamp(-1.0, 1.0)
    }
}

pub use crate::carla::frame::{to_carla, CarlaPose};

/// CARLA's signed angle from the forward vector to the waypoint (left-handed frame).
pub fn lateral_error(pose: &CarlaPose, waypoint: (f64, f64)) -> f64 {
    let v = (pose.yaw.cos(), pose.yaw.sin());
    let w = (waypoint.0 - pose.x, waypoint.1 - pose.y);
    let norms = (w.0 * w.0 + w.1 * w.1).sqrt() * (v.0 * v.0 + v.1 * v.1).sqrt();
    let mut angle = if norms == 0.0 { 1.0 } else { ((w.0 * v.0 + w.1 * v.1) / norms).clamp(-1.0, 1.0).acos() };
    if v.0 * w.1 - v.1 * w.0 < 0.0 {
        angle = -angle;
    }
    angle
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ControllerLimits {
    pub max_throttle: f64,
    pub max_brake: f64,
    pub max_steering: f64,
}

impl ControllerLimits {
    /// The paper's setting: all three 1.0 (CARLA's class defaults are 0.75 / 0.3 / 0.8).
    pub const PAPER: ControllerLimits = ControllerLimits { max_throttle: 1.0, max_brake: 1.0, max_steering: 1.0 };
}

/// CARLA `VehiclePIDController`.
#[derive(Clone, Debug)]
pub struct VehiclePidController {
    lon: Pid,
    lat: Pid,
    limits: ControllerLimits,
    past_steering: f64,
}

impl VehiclePidController {
    pub fn new(lateral: PidGains, longitudinal: PidGains, limits: ControllerLimits, dt: f64) -> Self {
        VehiclePidController { lon: Pid::new(longitudinal, dt), lat: Pid::new(lateral, dt), limits, past_steering: 0.0 }
    }

    /// One control call: speeds in km/h, pose and waypoint in CARLA's frame.
    pub fn run_step(
        &mut self,
        target_speed_kmh: f64,
        speed_kmh: f64,
        pose: &CarlaPose,
        waypoint: (f64, f64),
    ) -> Control {
        let acceleration = self.lon.step(target_speed_kmh - speed_kmh);
        let mut steering = self.lat.step(lateral_error(pose, waypoint));
        let (throttle, brake) = if acceleration >= 0.0 {
            (acceleration.min(self.limits.max_throttle), 0.0)
        } else {
            (0.0, acceleration.abs().min(self.limits.max_brake))
        };
        if steering > self.past_steering + MAX_STEER_CHANGE {
            steering = self.past_steering + MAX_STEER_CHANGE;
        } else if steering < self.past_steering - MAX_STEER_CHANGE {
            steering = self.past_steering - MAX_STEER_CHANGE;
        }
        let steer = if steering >= 0.0 {
            self.limits.max_steering.min(steering)
        } else {
            (-self.limits.max_steering).max(steering)
        };
        self.past_steering = steer;
        Control { throttle, brake, steer }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pid_derivative_and_integral_by_hand() {
        let mut pid = Pid::new(PidGains { k_p: 0.1, k_d: 0.01, k_i: 0.05 }, 0.05);
        // First call: no derivative or integral term.
        assert!((pid.step(2.0) - 0.2).abs() < 1e-12);
        // Second: e = 1, de = (1 - 2) / 0.05 = -20, ie = (2 + 1) * 0.05 = 0.15.
        assert!((pid.step(1.0) - (0.1 - 0.2 + 0.0075)).abs() < 1e-12);
        // Clipped to [-1, 1].
        assert_eq!(Pid::new(PidGains::PAPER, 0.05).step(3.0), 1.0);
    }

    #[test]
    fn buffer_keeps_ten_errors() {
        let mut pid = Pid::new(PidGains { k_p: 0.0, k_d: 0.0, k_i: 0.01 }, 1.0);
        for _ in 0..10 {
            pid.step(1.0);
        }
        // 11th error 0: the oldest 1 drops out, sum = 9 (not 10).
        assert!((pid.step(0.0) - 0.09).abs() < 1e-12);
    }

    #[test]
    fn lateral_error_signs_in_carla_frame() {
        let p = CarlaPose { x: 0.0, y: 0.0, yaw: 0.0 };
        // Waypoint to the right (CARLA +y): positive error, 45 degrees.
        assert!((lateral_error(&p, (1.0, 1.0)) - std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        assert!((lateral_error(&p, (1.0, -1.0)) + std::f64::consts::FRAC_PI_4).abs() < 1e-12);
        // On top of the waypoint: 1 rad (CARLA's convention for a zero vector).
        assert_eq!(lateral_error(&p, (0.0, 0.0)), 1.0);
        // Our left (y > 0) becomes CARLA's negative y: steer left = negative.
        let ours = to_carla(0.0, 0.0, 0.0);
        let w = to_carla(5.0, 2.0, 0.0);
        assert!(lateral_error(&ours, (w.x, w.y)) < 0.0);
    }

    #[test]
    fn steering_rate_limit_and_pedals() {
        let mut c = VehiclePidController::new(PidGains::PAPER, PidGains::PAPER, ControllerLimits::PAPER, 0.05);
        let p = CarlaPose { x: 0.0, y: 0.0, yaw: 0.0 };
        // Waypoint 90 degrees right: PID wants +1, but the first call may only reach +0.1.
        let out = c.run_step(30.0, 20.0, &p, (0.0, 10.0));
        assert!((out.steer - 0.1).abs() < 1e-12);
        assert_eq!((out.throttle, out.brake), (1.0, 0.0));
        let out = c.run_step(30.0, 20.0, &p, (0.0, 10.0));
        assert!((out.steer - 0.2).abs() < 1e-12);
        // Too fast: 2 * (-0.25) + 0.2 * (-0.25 - 10) / 0.05 -> clipped to -1 -> full brake.
        let out = c.run_step(20.0, 20.25, &p, (10.0, 0.0));
        assert_eq!((out.throttle, out.brake), (0.0, 1.0));
        // Class-default limits clip pedals and steering.
        let lim = ControllerLimits { max_throttle: 0.75, max_brake: 0.3, max_steering: 0.05 };
        let mut c = VehiclePidController::new(PidGains::PAPER, PidGains::PAPER, lim, 0.05);
        let out = c.run_step(50.0, 0.0, &p, (0.0, 10.0));
        assert_eq!((out.throttle, out.steer), (0.75, 0.05));
        let out = c.run_step(0.0, 50.0, &p, (0.0, -10.0));
        assert_eq!(out.brake, 0.3);
        assert!((out.steer + 0.05).abs() < 1e-12);
    }
}
