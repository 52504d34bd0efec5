//! The evaluation window: one horizon for every agent. An agent's plan ends where the agent chose
//! (the planner at its designed arrival, the baselines after 3 s); Table I and II measure every
//! attempt over the same `[t0, t0 + horizon]`, clipped at the log's end, whatever the agent.
//!
//! * Longer than the plan: the adversary's reference is extended to the horizon by
//!   `--after-plan`: `stop` (default) brakes to rest along the plan's last direction at
//!   [`STOP_DECEL`] (well inside the tyres' friction limit and the planner's 7.5 m/s^2 bound), then
//!   stays; `hold` keeps the plan's end velocity.
//! * Shorter than the plan: the plan is cut at the horizon.
//! * Contact with the ego ends the window: the case is re-run up to the contact (the first
//!   control step at or after it), so nothing after the crash is measured or judged.
//! * `--horizon plan` keeps each agent's own plan end (the old protocol, for comparison; no
//!   extension and no cut at contact).

use scene::{Plan, Scene, Waypoint};
use serde::{Deserialize, Serialize};

/// Deceleration of `--after-plan stop` (m/s^2).
pub const STOP_DECEL: f64 = 4.0;

/// `--horizon <seconds>|plan`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Horizon {
    Seconds(f64),
    Plan,
}

impl std::str::FromStr for Horizon {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "plan" {
            return Ok(Horizon::Plan);
        }
        match s.trim_end_matches('s').parse::<f64>() {
            Ok(h) if h > 0.0 && h.is_finite() => Ok(Horizon::Seconds(h)),
            _ => Err(format!("`{s}`: expected a positive number of seconds or `plan`")),
        }
    }
}

/// `--after-plan stop|hold`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AfterPlan {
    Stop,
    Hold,
}

impl std::str::FromStr for AfterPlan {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "stop" => Ok(AfterPlan::Stop),
            "hold" => Ok(AfterPlan::Hold),
            _ => Err(format!("`{s}`: expected stop or hold")),
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Window {
    pub horizon: Horizon,
    pub after_plan: AfterPlan,
}

impl Default for Window {
    fn default() -> Self {
        Window { horizon: Horizon::Seconds(5.0), after_plan: AfterPlan::Stop }
    }
}

impl Window {
    /// The window's end for an attempt starting at `t0` (scene clock), on the plan's `dt` grid,
    /// clipped at the log's end; `None` with `--horizon plan`.
    pub fn end(&self, scene: &Scene, t0: f64, dt: f64) -> Option<f64> {
        let Horizon::Seconds(h) = self.horizon else { return None };
        let last = scene.frames[scene.frames.len() - 1].timestamp_s;
        let span = h.min(last - t0).max(0.0);
        Some(t0 + ((span + 1e-9) / dt).floor() * dt)
    }

    /// The plan that is executed and measured: `plan` cut or extended to the window's end.
    pub fn apply(&self, scene: &Scene, plan: &Plan) -> Plan {
        match self.end(scene, plan.start_time_s, plan.dt_s) {
            None => plan.clone(),
            Some(end) => extend(&cut(plan, end), end, self.after_plan),
        }
    }
}

/// `plan` without its waypoints after `t_end` (at least two are kept).
pub fn cut(plan: &Plan, t_end: f64) -> Plan {
    let mut p = plan.clone();
    let keep = p.waypoints.iter().take_while(|w| w.t <= t_end + 1e-6).count().max(2);
    p.waypoints.truncate(keep);
    p
}

/// `plan` continued to `t_end` on its `dt` grid after its last waypoint.
pub fn extend(plan: &Plan, t_end: f64, after: AfterPlan) -> Plan {
    let mut p = plan.clone();
    let n = p.waypoints.len();
    let (a, b) = (p.waypoints[n - 2], p.waypoints[n - 1]);
    let dt = p.dt_s;
    let v = scene::glam::DVec2::new(b.x - a.x, b.y - a.y) / (b.t - a.t);
    let (dir, mut speed) = (v.normalize_or_zero(), v.length());
    let (mut x, mut y, mut t) = (b.x, b.y, b.t);
    while t + dt <= t_end + 1e-6 {
        let next = match after {
            AfterPlan::Stop => (speed - STOP_DECEL * dt).max(0.0),
            AfterPlan::Hold => speed,
        };
        let step = 0.5 * (speed + next) * dt;
        speed = next;
        x += dir.x * step;
        y += dir.y * step;
        t += dt;
        p.waypoints.push(Waypoint { t, x, y });
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plan(n: usize, dt: f64, speed: f64) -> Plan {
        let waypoints = (0..n).map(|k| Waypoint { t: 1.0 + k as f64 * dt, x: k as f64 * dt * speed, y: 0.0 }).collect();
        Plan {
            format: scene::plan::PLAN_FORMAT.into(),
            scene: "s".into(),
            behavior: scene::Behavior::SuddenBraking,
            adversary_track: "a".into(),
            target_zone: scene::Zone::Front,
            zone_layout: scene::ZoneLayout::Adjacent,
            start_time_s: 1.0,
            ttc_s: (n - 1) as f64 * dt,
            risk: scene::Risk::High,
            agent: "t".into(),
            reasoning: String::new(),
            dt_s: dt,
            waypoints,
            target: None,
            seed: None,
            path: None,
            inserted: None,
        }
    }

    #[test]
    fn parses_and_extends() {
        assert_eq!("5".parse::<Horizon>().unwrap(), Horizon::Seconds(5.0));
        assert_eq!("2.5s".parse::<Horizon>().unwrap(), Horizon::Seconds(2.5));
        assert_eq!("plan".parse::<Horizon>().unwrap(), Horizon::Plan);
        assert!("-1".parse::<Horizon>().is_err() && "later".parse::<AfterPlan>().is_err());
        let p = plan(21, 0.1, 10.0); // 2 s at 10 m/s
        let stop = extend(&p, 6.0, AfterPlan::Stop);
        assert!(stop.validate().is_ok(), "{:?}", stop.validate());
        assert!((stop.end_time_s() - 6.0).abs() < 1e-6);
        let last = stop.waypoints.len() - 1;
        // 10 m/s at 4 m/s^2: 12.5 m to rest, then still.
        assert!((stop.waypoints[last].x - (20.0 + 12.5)).abs() < 0.3, "{}", stop.waypoints[last].x);
        assert_eq!(stop.waypoints[last].x, stop.waypoints[last - 1].x);
        let hold = extend(&p, 6.0, AfterPlan::Hold);
        assert!((hold.waypoints.last().unwrap().x - 50.0).abs() < 1e-6);
        let short = cut(&p, 1.5);
        assert!((short.end_time_s() - 1.5).abs() < 1e-9 && short.validate().is_ok());
    }
}
