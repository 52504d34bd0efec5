//! The vehicle as a plant: one control period of a held `Control` (CARLA's `VehicleControl`)
//! through the actuation layer (pedal lag, drive and brake forces, steering target at the
//! steering-rate limit) into the single-track model, integrated in physics sub-steps of at most
//! `max_physics_dt_s` (shorter where the model is stiff, `model::stable_step`).
//!
//! The tracker calls it once per control period with the PID's command; a closed-loop driver
//! (the `drive` crate) calls it with whatever its policy commands. The plant knows nothing of
//! where a command came from, so both step the same physics sub-step for sub-step.

use crate::actuation::{ActuationParams, Control};
use crate::model::{at_friction_limit, derivative, rk4_step, stable_step, State};
use crate::params::VehicleParams;

/// What one control period did to the vehicle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PeriodOutcome {
    /// Longitudinal acceleration applied during the last sub-step (m/s^2).
    pub accel_long: f64,
    /// Lateral acceleration at the end of the period, `v (psi_dot + beta_dot)` (m/s^2).
    pub accel_lat: f64,
    /// Time of the period the tyres spent at the friction limit (s).
    pub friction_limit_s: f64,
}

/// The vehicle's state between control periods: the model state and the applied pedal
/// (`throttle - brake`, lagging the command).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plant {
    pub state: State,
    pub pedal: f64,
}

/// The model state became non-finite at time `t` (s).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NonFinite {
    pub t: f64,
}

impl Plant {
    pub fn new(state: State) -> Self {
        Plant { state, pedal: 0.0 }
    }

    /// Holds `control` from `t` for `period` seconds. `on_substep(t, state)` is called after
    /// every physics sub-step.
    #[allow(clippy::too_many_arguments)]
    pub fn advance(
        &mut self,
        control: &Control,
        t: f64,
        period: f64,
        max_physics_dt_s: f64,
        vehicle: &VehicleParams,
        actuation: &ActuationParams,
        mut on_substep: impl FnMut(f64, &State),
    ) -> Result<PeriodOutcome, NonFinite> {
        let mut x = self.state;
        let mut pedal = self.pedal;
        let mut elapsed = 0.0;
        let mut accel = 0.0;
        let mut u = [0.0, 0.0];
        let mut at_limit = 0.0;
        while elapsed < period - 1e-12 {
            let h_try = (period - elapsed).min(max_physics_dt_s);
            let applied = ActuationParams::applied(actuation.lag_pedal(pedal, control, h_try), control);
            let a_try = actuation.longitudinal_accel(&applied, x[3], vehicle, h_try);
            let h = stable_step(x[3], a_try, vehicle, max_physics_dt_s).min(period - elapsed);
            pedal = actuation.lag_pedal(pedal, control, h);
            let applied = ActuationParams::applied(pedal, control);
            accel = actuation.longitudinal_accel(&applied, x[3], vehicle, h);
            let delta_target = actuation.steering_target(control, x[3], vehicle);
            let rate = ((delta_target - x[2]) / h).clamp(vehicle.steering.v_min, vehicle.steering.v_max);
            u = [rate, accel];
            x = rk4_step(&x, u, vehicle, h);
            elapsed += h;
            if at_friction_limit(&x, u, vehicle) {
                at_limit += h;
            }
            if x.iter().any(|v| !v.is_finite()) {
                return Err(NonFinite { t: t + elapsed });
            }
            on_substep(t + elapsed, &x);
        }
        self.state = x;
        self.pedal = pedal;
        let d = derivative(&x, u, vehicle);
        Ok(PeriodOutcome { accel_long: accel, accel_lat: x[3] * (d[4] + d[6]), friction_limit_s: at_limit })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn full_brake_stops_the_car_without_reversing() {
        let (veh, act) = (VehicleParams::default(), ActuationParams::default());
        let mut p = Plant::new([0.0, 0.0, 0.0, 15.0, 0.0, 0.0, 0.0]);
        let brake = Control { throttle: 0.0, brake: 1.0, steer: 0.0 };
        let mut t = 0.0;
        for _ in 0..100 {
            p.advance(&brake, t, 0.05, 0.01, &veh, &act, |_, _| {}).unwrap();
            t += 0.05;
        }
        assert!(p.state[3].abs() < 1e-6, "still moving at {} m/s", p.state[3]);
        assert!(p.state[0] > 10.0 && p.state[0] < 30.0, "stopped after {} m", p.state[0]);
    }
}
