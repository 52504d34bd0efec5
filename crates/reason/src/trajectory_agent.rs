//! The Trajectory agent: waypoints from the adversary's position at t0 to a collision target
//! sampled (seeded) in the chosen zone, ending at t0 + TTC.
//!
//! * Labels-only (our protocol, small models): the model picks a style (`smooth`, `assertive`)
//!   among trajectories the planner generated; code writes every number.
//! * Numbers (our protocol, large models): the model writes world-frame waypoints on the scene
//!   clock.
//! * Paper protocol: every model writes the waypoints itself in the ego frame at t0 (t in seconds
//!   after t0), from the adversary's history, the ego's logged future, its start and the target
//!   (the paper's `Agent_traj`). Small models get a schema with exactly the waypoint count, so
//!   that their grammar stops.
//!
//! Every reply is validated in code ([`validate_trajectory`]) and re-prompted with its violations.

use crate::chat::{Asked, Chat};
use crate::planner::{search_vehicle_zone, trajectory_to};
use crate::prompt::{paper_trajectory_system, paper_trajectory_user, trajectory_system, trajectory_user};
use crate::reply::{parse_trajectory, Violation, WaypointReply};
use crate::target::sample_target;
use crate::validate::{validate_trajectory, TrajFrame, ZoneDecision};
use crate::world::World;
use crate::{Protocol, ReasonError, ReasonOptions};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use scene::glam::DVec2;
use scene::Waypoint;
use serde_json::json;

pub(crate) struct TrajectoryAsk<'a> {
    pub world: &'a World<'a>,
    pub o: &'a ReasonOptions,
    /// The model only chooses a style among planner trajectories.
    pub labels_only: bool,
    /// A small (grammar-constrained) model.
    pub small: bool,
    pub max_tokens: u32,
}

fn seeded(o: &ReasonOptions) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(o.seed ^ 0x7472_616a)
}

/// Tokens a reply of `n` waypoints needs (about 24 each, written out), with margin.
fn budget(n: usize) -> u32 {
    (64 + 28 * n) as u32
}

/// Runs the Trajectory agent for `d`: (world waypoints, target, validity) or the last violations.
pub(crate) fn trajectory_agent(
    a: &TrajectoryAsk,
    chat: &mut Chat,
    d: &ZoneDecision,
) -> Result<Asked<(Vec<Waypoint>, DVec2)>, ReasonError> {
    let (world, o) = (a.world, a.o);
    let vehicle = world.vehicle(&d.vehicle_id).expect("validated").clone();
    let mut rng = seeded(o);
    let n = (d.ttc_s / o.dt).round() as usize + 1;
    if a.labels_only {
        let options = search_vehicle_zone(world, &vehicle, d.behavior, d.zone, o.layout, &[d.ttc_s], o.dt, &mut rng);
        let schema = json!({"type": "object", "additionalProperties": false, "required": ["style"],
            "properties": {"style": {"type": "string", "enum": ["smooth", "assertive"]}}});
        let first_target = options.first().map_or(vehicle.now.p, |c| c.target);
        let user = format!(
            "{}\nChoose the style of vehicle {}'s manoeuvre: smooth (gentlest accelerations) or assertive (most critical time to collision).",
            trajectory_user(world, d.behavior, &vehicle.id, vehicle.now.p, vehicle.now.v, first_target, d.ttc_s, o.dt),
            vehicle.id
        );
        return chat.ask(trajectory_system(), user, schema, "trajectory", o.max_retries, a.max_tokens, |text| {
            let v = crate::reply::extract_json(text).map_err(|e| vec![e])?;
            let style = v["style"].as_str().ok_or_else(|| vec![Violation::new("style", "missing or not a string")])?;
            let pick = match style {
                "smooth" => options.iter().min_by(|a, b| a.peak_accel.total_cmp(&b.peak_accel)),
                "assertive" => options.iter().min_by(|a, b| a.predicted_min_ttc.total_cmp(&b.predicted_min_ttc)),
                other => return Err(vec![Violation::new("style", format!("`{other}` is not smooth or assertive"))]),
            }
            .ok_or_else(|| {
                vec![Violation::new(
                    "",
                    format!("no feasible trajectory for vehicle {} at TTC {:.1} s", vehicle.id, d.ttc_s),
                )]
            })?;
            let w: Vec<_> = pick.waypoints.iter().map(|w| WaypointReply { t: w.t, x: w.x, y: w.y }).collect();
            Ok((validate_trajectory(world, d, pick.target, &w, o.dt, TrajFrame::World)?, pick.target))
        });
    }
    let target = sample_target(world, d.zone, o.layout, d.ttc_s, &mut rng);
    let (system, user, frame) = if o.protocol == Protocol::Paper {
        let user = paper_trajectory_user(world, d.behavior, &vehicle, target, d.ttc_s, o.dt, o.history_s);
        (paper_trajectory_system(), user, TrajFrame::ego_at_t0(world))
    } else {
        let user = trajectory_user(world, d.behavior, &vehicle.id, vehicle.now.p, vehicle.now.v, target, d.ttc_s, o.dt);
        (trajectory_system(), user, TrajFrame::World)
    };
    let mut schema = crate::reply::trajectory_schema();
    if a.small {
        schema["properties"]["waypoints"]["minItems"] = json!(n);
        schema["properties"]["waypoints"]["maxItems"] = json!(n);
    }
    let max_tokens = a.max_tokens.max(budget(n));
    chat.ask(system, user, schema, "trajectory", o.max_retries, max_tokens, |text| {
        Ok((validate_trajectory(world, d, target, &parse_trajectory(text)?.waypoints, o.dt, frame)?, target))
    })
}

/// The planner's repair of a rejected trajectory: its trajectory for the same decision to the
/// same (seeded) target, else to any target it can reach in that zone at that TTC.
pub(crate) fn repair(world: &World, o: &ReasonOptions, d: &ZoneDecision) -> Option<(Vec<Waypoint>, DVec2)> {
    let vehicle = world.vehicle(&d.vehicle_id)?;
    let mut rng = seeded(o);
    let target = sample_target(world, d.zone, o.layout, d.ttc_s, &mut rng);
    if let Some(p) = trajectory_to(world, vehicle, d.behavior, target, d.ttc_s, o.dt) {
        return Some((p.waypoints, target));
    }
    let mut rng = seeded(o);
    let c = search_vehicle_zone(world, vehicle, d.behavior, d.zone, o.layout, &[d.ttc_s], o.dt, &mut rng);
    c.into_iter().min_by(|a, b| a.score.total_cmp(&b.score)).map(|c| (c.waypoints, c.target))
}
