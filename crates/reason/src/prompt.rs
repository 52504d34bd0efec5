//! Prompt texts of the Zone and Trajectory agents. The behaviour the user asked for is stated
//! in every prompt (the original ignored it); `auto` lists the whole library.

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
    let list: Vec<Behavior> = behavior.map_or(Behavior::ALL.to_vec(), |b| vec![b]);
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
) -> String {
    let mut s = format!(
        "{}\n{}\n{summary}\nThe log continues {:.1} s after t0, so ttc_s must be at most that.",
        behaviours_text(behavior),
        zones_text(world, layout),
        world.horizon()
    );
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

/// The follow-up message listing what was wrong with the last reply.
pub fn violations_text(v: &[crate::reply::Violation]) -> String {
    let mut s = String::from("Your reply was rejected:\n");
    for x in v {
        let _ = writeln!(s, "- {x}");
    }
    s.push_str("Reply again with one corrected JSON object.");
    s
}
