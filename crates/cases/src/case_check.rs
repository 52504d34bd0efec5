//! What `merge` checks of a case file read back from a shard's output before the tables count it:
//! a case file is data from elsewhere (another machine, a hand edit), so the numbers the tables
//! average must be ones a measurement gives. Every MinTTC lies in `[0, TTC_CAP_S]` (the metric
//! is capped), Success agrees with MinTTC < 1 s and a valid rollout, validity agrees with its
//! reasons, every time and distance is finite, comfort percentiles are finite and non-negative
//! and ComfortViol a percentage, and every measured instant lies in the measured interval. A refusal names the round and field and what was expected.

use crate::result::{CaseResult, Status};
use metrics::ttc::TTC_CAP_S;
use metrics::CaseMetrics;

/// Slack of a measured instant outside its interval (s): one step of the metrics' 0.1 s grid.
const INSTANT_SLACK_S: f64 = 0.1;

/// Checks `c`; the error is `field: what was expected` (`rounds[1].metrics.min_ttc_center_s: ...`).
pub fn check(c: &CaseResult) -> Result<(), String> {
    let Status::Done { rounds, best } = &c.status else { return Ok(()) };
    if rounds.is_empty() || *best >= rounds.len() {
        return Err(format!("best: {best} does not name one of its {} rounds", rounds.len()));
    }
    for (i, r) in rounds.iter().enumerate() {
        metrics_ok(&r.metrics).map_err(|e| format!("rounds[{i}].metrics.{e}"))?;
    }
    Ok(())
}

fn in_range(field: &str, v: f64, lo: f64, hi: f64, unit: &str) -> Result<(), String> {
    if v >= lo && v <= hi {
        Ok(())
    } else {
        Err(format!("{field}: {v:e} {unit}; expected a number in [{lo}, {hi}] {unit}"))
    }
}

fn success_agrees(field: &str, stored: bool, ttc: f64, valid: bool) -> Result<(), String> {
    let measured = ttc < metrics::case::SUCCESS_TTC_S && valid;
    if stored == measured {
        return Ok(());
    }
    Err(format!(
        "{field}: the file says {stored}, but its MinTTC is {ttc} s and its rollout {}: Success is MinTTC < {} s with a valid rollout",
        if valid { "valid" } else { "invalid" },
        metrics::case::SUCCESS_TTC_S
    ))
}

fn metrics_ok(m: &CaseMetrics) -> Result<(), String> {
    // Scene clocks differ (PandaSet's is Unix time): the interval is finite and at most
    // `MAX_INTERVAL_S` long, and every measured instant lies in it.
    let [t0, t1] = m.interval_s;
    in_range("interval_s[0]", t0, -f64::MAX, f64::MAX, "s")?;
    in_range("interval_s[1]", t1, t0, t0 + metrics::plausible::MAX_INTERVAL_S, "s")?;
    in_range("min_ttc_center_s", m.min_ttc_center_s, 0.0, TTC_CAP_S, "s")?;
    in_range("min_ttc_box_s", m.min_ttc_box_s, 0.0, TTC_CAP_S, "s")?;
    for (field, t) in [
        ("t_min_ttc_center_s", m.t_min_ttc_center_s),
        ("t_min_ttc_box_s", m.t_min_ttc_box_s),
        ("t_min_distance_s", m.t_min_distance_s),
    ] {
        in_range(field, t, t0 - INSTANT_SLACK_S, t1 + INSTANT_SLACK_S, "s")?;
    }
    in_range("min_distance_m", m.min_distance_m, 0.0, 2.0 * metrics::plausible::MAX_COORD_M, "m")?;
    let v = &m.validity;
    if v.valid != v.reasons.is_empty() {
        return Err(format!(
            "validity.valid: the file says {}, with {} reasons: valid means no reason",
            v.valid,
            v.reasons.len()
        ));
    }
    success_agrees("success_center", m.success_center, m.min_ttc_center_s, v.valid)?;
    success_agrees("success_box", m.success_box, m.min_ttc_box_s, v.valid)?;
    for (name, c) in [("comfort_executed", &m.comfort_executed), ("comfort_reference", &m.comfort_reference)] {
        if let Some(c) = c {
            in_range(&format!("{name}.a_lat_p95"), c.a_lat_p95, 0.0, f64::MAX, "m/s^2")?;
            in_range(&format!("{name}.kappa_dot_p95"), c.kappa_dot_p95, 0.0, f64::MAX, "1/(m s)")?;
            in_range(&format!("{name}.comfort_viol_pct"), c.comfort_viol_pct, 0.0, 100.0, "%")?;
        }
    }
    Ok(())
}
