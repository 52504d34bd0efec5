//! Prompt texts of the Zone and Trajectory agents. The behaviour the user asked for is stated
//! in every prompt (the original ignored it); `auto` lists the whole library. The user's other
//! constraints (adversary, zone, TTC) are stated too. The paper protocol's Trajectory agent
//! works in the ego frame at t0 ([`paper_trajectory_user`]).

use crate::behavior::spec;
use crate::validate::{MAX_ACCEL, MAX_SPEED};
use crate::world::World;
use scene::glam::DVec2;
use scene::zones::zone_rect;
use scene::{Behavior, Zone, ZoneLayout};
use std::fmt::Write;

pub fn zones_text(world: &World, layout: ZoneLayout) -> String {
    let mut s = String::from("Collision zones around the ego (ego frame, metres):\n");
    for z in Zone::ALL {
        let r = zone_rect(z, layout, world.ego_length, world.ego_width);
        let _ = writeln!(
            s,
            "- {}: x in [{:.2}, {:.2}], y in [{:.2}, {:.2}]",
            z.as_str(),
            r.min.x,
            r.max.x,
            r.min.y,
            r.max.y
        );
    }
    s
}

pub fn behaviours_text(behavior: Option<Behavior>) -> String {
    let list: Vec<Behavior> = behavior.map_or(Behavior::EVERY.to_vec(), |b| vec![b]);
    let mut s = String::from(if behavior.is_some() {
        "Requested dangerous behaviour:\n"
    } else {
        "Dangerous behaviours (choose one):\n"
    });
    for b in list {
        let sp = spec(b);
        let zones: Vec<&str> = sp.zones.iter().map(|z| z.as_str()).collect();
        let _ = writeln!(
            s,
            "- {}: {} (zones: {}; TTC {:.1}-{:.1} s)",
            b.as_str(),
            sp.description,
            zones.join("/"),
            sp.ttc_min,
            sp.ttc_max
        );
    }
    s
}

pub fn zone_system(labels_only: bool) -> String {
    let mut s = String::from(
        "You are the Zone agent of a driving-simulation tool that builds safety-critical corner cases from real logs. \
Pick the other vehicle that can most plausibly perform the dangerous behaviour, the collision zone around the ego it should reach, and the risk level.",
    );
    if labels_only {
        s.push_str(" Reply with one JSON object: vehicle_id, zone, behavior, risk, reasoning (one short sentence).");
    } else {
        s.push_str(" Also estimate the time to collision ttc_s (seconds after t0) assuming the behaviour happens. Reply with one JSON object: analysis, vehicle_id, zone, behavior, ttc_s, risk, reasoning. No prose outside the JSON.");
    }
    s
}

pub fn zone_user(
    world: &World,
    layout: ZoneLayout,
    behavior: Option<Behavior>,
    summary: &str,
    feedback: Option<&str>,
    req: &crate::validate::Requested,
) -> String {
    let mut s = format!(
        "{}\n{}\n{summary}\nThe log continues {:.1} s after t0, so ttc_s must be at most that.",
        behaviours_text(behavior),
        zones_text(world, layout),
        world.horizon()
    );
    if let Some(c) = constraints_text(req) {
        s.push('\n');
        s.push_str(&c);
    }
    if let Some(f) = feedback {
        s.push_str("\nA previous attempt was executed in the physics simulator: ");
        s.push_str(f);
        s.push_str("\nChange your choice so that the vehicle reaches the zone with a time to collision below 1 s.");
    }
    s
}

pub fn trajectory_system() -> String {
    format!(
        "You are the Trajectory agent. Write the adversarial vehicle's future waypoints in the WORLD frame: a JSON object \
{{\"waypoints\": [{{\"t\": .., \"x\": .., \"y\": ..}}, ...]}}. Rules: the first waypoint is the vehicle's position at t0, \
times step by exactly dt, the last waypoint is at t0 + TTC and equals the collision target, speed <= {MAX_SPEED} m/s, \
|acceleration| <= {MAX_ACCEL} m/s^2, smooth motion. No prose outside the JSON."
    )
}

#[allow(clippy::too_many_arguments)]
pub fn trajectory_user(
    world: &World,
    behavior: Behavior,
    vehicle: &str,
    p0: DVec2,
    v0: DVec2,
    target: DVec2,
    ttc: f64,
    dt: f64,
) -> String {
    let n = (ttc / dt).round() as usize + 1;
    let ego_end = world.ego_pose(world.t0 + ttc);
    format!(
        "Behaviour: {} ({}).\nVehicle {vehicle} at t0 = {:.3} s: position ({:.2}, {:.2}), velocity ({:.2}, {:.2}) m/s.\n\
Ego at t0 + TTC: ({:.2}, {:.2}), heading {:.3} rad.\nCollision target (world): ({:.2}, {:.2}) at t = {:.3} s.\n\
dt = {dt} s, TTC = {ttc:.2} s: write exactly {n} waypoints from t = {:.3} to t = {:.3}.",
        behavior.as_str(),
        spec(behavior).description,
        world.t0,
        p0.x,
        p0.y,
        v0.x,
        v0.y,
        ego_end.x,
        ego_end.y,
        ego_end.heading,
        target.x,
        target.y,
        world.t0 + ttc,
        world.t0,
        world.t0 + ttc
    )
}

/// The user's fixed choices, as an instruction (`None`: nothing fixed beyond the behaviour).
pub fn constraints_text(req: &crate::validate::Requested) -> Option<String> {
    let mut parts = Vec::new();
    if let Some(a) = req.adversary {
        parts.push(format!("vehicle_id must be {a}"));
    }
    if let Some(z) = req.zone {
        parts.push(format!("zone must be {}", z.as_str()));
    }
    if let Some(t) = req.ttc_s {
        parts.push(format!("ttc_s must be {t}"));
    }
    (!parts.is_empty()).then(|| format!("The user requires: {}.", parts.join("; ")))
}

pub fn paper_trajectory_system() -> String {
    format!(
        "You are the Trajectory agent. Write the adversarial vehicle's future waypoints in the EGO frame at t0 (origin: the ego's centre at t0, \
x forward, y left, metres; t in seconds after t0): a JSON object {{\"waypoints\": [{{\"t\": .., \"x\": .., \"y\": ..}}, ...]}}. \
Rules: the first waypoint is (t = 0, the vehicle's position (x0, y0)), times step by exactly dt, the last waypoint is at t = TTC and equals the \
collision target, speed <= {MAX_SPEED} m/s, |acceleration| <= {MAX_ACCEL} m/s^2, smooth motion consistent with the behaviour. No prose outside the JSON."
    )
}

/// The paper's Trajectory agent input: the adversary's history, the ego's logged future, its start
/// (x0, y0), the collision target, the behaviour and TTC, all in the ego frame at t0.
#[allow(clippy::too_many_arguments)]
pub fn paper_trajectory_user(
    world: &World,
    behavior: Behavior,
    vehicle: &crate::world::Vehicle,
    target: DVec2,
    ttc: f64,
    dt: f64,
    history_s: f64,
) -> String {
    let n = (ttc / dt).round() as usize + 1;
    let mut hist = String::new();
    let steps = (history_s / 0.5).round() as i64;
    for k in -steps..=0 {
        let t = world.t0 + k as f64 * 0.5;
        if let Some(kin) = crate::world::kin_at(&vehicle.run, t) {
            let p = world.to_ego_now(kin.p);
            let _ = write!(hist, " (t {:+.1}, x {:.2}, y {:.2}, v {:.1})", t - world.t0, p.x, p.y, kin.speed());
        }
    }
    let mut fut = String::new();
    let mut t = 0.5;
    while t <= ttc + 1e-9 {
        let p = world.to_ego_now(world.ego_pose(world.t0 + t).position());
        let _ = write!(fut, " (t {t:.1}, x {:.2}, y {:.2})", p.x, p.y);
        t += 0.5;
    }
    let p0 = world.to_ego_now(vehicle.now.p);
    let v0 = world.to_ego_now(vehicle.now.p + vehicle.now.v) - p0;
    let tl = world.to_ego_now(target);
    format!(
        "Behaviour: {} ({}).\nVehicle {} history (ego frame at t0):{hist}.\nEgo logged future:{fut}.\n\
Vehicle start (x0, y0) = ({:.2}, {:.2}), velocity ({:.2}, {:.2}) m/s.\nCollision target (x, y) = ({:.2}, {:.2}) at t = TTC = {ttc:.2} s.\n\
dt = {dt} s: write exactly {n} waypoints, t = 0, {dt}, ..., {ttc:.2}.",
        behavior.as_str(),
        spec(behavior).description,
        vehicle.id,
        p0.x,
        p0.y,
        v0.x,
        v0.y,
        tl.x,
        tl.y,
    )
}

/// The follow-up message listing what was wrong with the last reply.
pub fn violations_text(v: &[crate::reply::Violation]) -> String {
    let mut s = String::from("Your reply was rejected:\n");
    for x in v {
        let _ = writeln!(s, "- {x}");
    }
    s.push_str("Reply again with one corrected JSON object.");
    s
}
