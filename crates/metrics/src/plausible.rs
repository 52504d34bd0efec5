//! What [`crate::evaluate`] checks before it measures an executed file, so that an edited or
//! corrupt file is refused instead of measured: every number finite and within physical limits
//! no road user reaches, no step moving faster than [`MAX_SPEED_MPS`] from the one before, a
//! measured interval of at most [`MAX_INTERVAL_S`] (the grid is allocated from it), and the
//! stored validity summary (`max_tracking_error_m`, `max_abs_accel_lat`) equal to what the steps
//! give; and first what every reader of the format checks (`scene::executed_check`: box sizes,
//! periods, counts, resampled series), since a case may be measured without being read.
//! Each refusal names the field (`steps[30].x`) and what was expected.

use crate::error::MetricsError;
use scene::Executed;

/// Largest |coordinate| (m): beyond any UTM northing (1e7 m).
pub const MAX_COORD_M: f64 = 1.0e7;
/// Fastest any road user moves (m/s; 360 km/h).
pub const MAX_SPEED_MPS: f64 = 100.0;
/// Largest acceleration stored for a step (m/s^2; 1000 g: beyond tyre friction and any crash
/// pulse a physics engine reports).
pub const MAX_ACCEL_MPS2: f64 = 1.0e4;
/// Longest interval measured (s): 36,000 samples on the 0.1 s grid.
pub const MAX_INTERVAL_S: f64 = 3600.0;
/// Relative tolerance of a stored summary against its recomputation.
const SUMMARY_TOLERANCE: f64 = 1e-9;

fn refuse(field: String, message: String) -> MetricsError {
    MetricsError::Implausible { field, message }
}

/// `v` in plain notation where that is short, else in exponent notation (`1e300`).
fn num(v: f64) -> String {
    if v == 0.0 || (1e-3..1e7).contains(&v.abs()) {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

fn bounded(field: impl Fn() -> String, v: f64, limit: f64, unit: &str) -> Result<(), MetricsError> {
    if v.abs() <= limit {
        return Ok(());
    }
    let message =
        format!("{} {unit} is not finite or beyond the {} {unit} any road user stays within", num(v), num(limit));
    Err(refuse(field(), message))
}

/// No sample of `path` moves faster than [`MAX_SPEED_MPS`] from the one before (1 cm of slack).
fn continuous(name: &str, path: impl Iterator<Item = (f64, f64, f64)>) -> Result<(), MetricsError> {
    let mut previous: Option<(f64, f64, f64)> = None;
    for (i, (t, x, y)) in path.enumerate() {
        if let Some((tp, xp, yp)) = previous.replace((t, x, y)) {
            let (dx, dy) = (x - xp, y - yp);
            let d = dx.hypot(dy);
            if d > MAX_SPEED_MPS * (t - tp) + 0.01 {
                let axis = if dx.abs() >= dy.abs() { "x" } else { "y" };
                return Err(refuse(
                    format!("{name}[{i}].{axis}"),
                    format!(
                        "moved {d:.2} m in {:.3} s since {name}[{}] ({:.0} m/s), faster than {MAX_SPEED_MPS} m/s",
                        t - tp,
                        i - 1,
                        d / (t - tp)
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// `stored` must equal `recomputed` (relative [`SUMMARY_TOLERANCE`]).
fn same(field: &str, stored: f64, recomputed: f64, unit: &str) -> Result<(), MetricsError> {
    if (stored - recomputed).abs() <= SUMMARY_TOLERANCE * recomputed.abs().max(1.0) {
        return Ok(());
    }
    Err(refuse(
        format!("validity.{field}"),
        format!("the file says {} {unit}, its steps give {} {unit}", num(stored), num(recomputed)),
    ))
}

/// Checks the executed file's values and stored validity against its steps (module doc).
pub fn check(e: &Executed) -> Result<(), MetricsError> {
    // What every reader of the format checks (sizes, periods, counts, finite values), also for a
    // case built in memory rather than read through `load_executed`.
    scene::executed_check::check_values(e).map_err(|(field, message)| refuse(field, message))?;
    let (t0, t1) = (e.plan.start_time_s, e.plan.end_time_s());
    if !(..=MAX_INTERVAL_S).contains(&(t1 - t0)) {
        let message = format!("the plan spans {:.1} s, longer than the {MAX_INTERVAL_S} s measured", t1 - t0);
        return Err(refuse("plan.waypoints".into(), message));
    }
    for (i, w) in e.plan.waypoints.iter().enumerate() {
        bounded(|| format!("plan.waypoints[{i}].x"), w.x, MAX_COORD_M, "m")?;
        bounded(|| format!("plan.waypoints[{i}].y"), w.y, MAX_COORD_M, "m")?;
    }
    for (i, s) in e.steps.iter().enumerate() {
        for (name, v) in [("x", s.x), ("y", s.y), ("ref_x", s.ref_x), ("ref_y", s.ref_y)] {
            bounded(|| format!("steps[{i}].{name}"), v, MAX_COORD_M, "m")?;
        }
        bounded(|| format!("steps[{i}].speed"), s.speed, MAX_SPEED_MPS, "m/s")?;
        for (name, v) in [("accel_long", s.accel_long), ("accel_lat", s.accel_lat)] {
            bounded(|| format!("steps[{i}].{name}"), v, MAX_ACCEL_MPS2, "m/s^2")?;
        }
        let rest = [
            ("yaw_rate", s.yaw_rate),
            ("steering_angle", s.steering_angle),
            ("steer", s.steer),
            ("throttle", s.throttle),
            ("brake", s.brake),
        ];
        if let Some((name, v)) = rest.into_iter().find(|(_, v)| !v.is_finite()) {
            return Err(refuse(format!("steps[{i}].{name}"), format!("{v} is not a finite number")));
        }
    }
    for (i, p) in e.ego_path.iter().enumerate() {
        bounded(|| format!("ego_path[{i}].x"), p.x, MAX_COORD_M, "m")?;
        bounded(|| format!("ego_path[{i}].y"), p.y, MAX_COORD_M, "m")?;
    }
    continuous("steps", e.steps.iter().map(|s| (s.t, s.x, s.y)))?;
    continuous("ego_path", e.ego_path.iter().map(|p| (p.t, p.x, p.y)))?;
    let v = &e.validity;
    let tracking = e.steps.iter().map(|s| (s.x - s.ref_x).hypot(s.y - s.ref_y)).fold(0.0, f64::max);
    same("max_tracking_error_m", v.max_tracking_error_m, tracking, "m")?;
    let a_lat = e.steps.iter().map(|s| s.accel_lat.abs()).fold(0.0, f64::max);
    same("max_abs_accel_lat", v.max_abs_accel_lat, a_lat, "m/s^2")?;
    let span = e.steps[e.steps.len() - 1].t - e.steps[0].t;
    if !(v.friction_limit_s >= 0.0 && v.friction_limit_s <= span + 1e-9) {
        let message = format!("{} s is not a time within the {span:.2} s rollout", v.friction_limit_s);
        return Err(refuse("validity.friction_limit_s".into(), message));
    }
    Ok(())
}
