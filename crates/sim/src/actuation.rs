//! CARLA-like actuation: pedal and steering commands to the model's inputs.
//!
//! Commands follow CARLA's `VehicleControl`: `throttle` and `brake` in [0, 1], `steer` in [-1, 1]
//! with **positive = steer right** (CARLA is left-handed). Our model is right-handed (positive
//! steering angle = left), so the sign flips here, at the boundary.
//!
//! Longitudinal (all forces at the wheels, N; `r` the wheel radius):
//! * drive `F_d = throttle * T(rpm) * g_i * g_f * eta / r` with an ideal automatic gearbox that
//!   picks the gear `i` giving the largest force with `rpm = v / r * g_i * g_f * 60 / (2 pi)`
//!   at or below `max_rpm`; `T` is the piecewise-linear torque curve (CARLA's default
//!   `[(0, 400), (1890, 500), (5730, 400)]` N m);
//! * brake `F_b = brake * wheels * T_brake / r` (CARLA: 1500 N m per wheel), opposing motion;
//! * drag `0.5 rho Cd A v^2` and rolling resistance `C_rr m g` while moving;
//! * `a = (F_d - F_b - F_drag - F_roll) / m`, limited to the tyre friction `friction g`, and never
//!   through zero speed into reverse (no reverse gear is modelled: braking stops the car).
//!
//! Pedal lag: CARLA's PhysX vehicles do not turn a pedal step into a force step (engine
//! inertia, drivetrain and brake build-up). We model that as a first-order lag on the signed
//! pedal `p = throttle - brake`: `p_applied += (p_cmd - p_applied) (1 - exp(-h / tau))` per
//! sub-step `h`, `tau = pedal_time_constant_s` (0.25 s). Positive `p_applied` is throttle,
//! negative is brake. Without it the paper's PID gains (K_P = 2 on a km/h error) turn into a
//! 20 Hz full-throttle/full-brake limit cycle.
//!
//! Lateral: the steering-angle target is `-steer * max_steer * curve(|v| in km/h)` with
//! `max_steer = min(70 deg, model limit)` and CARLA's default steering curve
//! `[(0, 1), (20, 0.9), (60, 0.8), (120, 0.7)]`; the wheel angle follows it at the model's
//! steering-rate limit (0.4 rad/s for vehicle2).

use crate::model::G;
use crate::params::VehicleParams;
use serde::{Deserialize, Serialize};

/// A CARLA `VehicleControl` (steer positive = right).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Control {
    pub throttle: f64,
    pub brake: f64,
    pub steer: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ActuationParams {
    /// Engine torque (N m) against rpm, piecewise linear, held flat past the last point.
    pub torque_curve: Vec<(f64, f64)>,
    pub max_rpm: f64,
    pub gear_ratios: Vec<f64>,
    pub final_ratio: f64,
    pub drivetrain_efficiency: f64,
    pub wheel_radius: f64,
    pub brake_torque_per_wheel: f64,
    pub wheels: f64,
    pub drag_coefficient: f64,
    pub frontal_area: f64,
    pub air_density: f64,
    pub rolling_resistance: f64,
    /// CARLA's front-wheel max steer angle (rad), capped by the model's own limit.
    pub max_steer_angle: f64,
    /// Steering factor against speed (km/h), piecewise linear.
    pub steering_curve: Vec<(f64, f64)>,
    /// First-order lag of the applied pedal behind the command (s); 0 = instantaneous.
    pub pedal_time_constant_s: f64,
}

impl Default for ActuationParams {
    fn default() -> Self {
        ActuationParams {
            torque_curve: vec![(0.0, 400.0), (1890.0, 500.0), (5730.0, 400.0)],
            max_rpm: 5730.0,
            gear_ratios: vec![4.17, 2.34, 1.52, 1.14, 0.87, 0.69],
            final_ratio: 3.7,
            drivetrain_efficiency: 0.9,
            wheel_radius: 0.30,
            brake_torque_per_wheel: 1500.0,
            wheels: 4.0,
            drag_coefficient: 0.3,
            frontal_area: 2.2,
            air_density: 1.225,
            rolling_resistance: 0.015,
            max_steer_angle: 70f64.to_radians(),
            steering_curve: vec![(0.0, 1.0), (20.0, 0.9), (60.0, 0.8), (120.0, 0.7)],
            pedal_time_constant_s: 0.25,
        }
    }
}

/// Piecewise-linear lookup, flat outside the table.
pub fn lookup(table: &[(f64, f64)], x: f64) -> f64 {
    match table.iter().position(|(xi, _)| *xi > x) {
        None => table.last().map_or(0.0, |p| p.1),
        Some(0) => table[0].1,
        Some(i) => {
            let ((x0, y0), (x1, y1)) = (table[i - 1], table[i]);
            y0 + (x - x0) / (x1 - x0) * (y1 - y0)
        }
    }
}

impl ActuationParams {
    /// Largest drive force at the wheels for full throttle at speed `v` (N).
    pub fn max_drive_force(&self, v: f64) -> f64 {
        let wheel_rpm = v.max(0.0) / self.wheel_radius * 60.0 / std::f64::consts::TAU;
        self.gear_ratios
            .iter()
            .filter_map(|g| {
                let ratio = g * self.final_ratio;
                let rpm = wheel_rpm * ratio;
                (rpm <= self.max_rpm)
                    .then(|| lookup(&self.torque_curve, rpm) * ratio * self.drivetrain_efficiency / self.wheel_radius)
            })
            .fold(0.0, f64::max)
    }

    /// Longitudinal acceleration for a command at speed `v` (m/s). `h` is the step the value
    /// will be held for: braking never carries the car through zero into reverse.
    pub fn longitudinal_accel(&self, c: &Control, v: f64, veh: &VehicleParams, h: f64) -> f64 {
        let moving = v > 1e-3;
        let drive = c.throttle.clamp(0.0, 1.0) * self.max_drive_force(v);
        let brake = c.brake.clamp(0.0, 1.0) * self.wheels * self.brake_torque_per_wheel / self.wheel_radius;
        let drag = 0.5 * self.air_density * self.drag_coefficient * self.frontal_area * v * v;
        let roll = if moving { self.rolling_resistance * veh.m * G } else { 0.0 };
        let resist = brake + drag + roll;
        let mut a = (drive - resist) / veh.m;
        if !moving && drive <= resist {
            a = 0.0; // static: resistances hold the car, they do not push it backwards
        }
        a = a.clamp(-veh.friction * G, veh.friction * G);
        if a < 0.0 && v + a * h < 0.0 {
            a = -v.max(0.0) / h;
        }
        a
    }

    /// Advances the applied signed pedal (`throttle - brake`) towards the command over `h`.
    pub fn lag_pedal(&self, applied: f64, command: &Control, h: f64) -> f64 {
        let target = command.throttle.clamp(0.0, 1.0) - command.brake.clamp(0.0, 1.0);
        if self.pedal_time_constant_s <= 0.0 {
            return target;
        }
        applied + (target - applied) * (1.0 - (-h / self.pedal_time_constant_s).exp())
    }

    /// The control actually applied for a signed pedal value.
    pub fn applied(pedal: f64, command: &Control) -> Control {
        Control { throttle: pedal.max(0.0), brake: (-pedal).max(0.0), steer: command.steer }
    }

    /// Front-wheel angle target (rad, positive = left) for a CARLA steer command at speed `v`.
    pub fn steering_target(&self, c: &Control, v: f64, veh: &VehicleParams) -> f64 {
        let max = self.max_steer_angle.min(veh.steering.max).min(-veh.steering.min);
        -c.steer.clamp(-1.0, 1.0) * max * lookup(&self.steering_curve, v.abs() * 3.6)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lookup_interpolates_and_holds() {
        let t = [(0.0, 1.0), (20.0, 0.9), (60.0, 0.8)];
        assert_eq!(lookup(&t, -5.0), 1.0);
        assert!((lookup(&t, 10.0) - 0.95).abs() < 1e-12);
        assert_eq!(lookup(&t, 100.0), 0.8);
    }

    #[test]
    fn forces_by_hand() {
        let (a, v) = (ActuationParams::default(), VehicleParams::vehicle2());
        // Full brake from 10 m/s: 4 * 1500 / 0.3 = 20 kN, plus drag and rolling resistance,
        // over 1093 kg is beyond the friction limit 1.0 g = 9.81 m/s^2.
        let c = Control { throttle: 0.0, brake: 1.0, steer: 0.0 };
        assert!((a.longitudinal_accel(&c, 10.0, &v, 0.01) + v.friction * G).abs() < 1e-12);
        // Half brake: (10000 + 0.5*1.225*0.3*2.2*100 + 0.015*1093.295*9.81) / 1093.295.
        let c = Control { brake: 0.5, ..c };
        let expect = -(10000.0 + 0.5 * 1.225 * 0.3 * 2.2 * 100.0 + 0.015 * v.m * G) / v.m;
        assert!((a.longitudinal_accel(&c, 10.0, &v, 0.01) - expect).abs() < 1e-9);
        // Braking at 0.02 m/s for 0.01 s stops exactly, no reverse.
        assert!((a.longitudinal_accel(&c, 0.02, &v, 0.01) + 2.0).abs() < 1e-12);
        assert_eq!(a.longitudinal_accel(&c, 0.0, &v, 0.01), 0.0);
        // Full throttle from rest: 1st gear 400 N m * 4.17 * 3.7 * 0.9 / 0.3 = 18.5 kN -> friction limited.
        let go = Control { throttle: 1.0, brake: 0.0, steer: 0.0 };
        assert!((a.max_drive_force(0.0) - 400.0 * 4.17 * 3.7 * 0.9 / 0.3).abs() < 1e-9);
        assert!((a.longitudinal_accel(&go, 0.0, &v, 0.01) - v.friction * G).abs() < 1e-12);
        // Top gear still pulls at 45 m/s (162 km/h) but the engine is past max rpm in 1st.
        assert!(a.max_drive_force(45.0) > 0.0);
        assert!(a.max_drive_force(45.0) < a.max_drive_force(10.0));
    }

    #[test]
    fn pedal_lag_is_first_order() {
        let a = ActuationParams::default();
        let full = Control { throttle: 1.0, brake: 0.0, steer: 0.0 };
        // After one time constant: 1 - e^-1 of the step.
        let mut p = 0.0;
        for _ in 0..25 {
            p = a.lag_pedal(p, &full, 0.01);
        }
        assert!((p - (1.0 - (-1.0f64).exp())).abs() < 1e-12);
        let applied = ActuationParams::applied(-0.4, &Control { steer: 0.3, ..full });
        assert_eq!((applied.throttle, applied.brake, applied.steer), (0.0, 0.4, 0.3));
        let instant = ActuationParams { pedal_time_constant_s: 0.0, ..a };
        assert_eq!(instant.lag_pedal(0.0, &full, 0.01), 1.0);
    }

    #[test]
    fn steering_sign_and_curve() {
        let (a, v) = (ActuationParams::default(), VehicleParams::vehicle2());
        let right = Control { steer: 0.5, ..Default::default() };
        // CARLA positive steer = right = negative (clockwise) angle in our right-handed frame.
        assert!((a.steering_target(&right, 0.0, &v) + 0.5 * 1.066).abs() < 1e-12);
        // At 40 km/h the curve gives 0.85.
        assert!((a.steering_target(&right, 40.0 / 3.6, &v) + 0.5 * 1.066 * 0.85).abs() < 1e-12);
    }
}
