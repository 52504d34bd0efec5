//! Limits on the work and memory a rollout may ask for, checked before it starts: the control
//! period, the physics step and every resampling rate, over the rollout's span, must stay within
//! the step counts below (each step holds a record of about 250 bytes; each physics sub-step also
//! tests the adversary's box against every replayed actor). The defaults (0.05 s control, 0.01 s
//! physics, 10 Hz) stay well inside them for logs of several hours.
//!
//! The resampled series are bounded in number and in total, not only one by one: at most
//! [`MAX_RESAMPLE_RATES`] rates (8: the metrics rate and a few video rates) and
//! [`MAX_RESAMPLED_TOTAL`] samples over all of them (400,000; about 650 bytes each in the written
//! file, so 260 MB at most). Without them a 120 KB configuration of 20,000 rates wrote 528 MB.
//! The counts, periods and rates are those `scene::executed_check` accepts when the file is read
//! back; every field's range is checked by [`RolloutConfig::validate`] (`config_check`) first.

use crate::error::SimError;
use crate::rollout_config::RolloutConfig;

/// Most control steps in one rollout.
pub const MAX_CONTROL_STEPS: f64 = 200_000.0;
/// Most physics sub-steps in one rollout (at `max_physics_dt_s`).
pub const MAX_PHYSICS_STEPS: f64 = 2_000_000.0;
/// Most samples of one resampled series.
pub const MAX_RESAMPLED: f64 = 200_000.0;
/// Most resampling rates in one rollout.
pub const MAX_RESAMPLE_RATES: usize = scene::executed_check::MAX_RESAMPLED_SERIES;
/// Most resampled samples over all rates of one rollout.
pub const MAX_RESAMPLED_TOTAL: usize = scene::executed_check::MAX_RESAMPLED_TOTAL;

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

/// A control period of `dt_s` over a rollout of `span_s` seconds, within the periods an executed
/// file may have (1 ms to 1 s).
pub fn check_control_dt(dt_s: f64, span_s: f64) -> Result<(), String> {
    period(dt_s, span_s, MAX_CONTROL_STEPS, "control steps")?;
    let (lo, hi) = (scene::executed_check::MIN_CONTROL_DT_S, scene::executed_check::MAX_CONTROL_DT_S);
    if !(lo..=hi).contains(&dt_s) {
        return Err(format!("must be from {lo} to {hi} s, got {dt_s:e}"));
    }
    Ok(())
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
    count(span_s, 1.0 / hz, MAX_RESAMPLED, &format!("{hz:e} Hz"), "samples")?;
    let (lo, hi) = (scene::executed_check::MIN_RATE_HZ, scene::executed_check::MAX_RATE_HZ);
    if !(lo..=hi).contains(&hz) {
        return Err(format!("must be from {lo} to {hi} Hz, got {hz:e}"));
    }
    Ok(())
}

/// The samples `resample` writes at `hz` over `span_s` seconds (the first one included).
fn samples(hz: f64, span_s: f64) -> f64 {
    (span_s.max(0.0) * hz + 1e-9).floor() + 1.0
}

/// Checks `cfg` for a rollout of `span_s` seconds; `Err` names the configuration field.
pub fn check(cfg: &RolloutConfig, span_s: f64) -> Result<(), SimError> {
    let field = |field: String| move |message| SimError::Config { field, message };
    if cfg.resample_hz.len() > MAX_RESAMPLE_RATES {
        let message = format!("{} rates, at most {MAX_RESAMPLE_RATES} may be resampled", cfg.resample_hz.len());
        return Err(SimError::Config { field: "resample_hz".into(), message });
    }
    let t = &cfg.tracker;
    check_control_dt(t.control_dt_s, span_s).map_err(field("tracker.control_dt_s".into()))?;
    check_physics_dt(t.max_physics_dt_s, span_s).map_err(field("tracker.max_physics_dt_s".into()))?;
    for (i, hz) in cfg.resample_hz.iter().enumerate() {
        check_rate(*hz, span_s).map_err(field(format!("resample_hz[{i}]")))?;
    }
    // Every field's range (`config_check`), after the counts above whose messages say how much
    // work a period or rate asks for.
    cfg.validate()?;
    let total: f64 = cfg.resample_hz.iter().map(|hz| samples(*hz, span_s)).sum();
    if total > MAX_RESAMPLED_TOTAL as f64 {
        let message = format!(
            "{} rates over the {span_s:.2} s rollout make {total:.0} samples in all, more than {MAX_RESAMPLED_TOTAL}",
            cfg.resample_hz.len()
        );
        return Err(SimError::Config { field: "resample_hz".into(), message });
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

    #[test]
    fn the_number_of_rates_and_the_samples_over_all_of_them_are_bounded() {
        // 20,000 rates (a 120 KB configuration wrote 528 MB): refused before any work.
        let rates = (0..20_000).map(|i| 10.0 + i as f64 * 1e-3).collect();
        let mut c = RolloutConfig { resample_hz: rates, ..Default::default() };
        let e = check(&c, 4.0).unwrap_err().to_string();
        assert!(e.contains("`resample_hz`") && e.contains("20000 rates, at most 8"), "{e}");
        // 8 rates of 900 Hz over 60 s: each within the per-series budget (54,001 samples), 432,008
        // in all.
        c.resample_hz = vec![900.0; 8];
        check(&c, 50.0).unwrap();
        let e = check(&c, 60.0).unwrap_err().to_string();
        assert!(e.contains("`resample_hz`") && e.contains("432008 samples in all, more than 400000"), "{e}");
    }

    #[test]
    fn flag_values_are_held_to_the_ranges_an_executed_file_may_have() {
        assert!(check_control_dt(5.0, 9.0).unwrap_err().contains("from 0.001 to 1 s"));
        assert!(check_rate(2000.0, 1.0).unwrap_err().contains("from 0.001 to 1000 Hz"));
        check_control_dt(0.05, 9.0).unwrap();
        check_rate(24.0, 9.0).unwrap();
    }
}
