//! Plausible ranges for every field of a rollout configuration ([`RolloutConfig`]: tracker,
//! vehicle, actuation, smoothing, validity, resampling rates), checked when a configuration is
//! deserialised (`RolloutConfig` deserialises through [`RolloutConfig::validate`], so a
//! `--config` file is refused on load) and again before every rollout ([`crate::budget::check`]).
//! Without them a negative mass, an empty gearbox, a 1e9 m wheelbase (the model then crawls in
//! ever shorter stable steps), a 1e6 rad steering limit or NaN gains were executed and written as
//! a trajectory. The ranges are generous, a bicycle to a 40 t truck; each error names the field
//! and its range.
//!
//! | field | range | notes |
//! |---|---|---|
//! | `vehicle.length`, `width` | 0.3 to 30 m, 0.2 to 5 m | a bicycle to an articulated truck |
//! | `vehicle.a`, `b` | 0.05 to 15 m each, `a + b` (wheelbase) at most `length` | vehicle2: 1.16 + 1.42 m |
//! | `vehicle.m`, `i_z` | 20 to 60,000 kg, 1 to 1e6 kg m^2 | vehicle2: 1,093 kg, 1,792 kg m^2 |
//! | `vehicle.h_s` | 0.05 to 5 m | centre-of-gravity height |
//! | `vehicle.mu`, `c_sf`, `c_sr` | 0.1 to 3, 0.1 to 100 1/rad | vehicle2: 1.05, 20.9 |
//! | `vehicle.steering.min`/`max` | -pi/2 to 0, 0 to pi/2 rad (non-zero) | vehicle2: +-1.066 |
//! | `vehicle.steering.v_min`/`v_max` | -20 to 0, 0 to 20 rad/s (non-zero) | default +-1 |
//! | `vehicle.longitudinal` | `a_max` 0.1 to 30 m/s^2, `v_min` -30 to 0, `v_max` 1 to 100, `v_switch` 0.1 to 100 m/s | vehicle2: 11.5, -13.9, 50.8, 7.3 |
//! | `vehicle.kinematic_below` | 0.01 to 5 m/s | CommonRoad: 0.1 |
//! | `vehicle.friction` | 0.05 to 2 | ice to racing slicks |
//! | `vehicle.tyre` (friction circle) | `linear_fraction`, `reserve` 0 to 1 | |
//! | `actuation.torque_curve`, `steering_curve` | 1 to 64 points, x increasing | torque 0 to 50,000 N m at 0 to 30,000 rpm; factor 0 to 1 at 0 to 500 km/h |
//! | `actuation.gear_ratios` | 1 to 32 gears of 0.1 to 30 | trucks have up to 18 |
//! | `actuation.max_rpm`, `final_ratio` | 100 to 30,000 rpm, 0.5 to 30 | |
//! | `actuation.drivetrain_efficiency` | 0.01 to 1 | |
//! | `actuation.wheel_radius`, `brake_torque_per_wheel`, `wheels` | 0.1 to 1.5 m, 1 to 100,000 N m, 1 to 32 | |
//! | `actuation.drag_coefficient`, `frontal_area`, `air_density`, `rolling_resistance` | 0 to 2, 0 to 20 m^2, 0.5 to 1.5 kg/m^3, 0 to 0.1 | |
//! | `actuation.max_steer_angle`, `pedal_time_constant_s` | 0.01 to pi/2 rad, 0 to 5 s | |
//! | `tracker.control_dt_s`, `max_physics_dt_s` | 1 ms to 1 s, 10 us to `control_dt_s` | the ranges `scene::executed_check` reads back |
//! | `tracker.lateral`, `longitudinal` gains | `k_p`, `k_d`, `k_i` 0 to 100 | the paper: 2, 0.2, 0 |
//! | `tracker.limits` | 0 to 1 each | |
//! | `tracker.position_gain`, `lookahead_s`, `lookahead_min_m`, `lookahead_distance_ratio_s` | 0 to 10 1/s, 0 to 10 s, 0 to 100 m, 0 to 10 s | |
//! | `smoothing` sigmas, `jerk_psd`, `robust_k`, `iterations` | 1e-4 to 10 m, 1e-6 to 1e6, 0.5 to 100, 1 to 20 | |
//! | `validity` | `max_tracking_error_m` 0.01 to 1,000 m, `max_friction_limit_s` 0 to 3,600 s | |
//! | `resample_hz` | at most [`scene::executed_check::MAX_RESAMPLED_SERIES`] rates of 1 mHz to 1 kHz | sample counts: [`crate::budget`] |

use crate::error::SimError;
use crate::rollout_config::RolloutConfig;
use crate::tyre::TyreModel;
use scene::executed_check as ex;
use std::f64::consts::FRAC_PI_2;

type Check = Result<(), SimError>;

fn bad(field: &str, message: String) -> SimError {
    SimError::Config { field: field.to_string(), message }
}

/// `v` within `[lo, hi]` (NaN fails); names `field` and the range in `unit`.
fn range(field: &str, v: f64, lo: f64, hi: f64, unit: &str) -> Check {
    if (lo..=hi).contains(&v) {
        return Ok(());
    }
    Err(bad(field, format!("must be from {} to {} {unit}, got {}", ex::num(lo), ex::num(hi), ex::num(v))))
}

/// `v` within `[lo, hi]` and not zero (a limit that must allow motion both ways).
fn nonzero(field: &str, v: f64, lo: f64, hi: f64, unit: &str) -> Check {
    range(field, v, lo, hi, unit)?;
    if v == 0.0 {
        return Err(bad(field, format!("must not be 0 (from {lo} to {hi} {unit})")));
    }
    Ok(())
}

/// A piecewise-linear table: 1 to 64 points, x strictly increasing within `xr`, y within `yr`.
fn table(field: &str, t: &[(f64, f64)], xr: [f64; 2], xu: &str, yr: [f64; 2], yu: &str) -> Check {
    if t.is_empty() || t.len() > 64 {
        return Err(bad(field, format!("needs 1 to 64 points, got {}", t.len())));
    }
    for (i, (x, y)) in t.iter().enumerate() {
        range(&format!("{field}[{i}][0]"), *x, xr[0], xr[1], xu)?;
        range(&format!("{field}[{i}][1]"), *y, yr[0], yr[1], yu)?;
        if i > 0 && *x <= t[i - 1].0 {
            return Err(bad(&format!("{field}[{i}][0]"), format!("must increase strictly ({x} after {})", t[i - 1].0)));
        }
    }
    Ok(())
}

impl RolloutConfig {
    /// Checks every field against its plausible range (module doc); `Err` names the field.
    pub fn validate(&self) -> Check {
        check_tracker(self)?;
        check_vehicle(self)?;
        check_actuation(self)?;
        let s = &self.smoothing;
        for (f, v) in
            [("log_sigma_m", s.log_sigma_m), ("still_sigma_m", s.still_sigma_m), ("plan_sigma_m", s.plan_sigma_m)]
        {
            range(&format!("smoothing.{f}"), v, 1e-4, 10.0, "m")?;
        }
        range("smoothing.jerk_psd", s.jerk_psd, 1e-6, 1e6, "m^2/s^5")?;
        range("smoothing.robust_k", s.robust_k, 0.5, 100.0, "sigmas")?;
        if !(1..=20).contains(&s.iterations) {
            return Err(bad("smoothing.iterations", format!("must be from 1 to 20 passes, got {}", s.iterations)));
        }
        let v = &self.validity;
        range("validity.max_tracking_error_m", v.max_tracking_error_m, 0.01, 1000.0, "m")?;
        range("validity.max_friction_limit_s", v.max_friction_limit_s, 0.0, 3600.0, "s")?;
        if self.resample_hz.len() > ex::MAX_RESAMPLED_SERIES {
            let message =
                format!("{} rates, at most {} may be resampled", self.resample_hz.len(), ex::MAX_RESAMPLED_SERIES);
            return Err(bad("resample_hz", message));
        }
        for (i, hz) in self.resample_hz.iter().enumerate() {
            range(&format!("resample_hz[{i}]"), *hz, ex::MIN_RATE_HZ, ex::MAX_RATE_HZ, "Hz")?;
        }
        Ok(())
    }
}

fn check_tracker(c: &RolloutConfig) -> Check {
    let t = &c.tracker;
    range("tracker.control_dt_s", t.control_dt_s, ex::MIN_CONTROL_DT_S, ex::MAX_CONTROL_DT_S, "s")?;
    range("tracker.max_physics_dt_s", t.max_physics_dt_s, ex::MIN_PHYSICS_DT_S, t.control_dt_s, "s (control_dt_s)")?;
    for (name, g) in [("lateral", &t.lateral), ("longitudinal", &t.longitudinal)] {
        for (k, v) in [("k_p", g.k_p), ("k_d", g.k_d), ("k_i", g.k_i)] {
            range(&format!("tracker.{name}.{k}"), v, 0.0, 100.0, "")?;
        }
    }
    let l = &t.limits;
    for (k, v) in [("max_throttle", l.max_throttle), ("max_brake", l.max_brake), ("max_steering", l.max_steering)] {
        range(&format!("tracker.limits.{k}"), v, 0.0, 1.0, "")?;
    }
    range("tracker.position_gain", t.position_gain, 0.0, 10.0, "1/s")?;
    range("tracker.lookahead_s", t.lookahead_s, 0.0, 10.0, "s")?;
    range("tracker.lookahead_min_m", t.lookahead_min_m, 0.0, 100.0, "m")?;
    range("tracker.lookahead_distance_ratio_s", t.lookahead_distance_ratio_s, 0.0, 10.0, "s")
}

fn check_vehicle(c: &RolloutConfig) -> Check {
    let v = &c.vehicle;
    range("vehicle.length", v.length, 0.3, 30.0, "m")?;
    range("vehicle.width", v.width, 0.2, 5.0, "m")?;
    range("vehicle.a", v.a, 0.05, 15.0, "m")?;
    range("vehicle.b", v.b, 0.05, 15.0, "m")?;
    if v.wheelbase() > v.length {
        let message = format!("the wheelbase a + b = {} m is longer than the vehicle ({} m)", v.wheelbase(), v.length);
        return Err(bad("vehicle.a", message));
    }
    range("vehicle.m", v.m, 20.0, 60_000.0, "kg")?;
    range("vehicle.i_z", v.i_z, 1.0, 1e6, "kg m^2")?;
    range("vehicle.h_s", v.h_s, 0.05, 5.0, "m")?;
    range("vehicle.mu", v.mu, 0.1, 3.0, "")?;
    range("vehicle.c_sf", v.c_sf, 0.1, 100.0, "1/rad")?;
    range("vehicle.c_sr", v.c_sr, 0.1, 100.0, "1/rad")?;
    let s = &v.steering;
    nonzero("vehicle.steering.min", s.min, -FRAC_PI_2, 0.0, "rad")?;
    nonzero("vehicle.steering.max", s.max, 0.0, FRAC_PI_2, "rad")?;
    nonzero("vehicle.steering.v_min", s.v_min, -20.0, 0.0, "rad/s")?;
    nonzero("vehicle.steering.v_max", s.v_max, 0.0, 20.0, "rad/s")?;
    let l = &v.longitudinal;
    range("vehicle.longitudinal.a_max", l.a_max, 0.1, 30.0, "m/s^2")?;
    range("vehicle.longitudinal.v_min", l.v_min, -30.0, 0.0, "m/s")?;
    range("vehicle.longitudinal.v_max", l.v_max, 1.0, 100.0, "m/s")?;
    range("vehicle.longitudinal.v_switch", l.v_switch, 0.1, 100.0, "m/s")?;
    range("vehicle.kinematic_below", v.kinematic_below, 0.01, 5.0, "m/s")?;
    range("vehicle.friction", v.friction, 0.05, 2.0, "")?;
    if let TyreModel::FrictionCircle { linear_fraction, reserve } = v.tyre {
        range("vehicle.tyre.linear_fraction", linear_fraction, 0.0, 1.0, "")?;
        range("vehicle.tyre.reserve", reserve, 0.0, 1.0, "")?;
    }
    Ok(())
}

fn check_actuation(c: &RolloutConfig) -> Check {
    let a = &c.actuation;
    table("actuation.torque_curve", &a.torque_curve, [0.0, 30_000.0], "rpm", [0.0, 50_000.0], "N m")?;
    range("actuation.max_rpm", a.max_rpm, 100.0, 30_000.0, "rpm")?;
    if a.gear_ratios.is_empty() || a.gear_ratios.len() > 32 {
        return Err(bad("actuation.gear_ratios", format!("needs 1 to 32 gears, got {}", a.gear_ratios.len())));
    }
    for (i, g) in a.gear_ratios.iter().enumerate() {
        range(&format!("actuation.gear_ratios[{i}]"), *g, 0.1, 30.0, "")?;
    }
    range("actuation.final_ratio", a.final_ratio, 0.5, 30.0, "")?;
    range("actuation.drivetrain_efficiency", a.drivetrain_efficiency, 0.01, 1.0, "")?;
    range("actuation.wheel_radius", a.wheel_radius, 0.1, 1.5, "m")?;
    range("actuation.brake_torque_per_wheel", a.brake_torque_per_wheel, 1.0, 100_000.0, "N m")?;
    range("actuation.wheels", a.wheels, 1.0, 32.0, "wheels")?;
    range("actuation.drag_coefficient", a.drag_coefficient, 0.0, 2.0, "")?;
    range("actuation.frontal_area", a.frontal_area, 0.0, 20.0, "m^2")?;
    range("actuation.air_density", a.air_density, 0.5, 1.5, "kg/m^3")?;
    range("actuation.rolling_resistance", a.rolling_resistance, 0.0, 0.1, "")?;
    range("actuation.max_steer_angle", a.max_steer_angle, 0.01, FRAC_PI_2, "rad")?;
    table("actuation.steering_curve", &a.steering_curve, [0.0, 500.0], "km/h", [0.0, 1.0], "")?;
    range("actuation.pedal_time_constant_s", a.pedal_time_constant_s, 0.0, 5.0, "s")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::VehicleParams;

    fn refused(edit: impl Fn(&mut RolloutConfig), field: &str, expect: &str) {
        let mut c = RolloutConfig::default();
        edit(&mut c);
        let e = c.validate().expect_err(field).to_string();
        assert!(e.contains(&format!("`{field}`")) && e.contains(expect), "{field}: {e}");
    }

    #[test]
    fn defaults_and_the_commonroad_sets_are_valid() {
        RolloutConfig::default().validate().unwrap();
        for vehicle in [VehicleParams::vehicle2(), VehicleParams::vehicle2_linear(), VehicleParams::carla_like()] {
            RolloutConfig { vehicle, ..Default::default() }.validate().unwrap();
        }
    }

    #[test]
    fn absurd_vehicles_are_refused_by_field() {
        refused(|c| c.vehicle.m = -5.0, "vehicle.m", "from 20 to 60000 kg, got -5");
        refused(|c| c.vehicle.m = 0.0, "vehicle.m", "got 0");
        refused(|c| c.vehicle.a = 1e9, "vehicle.a", "from 0.05 to 15 m");
        refused(|c| c.vehicle.b = 5.0, "vehicle.a", "wheelbase");
        refused(|c| c.vehicle.i_z = f64::NAN, "vehicle.i_z", "got NaN");
        refused(|c| c.vehicle.steering.max = 1e6, "vehicle.steering.max", "rad");
        refused(|c| c.vehicle.steering.v_min = 0.0, "vehicle.steering.v_min", "must not be 0");
        refused(|c| c.vehicle.friction = f64::INFINITY, "vehicle.friction", "got inf");
        refused(
            |c| c.vehicle.tyre = TyreModel::FrictionCircle { linear_fraction: 2.0, reserve: 0.3 },
            "vehicle.tyre.linear_fraction",
            "from 0 to 1",
        );
    }

    #[test]
    fn absurd_actuation_and_tracker_are_refused_by_field() {
        refused(|c| c.actuation.gear_ratios.clear(), "actuation.gear_ratios", "needs 1 to 32 gears, got 0");
        refused(|c| c.actuation.max_steer_angle = 1e6, "actuation.max_steer_angle", "rad, got 1e6");
        refused(|c| c.actuation.torque_curve[2].0 = 10.0, "actuation.torque_curve[2][0]", "increase strictly");
        refused(|c| c.actuation.torque_curve.clear(), "actuation.torque_curve", "1 to 64 points");
        refused(|c| c.actuation.wheel_radius = -0.3, "actuation.wheel_radius", "from 0.1 to 1.5 m");
        refused(|c| c.tracker.lateral.k_p = f64::NAN, "tracker.lateral.k_p", "got NaN");
        refused(|c| c.tracker.longitudinal.k_d = -1.0, "tracker.longitudinal.k_d", "from 0 to 100");
        refused(|c| c.tracker.max_physics_dt_s = 0.1, "tracker.max_physics_dt_s", "control_dt_s");
        refused(|c| c.tracker.control_dt_s = 5.0, "tracker.control_dt_s", "from 0.001 to 1 s");
        refused(|c| c.smoothing.iterations = 1_000_000, "smoothing.iterations", "1 to 20");
        refused(|c| c.validity.max_tracking_error_m = f64::NAN, "validity.max_tracking_error_m", "NaN");
        refused(|c| c.resample_hz = vec![10.0; 20_000], "resample_hz", "20000 rates, at most 8");
        refused(|c| c.resample_hz.push(1e9), "resample_hz[1]", "Hz");
    }

    #[test]
    fn a_config_file_is_checked_when_it_is_read() {
        let good = serde_json::to_value(RolloutConfig::default()).unwrap();
        let back: RolloutConfig = serde_json::from_value(good.clone()).unwrap();
        assert_eq!(back, RolloutConfig::default());
        let mut bad = good;
        bad["vehicle"]["m"] = serde_json::json!(-5.0);
        let e = serde_json::from_value::<RolloutConfig>(bad).unwrap_err().to_string();
        assert!(e.contains("`vehicle.m`") && e.contains("kg"), "{e}");
    }
}
