//! Validation of every agent reply (LLMs propose, code checks). Zone decisions: the behaviour is
//! the requested one, the vehicle exists and is present at t0, the zone is one of four and one
//! the vehicle can reach for that behaviour, TTC in (0, horizon]; the user's constraints
//! (`--adversary`, `--zone`, `--ttc`) hold. The accepted TTC is put on the waypoint grid (the
//! nearest multiple of dt, see [`snap_ttc`]): a trajectory must end at t0 + TTC in steps of
//! exactly dt, which no TTC off the grid allows. Trajectories: finite, strictly increasing times
//! at exactly the requested dt from t0 to t0 + TTC, start within 0.5 m of the vehicle, end within
//! 0.5 m of the collision target, speed <= 40 m/s, |acceleration| <= 8 m/s^2. They may be written
//! in the world frame or in the ego frame at t0 ([`TrajFrame`]); violations quote the reply's frame.

use crate::behavior::candidate_zones;
use crate::quintic::limits;
use crate::reply::{Violation, WaypointReply, ZoneReply};
use crate::world::World;
use scene::glam::DVec2;
use scene::motion::Pose2;
use scene::{Behavior, Risk, Waypoint, Zone};

pub const START_TOLERANCE_M: f64 = 0.5;
pub const END_TOLERANCE_M: f64 = 0.5;
pub const MAX_SPEED: f64 = 40.0;
pub const MAX_ACCEL: f64 = 8.0;
const TIME_TOLERANCE: f64 = 1e-6;

/// A validated Zone agent decision.
#[derive(Clone, Debug, PartialEq)]
pub struct ZoneDecision {
    pub vehicle_id: String,
    pub zone: Zone,
    pub behavior: Behavior,
    pub ttc_s: f64,
    pub risk: Risk,
    pub analysis: String,
    pub reasoning: String,
}

pub fn parse_risk(s: &str) -> Option<Risk> {
    match s {
        "low" => Some(Risk::Low),
        "medium" => Some(Risk::Medium),
        "high" => Some(Risk::High),
        "critical" => Some(Risk::Critical),
        _ => None,
    }
}

/// `ttc` on the waypoint grid: the nearest multiple of `dt` (at least one step), floored instead
/// when rounding up would pass `horizon`; `None` when the log leaves less than one step.
pub fn snap_ttc(ttc: f64, dt: f64, horizon: f64) -> Option<f64> {
    let mut k = (ttc / dt).round().max(1.0);
    if k * dt > horizon + 1e-9 {
        k = (horizon / dt + 1e-9).floor();
    }
    (k >= 1.0).then_some(k * dt)
}

/// What the user fixed for this run (`None`: the agent chooses).
#[derive(Clone, Copy, Debug, Default)]
pub struct Requested<'a> {
    pub behavior: Option<Behavior>,
    pub adversary: Option<&'a str>,
    pub zone: Option<Zone>,
    pub ttc_s: Option<f64>,
    /// Waypoint spacing (s): the TTC grid.
    pub dt: f64,
}

impl<'a> Requested<'a> {
    pub fn of(o: &'a crate::ReasonOptions) -> Self {
        Requested { behavior: o.behavior, adversary: o.adversary.as_deref(), zone: o.zone, ttc_s: o.ttc_s, dt: o.dt }
    }
}

/// Checks a Zone reply against the scene and the user's request.
pub fn validate_zone(world: &World, r: &ZoneReply, req: &Requested) -> Result<ZoneDecision, Vec<Violation>> {
    let requested = req.behavior;
    let mut v = Vec::new();
    if let Some(a) = req.adversary.filter(|a| *a != r.vehicle_id) {
        v.push(Violation::new(
            "vehicle_id",
            format!("must be `{a}` (the requested adversary), got `{}`", r.vehicle_id),
        ));
    }
    if let Some(z) = req.zone.filter(|z| z.as_str() != r.zone) {
        v.push(Violation::new("zone", format!("must be `{}` (the requested zone), got `{}`", z.as_str(), r.zone)));
    }
    if let Some(t) = req.ttc_s.filter(|t| (t - r.ttc_s).abs() > req.dt / 2.0) {
        v.push(Violation::new("ttc_s", format!("must be {t} s (the requested TTC), got {}", r.ttc_s)));
    }
    let behavior = match r.behavior.parse::<Behavior>() {
        Ok(b) if requested.is_some_and(|q| q != b) => {
            v.push(Violation::new(
                "behavior",
                format!("must be `{}` (the requested behaviour), got `{b:?}`", requested.map_or("", |q| q.as_str())),
            ));
            None
        }
        Ok(b) => Some(b),
        Err(e) => {
            v.push(Violation::new("behavior", e));
            None
        }
    };
    let zone = match r.zone.parse::<Zone>() {
        Ok(z) => Some(z),
        Err(e) => {
            v.push(Violation::new("zone", e));
            None
        }
    };
    let risk = parse_risk(&r.risk);
    if risk.is_none() {
        v.push(Violation::new("risk", format!("`{}` is not one of low, medium, high, critical", r.risk)));
    }
    let horizon = world.horizon();
    if !(r.ttc_s.is_finite() && r.ttc_s > 0.0 && r.ttc_s <= horizon + 1e-9) {
        v.push(Violation::new(
            "ttc_s",
            format!("{} is not in (0, {horizon:.2}] s (the log ends {horizon:.2} s after t0)", r.ttc_s),
        ));
    }
    match world.vehicle(&r.vehicle_id) {
        None => {
            let ids: Vec<&str> = world.vehicles.iter().take(12).map(|v| v.id.as_str()).collect();
            v.push(Violation::new(
                "vehicle_id",
                format!(
                    "vehicle `{}` does not exist or is not present at t0 (present: {})",
                    r.vehicle_id,
                    ids.join(", ")
                ),
            ));
        }
        Some(veh) => {
            if let (Some(b), Some(z)) = (behavior, zone) {
                match candidate_zones(world, veh, b) {
                    Err(why) => v.push(Violation::new(
                        "vehicle_id",
                        format!("vehicle `{}` cannot perform {}: {why}", veh.id, b.as_str()),
                    )),
                    Ok(zs) if !zs.contains(&z) => {
                        let names: Vec<&str> = zs.iter().map(|z| z.as_str()).collect();
                        v.push(Violation::new(
                            "zone",
                            format!(
                                "vehicle `{}` performing {} can aim at {} only",
                                veh.id,
                                b.as_str(),
                                names.join(" or ")
                            ),
                        ));
                    }
                    Ok(_) => {}
                }
            }
        }
    }
    let ttc = snap_ttc(r.ttc_s, req.dt, horizon);
    if ttc.is_none() && v.is_empty() {
        v.push(Violation::new(
            "ttc_s",
            format!("the log ends {horizon:.2} s after t0, less than one dt = {} s", req.dt),
        ));
    }
    if !v.is_empty() {
        return Err(v);
    }
    Ok(ZoneDecision {
        vehicle_id: r.vehicle_id.clone(),
        zone: zone.expect("checked"),
        behavior: behavior.expect("checked"),
        ttc_s: ttc.expect("checked"),
        risk: risk.expect("checked"),
        analysis: r.analysis.clone(),
        reasoning: r.reasoning.clone(),
    })
}

/// The frame a Trajectory reply is written in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TrajFrame {
    /// World coordinates, times on the scene clock.
    World,
    /// The ego frame at t0 (origin the ego's centre, x forward, y left), times in seconds after t0:
    /// the paper's frame.
    EgoAtT0(Pose2),
}

impl TrajFrame {
    pub fn ego_at_t0(world: &World) -> Self {
        let e = &world.ego_now;
        TrajFrame::EgoAtT0(Pose2 { t: world.t0, x: e.p.x, y: e.p.y, heading: e.heading })
    }

    /// A reply waypoint on the scene clock in the world frame.
    pub fn to_world(&self, w: &WaypointReply) -> Waypoint {
        match self {
            TrajFrame::World => Waypoint { t: w.t, x: w.x, y: w.y },
            TrajFrame::EgoAtT0(pose) => {
                let p = pose.to_world(DVec2::new(w.x, w.y));
                Waypoint { t: pose.t + w.t, x: p.x, y: p.y }
            }
        }
    }

    /// A world point as the reply's frame writes it.
    pub fn show(&self, p: DVec2) -> DVec2 {
        match self {
            TrajFrame::World => p,
            TrajFrame::EgoAtT0(pose) => pose.to_local(p),
        }
    }

    /// A scene-clock time as the reply's frame writes it.
    pub fn show_t(&self, t: f64) -> f64 {
        match self {
            TrajFrame::World => t,
            TrajFrame::EgoAtT0(pose) => t - pose.t,
        }
    }
}

/// Checks trajectory waypoints (written in `frame`) against the decision and the collision
/// target (world); returns them in the world frame on the scene clock.
pub fn validate_trajectory(
    world: &World,
    d: &ZoneDecision,
    target: DVec2,
    reply: &[WaypointReply],
    dt: f64,
    frame: TrajFrame,
) -> Result<Vec<Waypoint>, Vec<Violation>> {
    let mut v = Vec::new();
    let n = (d.ttc_s / dt).round() as usize + 1;
    if reply.len() < 2 {
        return Err(vec![Violation::new(
            "waypoints",
            format!("need {n} waypoints from t0 to t0 + TTC at dt {dt} s, got {}", reply.len()),
        )]);
    }
    if let Some(i) = reply.iter().position(|p| !(p.t.is_finite() && p.x.is_finite() && p.y.is_finite())) {
        return Err(vec![Violation::new(format!("waypoints[{i}]"), "t, x and y must be finite numbers")]);
    }
    let w: Vec<Waypoint> = reply.iter().map(|p| frame.to_world(p)).collect();
    for (i, p) in w.windows(2).enumerate() {
        let step = p[1].t - p[0].t;
        if step <= 0.0 {
            v.push(Violation::new(
                format!("waypoints[{}].t", i + 1),
                format!("times must increase strictly ({} after {})", reply[i + 1].t, reply[i].t),
            ));
            break;
        }
        if (step - dt).abs() > TIME_TOLERANCE {
            v.push(Violation::new(
                format!("waypoints[{}].t", i + 1),
                format!("spacing {step:.4} s, expected dt = {dt} s"),
            ));
            break;
        }
    }
    if (w[0].t - world.t0).abs() > TIME_TOLERANCE {
        v.push(Violation::new(
            "waypoints[0].t",
            format!("must be t0 = {:.3} s, got {:.3}", frame.show_t(world.t0), reply[0].t),
        ));
    }
    let t_end = world.t0 + d.ttc_s;
    let last = w[w.len() - 1];
    if (last.t - t_end).abs() > TIME_TOLERANCE {
        v.push(Violation::new(
            format!("waypoints[{}].t", w.len() - 1),
            format!(
                "the last waypoint must be at t0 + TTC = {:.3} s, got {:.3}",
                frame.show_t(t_end),
                reply[w.len() - 1].t
            ),
        ));
    }
    if let Some(veh) = world.vehicle(&d.vehicle_id) {
        let off = DVec2::new(w[0].x, w[0].y).distance(veh.now.p);
        if off > START_TOLERANCE_M {
            let at = frame.show(veh.now.p);
            v.push(Violation::new(
                "waypoints[0]",
                format!(
                    "starts {off:.2} m from vehicle `{}` at ({:.2}, {:.2}); must be within {START_TOLERANCE_M} m",
                    veh.id, at.x, at.y
                ),
            ));
        }
    }
    let miss = DVec2::new(last.x, last.y).distance(target);
    if miss > END_TOLERANCE_M {
        let at = frame.show(target);
        v.push(Violation::new(
            format!("waypoints[{}]", w.len() - 1),
            format!(
                "ends {miss:.2} m from the collision target ({:.2}, {:.2}); must be within {END_TOLERANCE_M} m",
                at.x, at.y
            ),
        ));
    }
    if v.is_empty() {
        let l = limits(&w);
        if l.max_speed > MAX_SPEED {
            v.push(Violation::new("waypoints", format!("speed reaches {:.1} m/s (at most {MAX_SPEED})", l.max_speed)));
        }
        if l.max_accel > MAX_ACCEL {
            v.push(Violation::new(
                "waypoints",
                format!("acceleration reaches {:.1} m/s^2 (at most {MAX_ACCEL})", l.max_accel),
            ));
        } // A pedestrian or cyclist is held to its class's limits too.
        if let Some(veh) = world.vehicle(&d.vehicle_id).filter(|x| x.class.is_vulnerable()) {
            if let Err(why) = crate::vru::check_limits(&w, veh.class, veh.now.heading) {
                v.extend(why.into_iter().map(|m| Violation::new("waypoints", m)));
            }
        }
    }
    if v.is_empty() {
        Ok(w)
    } else {
        Err(v)
    }
}
