//! The tracking loop: every control period the CARLA PID turns the reference into pedal and
//! steering commands; the actuation layer turns those into model inputs; the model integrates
//! in sub-steps of at most `max_physics_dt_s` (shorter where the model is stiff).
//!
//! Target speed (m/s, converted to km/h only at the PID boundary):
//! `max(0, |v_ref(t + dt)| + position_gain * ((p_ref(t) - p) . tangent))`: the reference's own
//! speed one control period ahead, plus a correction for being behind or ahead along the path.
//! The lateral target is [`Reference::lookahead`]: the reference point `lookahead_s` (0.5 s)
//! ahead in time, pushed along the path until it is at least `lookahead_min_m +
//! lookahead_distance_ratio_s * |v|` from the vehicle. The look-ahead distance therefore grows
//! with speed: by default `max(3 m, about 0.5 s * v)` (ratio 0; 7.5 m at 15 m/s, 20 m at
//! 40 m/s). With ratio 0.5 s it is CARLA's `LocalPlanner` rule (`min_distance =
//! base_min_distance + distance_ratio * speed`, 3.0 m + 0.5 s * v); on the KITTI paths that cuts
//! corners twice as much (median RMS 0.53 m against 0.21 m) and lets 1 to 2 of 55 noisy windows
//! reach the friction limit, so it is not the default (BENCHMARKS.md). Straight ahead while the
//! reference stands still (no steering wind-up at standstill).
//!
//! Every physics sub-step also records whether the tyres were at the friction limit
//! ([`crate::model::at_friction_limit`]): the time spent there is a validity criterion.

use crate::actuation::{ActuationParams, Control};
use crate::model::State;
use crate::params::VehicleParams;
use crate::pid::{to_carla, ControllerLimits, PidGains, VehiclePidController};
use crate::plant::Plant;
use crate::reference::Reference;
use scene::glam::DVec2;
use serde::{Deserialize, Serialize};

/// Below this much reference motion over the look-ahead time the reference counts as standing
/// still (m).
pub const STANDSTILL_M: f64 = 0.3;

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackerConfig {
    /// Control period (s): the PID's `dt` and how often commands change.
    pub control_dt_s: f64,
    /// Longest physics sub-step (s).
    pub max_physics_dt_s: f64,
    pub lateral: PidGains,
    pub longitudinal: PidGains,
    pub limits: ControllerLimits,
    /// Speed correction per metre of along-track position error (1/s).
    pub position_gain: f64,
    /// Look-ahead time (s) where the search for the lateral target starts, and its minimum
    /// distance at rest (m; CARLA's `base_min_distance`).
    pub lookahead_s: f64,
    pub lookahead_min_m: f64,
    /// Growth of the minimum look-ahead distance with the vehicle's speed (m per m/s, i.e. s;
    /// CARLA's `distance_ratio`).
    #[serde(default = "default_distance_ratio")]
    pub lookahead_distance_ratio_s: f64,
}

fn default_distance_ratio() -> f64 {
    0.0
}

impl Default for TrackerConfig {
    fn default() -> Self {
        TrackerConfig {
            control_dt_s: 0.05,
            max_physics_dt_s: 0.01,
            lateral: PidGains::PAPER,
            longitudinal: PidGains::PAPER,
            limits: ControllerLimits::PAPER,
            position_gain: 1.0,
            lookahead_s: 0.5,
            lookahead_min_m: 3.0,
            lookahead_distance_ratio_s: default_distance_ratio(),
        }
    }
}

/// The vehicle after one control step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepRecord {
    pub t: f64,
    pub state: State,
    pub control: Control,
    /// Longitudinal acceleration applied during the step (m/s^2).
    pub accel_long: f64,
    /// Lateral acceleration at the end of the step, `v (psi_dot + beta_dot)` (m/s^2).
    pub accel_lat: f64,
    pub reference: DVec2,
    /// Time of this step the tyres spent at the friction limit (s).
    pub friction_limit_s: f64,
}

/// Errors of the tracking loop.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TrackError {
    #[error("the vehicle state became non-finite at t = {t:.3} s (model diverged)")]
    Diverged { t: f64 },
    #[error("invalid tracker configuration: {0}")]
    Config(String),
}

/// A last control step shorter than this fraction of the period is not taken.
pub const MIN_LAST_STEP: f64 = 1e-3;

/// Number of control steps from `t_start` to `t_end` (the last one may be shorter, but not
/// shorter than [`MIN_LAST_STEP`] of a period). On a Unix-time clock (PandaSet: 1.5e9 s) the span
/// carries rounding errors of 1e-7 s; a tolerance of 1e-9 steps added a step of no length whose
/// time equalled the one before, which no reader of the executed file accepts.
pub fn control_steps(t_start: f64, t_end: f64, control_dt_s: f64) -> usize {
    ((t_end - t_start) / control_dt_s - MIN_LAST_STEP).ceil().max(0.0) as usize
}

/// The control law of every backend: each control period, the target speed and the look-ahead
/// waypoint from the reference (module doc), then CARLA's `VehiclePIDController` in its own units
/// (km/h, CARLA's left-handed frame). The built-in tracker and the CARLA bridge both call it, so
/// the two backends command the same way from the same state.
pub struct ControlLaw {
    config: TrackerConfig,
    pid: VehiclePidController,
}

impl ControlLaw {
    pub fn new(c: &TrackerConfig) -> Self {
        ControlLaw { config: *c, pid: VehiclePidController::new(c.lateral, c.longitudinal, c.limits, c.control_dt_s) }
    }

    /// The command at time `t` for a vehicle at `pos` (m, world) heading `heading` (rad) at
    /// `speed` (m/s, >= 0).
    pub fn command(&mut self, reference: &Reference, t: f64, pos: DVec2, heading: f64, speed: f64) -> Control {
        let c = &self.config;
        let v_ref = reference.velocity(t + c.control_dt_s);
        let dir = DVec2::new(heading.cos(), heading.sin());
        let tangent = v_ref.try_normalize().unwrap_or(dir);
        let target_speed = (v_ref.length() + c.position_gain * (reference.position(t) - pos).dot(tangent)).max(0.0);
        // While the reference stands still (a parked car before its manoeuvre), aim straight
        // ahead: steering towards a far-future point at standstill would wind the wheels up.
        let wp = if reference.position(t + c.lookahead_s).distance(reference.position(t)) < STANDSTILL_M {
            pos + dir * c.lookahead_min_m
        } else {
            let min_distance = c.lookahead_min_m + c.lookahead_distance_ratio_s * speed;
            reference.lookahead(t, pos, c.lookahead_s, min_distance)
        };
        let wp_c = to_carla(wp.x, wp.y, 0.0);
        self.pid.run_step(target_speed * 3.6, speed * 3.6, &to_carla(pos.x, pos.y, heading), (wp_c.x, wp_c.y))
    }
}

pub struct Tracker<'a> {
    pub config: &'a TrackerConfig,
    pub vehicle: &'a VehicleParams,
    pub actuation: &'a ActuationParams,
}

impl Tracker<'_> {
    /// Tracks `reference` from `initial` at `t_start` until `t_end`. `on_substep(t, state)` is
    /// called after every physics sub-step (collision checks). Returns one record per control
    /// step, the initial state first.
    pub fn run(
        &self,
        reference: &Reference,
        initial: State,
        t_start: f64,
        t_end: f64,
        mut on_substep: impl FnMut(f64, &State),
    ) -> Result<Vec<StepRecord>, TrackError> {
        let c = self.config;
        if !(c.control_dt_s > 0.0 && c.max_physics_dt_s > 0.0 && c.max_physics_dt_s <= c.control_dt_s) {
            return Err(TrackError::Config(format!(
                "need 0 < max_physics_dt_s ({}) <= control_dt_s ({})",
                c.max_physics_dt_s, c.control_dt_s
            )));
        }
        let mut law = ControlLaw::new(c);
        let mut plant = Plant::new(initial);
        let mut records = vec![StepRecord {
            t: t_start,
            state: plant.state,
            control: Control::default(),
            accel_long: 0.0,
            accel_lat: 0.0,
            reference: reference.position(t_start),
            friction_limit_s: 0.0,
        }];
        let n = control_steps(t_start, t_end, c.control_dt_s);
        for k in 0..n {
            let t = t_start + k as f64 * c.control_dt_s;
            let period = c.control_dt_s.min(t_end - t);
            let x = plant.state;
            let control = law.command(reference, t, DVec2::new(x[0], x[1]), x[4], x[3].abs());
            let outcome = plant
                .advance(&control, t, period, c.max_physics_dt_s, self.vehicle, self.actuation, &mut on_substep)
                .map_err(|e| TrackError::Diverged { t: e.t })?;
            records.push(StepRecord {
                t: t + period,
                state: plant.state,
                control,
                accel_long: outcome.accel_long,
                accel_lat: outcome.accel_lat,
                reference: reference.position(t + period),
                friction_limit_s: outcome.friction_limit_s,
            });
        }
        Ok(records)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tracker_run(reference: &Reference, v0: f64, heading: f64) -> Vec<StepRecord> {
        let (cfg, veh, act) = (TrackerConfig::default(), VehicleParams::default(), ActuationParams::default());
        let tr = Tracker { config: &cfg, vehicle: &veh, actuation: &act };
        let p0 = reference.position(reference.start_time());
        let x0 = [p0.x, p0.y, 0.0, v0, heading, 0.0, 0.0];
        tr.run(reference, x0, reference.start_time(), reference.end_time(), |_, _| {}).unwrap()
    }

    #[test]
    fn no_steering_wind_up_while_parked() {
        // Parked for 2 s, then drive off along a 30-degree left diagonal: the wheels stay straight
        // while parked and the car then follows the diagonal.
        let mut pts: Vec<(f64, DVec2)> = (0..20).map(|i| (i as f64 * 0.1, DVec2::ZERO)).collect();
        let dir = DVec2::new(30f64.to_radians().cos(), 30f64.to_radians().sin());
        for i in 0..=40 {
            let s = 0.5 * 2.0 * (i as f64 * 0.1).powi(2) / 2.0;
            pts.push((2.0 + i as f64 * 0.1, dir * s));
        }
        let r = Reference::new(pts).unwrap();
        let rec = tracker_run(&r, 0.0, 0.0);
        let parked = rec.iter().filter(|s| s.t < 1.5).map(|s| s.state[2].abs()).fold(0.0, f64::max);
        assert!(parked < 1e-9, "wheels turned {parked} rad while parked");
        let last = rec.last().unwrap();
        let err = (DVec2::new(last.state[0], last.state[1]) - last.reference).length();
        assert!(err < 1.5, "end error {err} m");
    }

    #[test]
    fn no_empty_last_step_on_a_unix_time_clock() {
        // PandaSet 002's clock: t0 + 0.2 s computed in f64 is 0.20000004768371582 s after t0, a
        // hair past 4 control periods.
        let t0 = 1557539958.000022;
        assert_eq!(control_steps(t0, t0 + 0.2, 0.05), 4);
        let r = Reference::new((0..=2).map(|i| (t0 + i as f64 * 0.1, DVec2::new(i as f64, 0.0))).collect()).unwrap();
        let rec = tracker_run(&r, 10.0, 0.0);
        assert!(rec.windows(2).all(|w| w[1].t > w[0].t), "times must increase strictly");
        assert_eq!(control_steps(0.0, 1.0, 0.3), 4);
        assert_eq!(control_steps(0.0, 0.9, 0.3), 3);
    }

    #[test]
    fn holds_speed_on_a_straight_line() {
        let r = Reference::new((0..=80).map(|i| (i as f64 * 0.1, DVec2::new(i as f64 * 1.5, 0.0))).collect()).unwrap();
        let rec = tracker_run(&r, 15.0, 0.0);
        assert_eq!(rec.len(), 161);
        let last = rec.last().unwrap();
        assert!((last.t - 8.0).abs() < 1e-9);
        assert!((DVec2::new(last.state[0], last.state[1]) - r.position(8.0)).length() < 1.0);
        assert!(last.state[1].abs() < 1e-6);
    }

    #[test]
    fn follows_a_left_turn_and_brakes_to_a_stop() {
        // Quarter circle of radius 30 m at 8 m/s, then a stop over 3 s.
        let mut pts = Vec::new();
        let omega = 8.0 / 30.0;
        for i in 0..=59 {
            let t = i as f64 * 0.1;
            let a = omega * t;
            pts.push((t, DVec2::new(30.0 * a.sin(), 30.0 * (1.0 - a.cos()))));
        }
        let (t_end, p_end) = *pts.last().unwrap();
        let dir = DVec2::new((omega * t_end).cos(), (omega * t_end).sin());
        for i in 1..=40 {
            let s = (i as f64 * 0.1).min(3.0);
            let d = 8.0 * s - 8.0 / 6.0 * s * s; // decelerate 8 -> 0 over 3 s
            pts.push((t_end + i as f64 * 0.1, p_end + dir * d));
        }
        let r = Reference::new(pts).unwrap();
        let rec = tracker_run(&r, 8.0, 0.0);
        let errs: Vec<f64> = rec.iter().map(|s| (DVec2::new(s.state[0], s.state[1]) - s.reference).length()).collect();
        let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len() as f64).sqrt();
        assert!(rms < 1.0, "rms {rms}");
        let last = rec.last().unwrap();
        assert!(last.state[3] < 0.5, "still moving at {} m/s", last.state[3]);
        assert!(last.state[3] >= 0.0, "no reverse");
        // It turned left: heading about 1.6 rad.
        assert!((last.state[4] - omega * t_end).abs() < 0.2, "heading {}", last.state[4]);
    }
}
