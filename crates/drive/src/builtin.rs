//! The reference policies, anchors for every score:
//! * `log`: the open-loop replay of today (the ego on its logged pose, no dynamics): the driver
//!   who does not react. It is also the no-reaction run that gives NeuroNCAP's reference impact
//!   speed.
//! * `constant`: keeps a constant speed along its lane (the route), tracked by the PID: the
//!   speed it starts with, or the log's mean speed over the episode where that is higher (an
//!   ego that starts from rest in the log would otherwise stay parked).
//! * `idm-aeb`: the intelligent driver model (Treiber, Hennecke and Helbing 2000; desired
//!   speed: the log's highest over the episode) behind the nearest object in its lane, with automatic emergency braking when a box contact is
//!   predicted sooner than it could stop, both on the **ground-truth** objects: a
//!   perfect-perception baseline, not a perception stack.
//!
//! `constant` and `idm-aeb` answer 2 s trajectories along the route (0.1 s apart) that the CARLA
//! PID tracks; emergency braking is a trajectory that stops at 10 m/s^2, more than the tyres
//! give, so the PID brakes fully while it keeps the lane. None of them looks at the images.

use crate::action::{Action, Waypoint};
use crate::error::DriveError;
use crate::policy::{EpisodeInfo, Observation, Policy, Ready};
use crate::route::Route;
use metrics::ttc::{box_ttc, Footprint};
use scene::glam::DVec2;
use scene::motion::Pose2;

/// The built-in policies' names.
pub const BUILTINS: [&str; 3] = ["log", "constant", "idm-aeb"];

/// A built-in policy by name.
pub fn builtin(name: &str) -> Option<Box<dyn Policy>> {
    match name {
        "log" => Some(Box::new(Log)),
        "constant" => Some(Box::new(Constant::default())),
        "idm-aeb" => Some(Box::new(IdmAeb::default())),
        _ => None,
    }
}

/// Trajectory horizon and spacing (s).
const HORIZON_S: f64 = 2.0;
const STEP_S: f64 = 0.1;

/// The trajectory from `s` along `route` starting at time `t` with speed `v` (m/s) and a
/// constant acceleration `a` (m/s^2), never backwards.
fn along_route(route: &Route, s: f64, t: f64, v: f64, a: f64) -> Vec<Waypoint> {
    let n = (HORIZON_S / STEP_S).round() as usize;
    let (mut si, mut vi) = (s, v.max(0.0));
    (1..=n)
        .map(|i| {
            let v_next = (vi + a * STEP_S).max(0.0);
            si += 0.5 * (vi + v_next) * STEP_S;
            vi = v_next;
            let p = route.at(si);
            Waypoint { t: t + i as f64 * STEP_S, x: p.x, y: p.y }
        })
        .collect()
}

fn route_of(info: &EpisodeInfo) -> Route {
    Route::new(info.route.iter().map(|p| DVec2::new(p[0], p[1])).collect())
}

/// The open-loop replay.
pub struct Log;

impl Policy for Log {
    fn name(&self) -> String {
        "log".into()
    }
    fn needs_images(&self) -> bool {
        false
    }
    fn start(&mut self, _info: &EpisodeInfo) -> Result<Ready, DriveError> {
        Ok(Ready { name: self.name(), ground_truth: false })
    }
    fn act(&mut self, _obs: &Observation) -> Result<Action, DriveError> {
        Ok(Action::FollowLog)
    }
}

/// Keeps its starting speed and its lane.
#[derive(Default)]
pub struct Constant {
    route: Option<Route>,
    /// The log's mean speed over the episode (m/s).
    logged_mean: f64,
    speed: Option<f64>,
}

impl Policy for Constant {
    fn name(&self) -> String {
        "constant".into()
    }
    fn needs_images(&self) -> bool {
        false
    }
    fn start(&mut self, info: &EpisodeInfo) -> Result<Ready, DriveError> {
        self.route = Some(route_of(info));
        self.logged_mean = info.logged_speed_mean;
        Ok(Ready { name: self.name(), ground_truth: false })
    }
    fn act(&mut self, obs: &Observation) -> Result<Action, DriveError> {
        let route = self.route.as_ref().ok_or_else(|| DriveError::settings("policy constant", "not started"))?;
        let v = *self.speed.get_or_insert(obs.ego.speed.max(self.logged_mean));
        let (s, _) = route.project(DVec2::new(obs.ego.x, obs.ego.y));
        Ok(Action::Trajectory(along_route(route, s, obs.t, v, 0.0)))
    }
}

/// IDM parameters and the emergency brake's.
#[derive(Clone, Copy, Debug)]
pub struct IdmParams {
    /// Comfortable acceleration and deceleration (m/s^2), time headway (s), jam distance (m).
    pub a_max: f64,
    pub b_comf: f64,
    pub headway_s: f64,
    pub s0_m: f64,
    /// Half-width margin of the lane corridor beyond the ego's half width (m).
    pub corridor_margin_m: f64,
    /// The deceleration the emergency brake counts on (m/s^2) and its reaction margin (s):
    /// it brakes when a contact is predicted within `v / (2 a) + margin`.
    pub aeb_decel: f64,
    pub aeb_margin_s: f64,
}

impl Default for IdmParams {
    fn default() -> Self {
        IdmParams {
            a_max: 1.5,
            b_comf: 3.0,
            headway_s: 1.5,
            s0_m: 2.0,
            corridor_margin_m: 0.3,
            aeb_decel: 6.0,
            aeb_margin_s: 0.6,
        }
    }
}

#[derive(Default)]
pub struct IdmAeb {
    pub params: IdmParams,
    route: Option<Route>,
    desired_speed: Option<f64>,
    ego_size: [f64; 2],
    /// Whether the emergency brake fired on the last tick (it holds while the threat lasts).
    pub braking: bool,
}

impl IdmAeb {
    /// The IDM acceleration at speed `v` behind a lead `gap` metres ahead moving at `v_lead`
    /// along the route (no lead: free road).
    fn idm(&self, v: f64, v0: f64, lead: Option<(f64, f64)>) -> f64 {
        let p = &self.params;
        let free = 1.0 - (v / v0.max(0.1)).powi(4);
        let interaction = lead.map_or(0.0, |(gap, v_lead)| {
            let dv = v - v_lead;
            let s_star = p.s0_m + (v * p.headway_s + v * dv / (2.0 * (p.a_max * p.b_comf).sqrt())).max(0.0);
            (s_star / gap.max(0.1)).powi(2)
        });
        (p.a_max * (free - interaction)).clamp(-9.0, p.a_max)
    }
}

impl Policy for IdmAeb {
    fn name(&self) -> String {
        "idm-aeb".into()
    }
    fn needs_images(&self) -> bool {
        false
    }
    fn start(&mut self, info: &EpisodeInfo) -> Result<Ready, DriveError> {
        self.route = Some(route_of(info));
        self.ego_size = [info.ego_size_lwh[0], info.ego_size_lwh[1]];
        self.desired_speed = Some(info.logged_speed_max.max(1.0));
        Ok(Ready { name: self.name(), ground_truth: true })
    }
    fn act(&mut self, obs: &Observation) -> Result<Action, DriveError> {
        let route = self.route.as_ref().ok_or_else(|| DriveError::settings("policy idm-aeb", "not started"))?;
        let objects = obs.ground_truth.as_ref().map_or(&[][..], |g| &g.objects[..]);
        let e = &obs.ego;
        let v = e.speed;
        let v0 = self.desired_speed.unwrap_or(1.0);
        let pos = DVec2::new(e.x, e.y);
        let (s_ego, _) = route.project(pos);
        let [len, wid] = self.ego_size;
        let half = wid / 2.0 + self.params.corridor_margin_m;
        // The nearest object in the lane corridor ahead: (bumper gap, speed along the route).
        let mut lead: Option<(f64, f64)> = None;
        // The soonest predicted box contact with an object ahead, at constant velocities.
        let mut ttc = f64::INFINITY;
        let heading = DVec2::new(e.heading.cos(), e.heading.sin());
        let me = Footprint { pose: Pose2 { t: obs.t, x: e.x, y: e.y, heading: e.heading }, length: len, width: wid };
        for o in objects {
            let c = DVec2::new(o.x, o.y);
            let (s_o, d_o) = route.project(c);
            let dir_o = DVec2::new(o.heading.cos(), o.heading.sin());
            let tangent = route.direction(s_o);
            // Half extents of the object's box along and across the route.
            let along = 0.5 * (o.length * dir_o.dot(tangent).abs() + o.width * dir_o.perp_dot(tangent).abs());
            let across = 0.5 * (o.length * dir_o.perp_dot(tangent).abs() + o.width * dir_o.dot(tangent).abs());
            let gap = s_o - s_ego - len / 2.0 - along;
            if s_o > s_ego && d_o.abs() - across < half && lead.is_none_or(|(g, _)| gap < g) {
                lead = Some((gap, DVec2::new(o.vx, o.vy).dot(tangent)));
            }
            if (c - pos).dot(heading) > 0.0 {
                let other = Footprint {
                    pose: Pose2 { t: obs.t, x: o.x, y: o.y, heading: o.heading },
                    length: o.length,
                    width: o.width,
                };
                ttc = ttc.min(box_ttc(&me, heading * v, &other, DVec2::new(o.vx, o.vy)));
            }
        }
        let p = &self.params;
        let threshold = v / (2.0 * p.aeb_decel) + p.aeb_margin_s;
        // Hysteresis: once braking, hold it while a contact is predicted within 0.5 s more.
        self.braking = v > 0.05 && ttc < threshold + if self.braking { 0.5 } else { 0.0 };
        let a = if self.braking { -10.0 } else { self.idm(v, v0, lead) };
        Ok(Action::Trajectory(along_route(route, s_ego, obs.t, v, a)))
    }
}
