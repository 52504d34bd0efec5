//! What a policy answers each tick, and the checks every answer passes before it reaches the
//! vehicle: a control (CARLA's `VehicleControl`: steer in [-1, 1], + = right; throttle and brake
//! in [0, 1]) held for the whole tick, or a short trajectory of timed world positions that the
//! CARLA PID tracks (as `simulate` tracks a plan). Every number must be finite and physically
//! possible: a trajectory starts within a second of the tick, covers at least the tick, lasts at
//! most [`MAX_TRAJECTORY_S`], stays within [`MAX_REACH_M`] of the ego and implies at most
//! [`MAX_SPEED`]. The built-in `log` policy alone may answer [`Action::FollowLog`] (the
//! open-loop replay: the ego is put on its logged pose, no dynamics).

use crate::error::PolicyError;
use serde::{Deserialize, Serialize};

/// The fastest a trajectory may move the ego (m/s; 252 km/h).
pub const MAX_SPEED: f64 = 70.0;
/// How far ahead in time a trajectory may reach (s).
pub const MAX_TRAJECTORY_S: f64 = 20.0;
/// How far from the ego a trajectory point may lie (m).
pub const MAX_REACH_M: f64 = 500.0;
/// Most points in one trajectory.
pub const MAX_POINTS: usize = 1000;

/// A CARLA `VehicleControl` as a policy sends it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ControlMsg {
    pub steer: f64,
    pub throttle: f64,
    pub brake: f64,
}

/// One timed point of a trajectory (scene clock, world frame).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Waypoint {
    pub t: f64,
    pub x: f64,
    pub y: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Action {
    Control(ControlMsg),
    Trajectory(Vec<Waypoint>),
    /// The ego on its logged pose (built-in `log` policy only).
    FollowLog,
}

impl Action {
    pub fn kind(&self) -> &'static str {
        match self {
            Action::Control(_) => "control",
            Action::Trajectory(_) => "trajectory",
            Action::FollowLog => "follow_log",
        }
    }
}

fn out_of_range(tick: usize, field: impl Into<String>, detail: impl Into<String>) -> PolicyError {
    PolicyError::OutOfRange { tick: format!("tick {tick}"), field: field.into(), detail: detail.into() }
}

fn in_range(tick: usize, field: &str, v: f64, lo: f64, hi: f64) -> Result<(), PolicyError> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(())
    } else {
        Err(out_of_range(tick, field, format!("must be from {lo} to {hi}, got {v}")))
    }
}

/// Checks `action` at tick `tick` (time `t`, ticks `dt` apart) for an ego at `(x, y)`.
pub fn validate(action: &Action, tick: usize, t: f64, dt: f64, ego: (f64, f64)) -> Result<(), PolicyError> {
    match action {
        Action::FollowLog => Ok(()),
        Action::Control(c) => {
            in_range(tick, "control.steer", c.steer, -1.0, 1.0)?;
            in_range(tick, "control.throttle", c.throttle, 0.0, 1.0)?;
            in_range(tick, "control.brake", c.brake, 0.0, 1.0)
        }
        Action::Trajectory(points) => {
            if points.is_empty() || points.len() > MAX_POINTS {
                return Err(out_of_range(
                    tick,
                    "trajectory",
                    format!("needs 1 to {MAX_POINTS} points, got {}", points.len()),
                ));
            }
            for (i, p) in points.iter().enumerate() {
                let field = |f: &str| format!("trajectory[{i}].{f}");
                for (name, v) in [("t", p.t), ("x", p.x), ("y", p.y)] {
                    if !v.is_finite() {
                        return Err(out_of_range(tick, field(name), format!("must be a finite number, got {v}")));
                    }
                }
                if i == 0 && !(p.t > t - 1e-9 && p.t <= t + 1.0) {
                    return Err(out_of_range(
                        tick,
                        field("t"),
                        format!(
                            "must be after the tick's time {t:.3} s and within 1 s of it (scene clock), got {:.3}",
                            p.t
                        ),
                    ));
                }
                if p.t > t + MAX_TRAJECTORY_S {
                    return Err(out_of_range(
                        tick,
                        field("t"),
                        format!("reaches more than {MAX_TRAJECTORY_S} s ahead"),
                    ));
                }
                let reach = (p.x - ego.0).hypot(p.y - ego.1);
                if reach > MAX_REACH_M {
                    return Err(out_of_range(
                        tick,
                        field("x"),
                        format!("is {reach:.1} m from the ego, more than {MAX_REACH_M} m"),
                    ));
                }
                let (pt, px, py) =
                    if i == 0 { (t, ego.0, ego.1) } else { (points[i - 1].t, points[i - 1].x, points[i - 1].y) };
                if i > 0 && p.t < pt + 1e-3 {
                    return Err(out_of_range(
                        tick,
                        field("t"),
                        "times must increase by at least 1 ms a point".to_string(),
                    ));
                }
                let span = p.t - pt;
                if span > 1e-3 {
                    let speed = (p.x - px).hypot(p.y - py) / span;
                    if speed > MAX_SPEED {
                        return Err(out_of_range(
                            tick,
                            field("x"),
                            format!("implies {speed:.1} m/s, more than {MAX_SPEED} m/s"),
                        ));
                    }
                }
            }
            let last = points[points.len() - 1].t;
            if last < t + dt - 1e-6 {
                return Err(out_of_range(
                    tick,
                    "trajectory",
                    format!("ends at {last:.3} s, before the tick does ({:.3} s)", t + dt),
                ));
            }
            Ok(())
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_what_no_car_can_do() {
        let ok = Action::Control(ControlMsg { steer: -0.2, throttle: 0.0, brake: 1.0 });
        assert!(validate(&ok, 0, 0.0, 0.1, (0.0, 0.0)).is_ok());
        let bad = Action::Control(ControlMsg { steer: 0.0, throttle: f64::NAN, brake: 0.0 });
        assert!(validate(&bad, 3, 0.0, 0.1, (0.0, 0.0)).unwrap_err().to_string().contains("control.throttle"));
        let traj =
            |pts: &[(f64, f64)]| Action::Trajectory(pts.iter().map(|&(t, x)| Waypoint { t, x, y: 0.0 }).collect());
        assert!(validate(&traj(&[(0.1, 1.0), (0.5, 5.0)]), 0, 0.0, 0.1, (0.0, 0.0)).is_ok());
        // Too fast, backwards in time, too short, too far.
        assert!(validate(&traj(&[(0.1, 100.0)]), 0, 0.0, 0.1, (0.0, 0.0)).is_err());
        assert!(validate(&traj(&[(0.2, 1.0), (0.1, 2.0)]), 0, 0.0, 0.1, (0.0, 0.0)).is_err());
        assert!(validate(&traj(&[(0.05, 0.5)]), 0, 0.0, 0.1, (0.0, 0.0)).is_err());
        assert!(validate(&traj(&[(0.1, 1.0), (19.0, 600.0)]), 0, 0.0, 0.1, (0.0, 0.0)).is_err());
    }
}
