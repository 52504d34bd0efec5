//! Limits on the work and memory a rollout may ask for, checked before it starts: the control
//! period, the physics step and every resampling rate, over the rollout's span, must stay within
//! the step counts below (each step holds a record of about 250 bytes; each physics sub-step also
//! tests the adversary's box against every replayed actor). The defaults (0.05 s control, 0.01 s
//! physics, 10 Hz) stay well inside them for logs of several hours.

use crate::error::SimError;
use crate::rollout::RolloutConfig;

/// Most control steps in one rollout.
pub const MAX_CONTROL_STEPS: f64 = 200_000.0;
/// Most physics sub-steps in one rollout (at `max_physics_dt_s`).
pub const MAX_PHYSICS_STEPS: f64 = 2_000_000.0;
/// Most samples of one resampled series.
pub const MAX_RESAMPLED: f64 = 200_000.0;

/// Steps of `dt_s` seconds (shown as `shown`) over `span_s` against `max`; names no field.
fn count(span_s: f64, dt_s: f64, max: f64, shown: &str, what: &str) -> Result<(), String> {
    let n = span_s / dt_s;
    if n > max {
        return Err(format!("{shown} over the {span_s:.2} s rollout makes {n:.3e} {what}, more than {max}"));
    }
    Ok(())
}

fn period(dt_s: f64, span_s: f64, max: f64, what: &str) -> Result<(), String> {
    if !(dt_s > 0.0 && dt_s.is_finite()) {
        return Err(format!("must be a positive number of seconds, got {dt_s:e}"));
    }
    count(span_s, dt_s, max, &format!("{dt_s:e} s"), what)
}

/// A control period of `dt_s` over a rollout of `span_s` seconds.
pub fn check_control_dt(dt_s: f64, span_s: f64) -> Result<(), String> {
    period(dt_s, span_s, MAX_CONTROL_STEPS, "control steps")
}

/// A physics step of `dt_s` over a rollout of `span_s` seconds.
pub fn check_physics_dt(dt_s: f64, span_s: f64) -> Result<(), String> {
    period(dt_s, span_s, MAX_PHYSICS_STEPS, "physics steps")
}

/// A resampling rate of `hz` over a rollout of `span_s` seconds.
pub fn check_rate(hz: f64, span_s: f64) -> Result<(), String> {
    if !(hz > 0.0 && hz.is_finite()) {
        return Err(format!("must be a positive rate in Hz, got {hz:e}"));
    }
    count(span_s, 1.0 / hz, MAX_RESAMPLED, &format!("{hz:e} Hz"), "samples")
}

/// Checks `cfg` for a rollout of `span_s` seconds; `Err` names the configuration field.
pub fn check(cfg: &RolloutConfig, span_s: f64) -> Result<(), SimError> {
    let field = |field: String| move |message| SimError::Config { field, message };
    let t = &cfg.tracker;
    check_control_dt(t.control_dt_s, span_s).map_err(field("tracker.control_dt_s".into()))?;
    check_physics_dt(t.max_physics_dt_s, span_s).map_err(field("tracker.max_physics_dt_s".into()))?;
    for (i, hz) in cfg.resample_hz.iter().enumerate() {
        check_rate(*hz, span_s).map_err(field(format!("resample_hz[{i}]")))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_pass_and_tiny_steps_or_huge_rates_name_the_field() {
        let cfg = RolloutConfig::default();
        check(&cfg, 3600.0).unwrap();
        let mut c = cfg.clone();
        c.tracker.control_dt_s = 1e-9;
        let e = check(&c, 9.0).unwrap_err().to_string();
        assert!(e.contains("tracker.control_dt_s") && e.contains("control steps"), "{e}");
        let mut c = cfg.clone();
        c.resample_hz.push(1e9);
        let e = check(&c, 9.0).unwrap_err().to_string();
        assert!(e.contains("resample_hz[1]") && e.contains("samples"), "{e}");
        let mut c = cfg;
        c.resample_hz[0] = f64::NAN;
        assert!(check(&c, 9.0).unwrap_err().to_string().contains("positive rate"));
    }
}
