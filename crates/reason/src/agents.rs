//! The two-agent chain. The Zone agent proposes (vehicle, zone, behaviour, TTC, risk); the
//! Trajectory agent proposes waypoints to a collision target sampled in that zone. Every reply
//! is parsed and validated; on failure the agent is re-prompted with the list of violations (up
//! to `max_retries` times), then the planner repairs it ([`Repair::Planner`]) or the run ends
//! with [`Outcome::Rejected`] ([`Repair::None`]). Under our protocol small models
//! ([`Capability::LabelsOnly`]) only choose: the vehicle and zone from code-checked candidates,
//! and a trajectory style among code-generated ones; every number comes from code. Under the
//! paper's protocol ([`Protocol::Paper`]) every model writes the TTC and the timed waypoints
//! itself, in the ego frame at t0 (`trajectory_agent`).

use crate::backend::{Backend, Capability};
use crate::chat::{invalid, repaired, Chat};
use crate::constraints::{search, search_with};
use crate::planner::{Breadth, Candidate};
use crate::prompt::{zone_system, zone_user};
use crate::reply::{parse_zone, Violation, ZoneReply};
use crate::summary::{describe, SummaryOptions};
use crate::trajectory_agent::{trajectory_agent, TrajectoryAsk};
use crate::validate::{validate_zone, Requested, ZoneDecision};
use crate::world::World;
use crate::{Outcome, Protocol, ReasonError, ReasonOptions, Repair, Validity, ValidityStats};
use scene::Behavior;
use serde_json::json;

/// What `auto` chooses among: every behaviour some road user in `world` may perform (its class;
/// with `--adversary`, only that one's).
pub fn auto_behaviours(world: &World) -> Vec<Behavior> {
    let out: Vec<Behavior> = Behavior::EVERY
        .into_iter()
        .filter(|b| world.actors().any(|v| crate::behavior::class_can(v.class, *b)))
        .collect();
    // Nobody in range: every behaviour, so that each says why.
    if out.is_empty() {
        Behavior::EVERY.to_vec()
    } else {
        out
    }
}

/// The planner's best candidate for the behaviour (or for every behaviour when `None`).
pub fn best_candidate(world: &World, o: &ReasonOptions) -> Result<Candidate, String> {
    ranked_candidates(world, o).map(|mut c| c.swap_remove(0))
}

/// Every candidate of the planner for the behaviour (or for every behaviour when `None`), best
/// first (a stable sort by score: equal scores keep the behaviour's own order); `Err` says why
/// there is none.
pub fn ranked_candidates(world: &World, o: &ReasonOptions) -> Result<Vec<Candidate>, String> {
    ranked_candidates_with(world, o, Breadth::DEFAULT)
}

/// [`ranked_candidates`] from a search sampled as `breadth` says.
pub fn ranked_candidates_with(world: &World, o: &ReasonOptions, breadth: Breadth) -> Result<Vec<Candidate>, String> {
    let behaviours: Vec<Behavior> = o.behavior.map_or_else(|| auto_behaviours(world), |b| vec![b]);
    let mut reasons = Vec::new();
    let mut all: Vec<Candidate> = Vec::new();
    for b in behaviours {
        match search_with(world, b, o, breadth) {
            Ok(c) => all.extend(c),
            Err(e) => reasons.push(e),
        }
    }
    all.sort_by(|a, b| a.score.total_cmp(&b.score));
    (!all.is_empty()).then_some(all).ok_or_else(|| match &o.adversary {
        Some(id) => {
            let what = o.behavior.map_or("be the adversary".to_string(), |b| format!("perform {}", b.as_str()));
            let zone = o.zone.map_or(String::new(), |z| format!(" into zone {}", z.as_str()));
            format!("track {id} cannot {what}{zone}: {}", reasons.join("; "))
        }
        None => reasons.join("; "),
    })
}

pub fn describe_candidate(world: &World, c: &Candidate) -> String {
    let v = world.vehicle(&c.vehicle_id).expect("candidate vehicles are in the world");
    let l = world.to_ego_now(v.now.p);
    let contact = c.predicted_contact_with.as_ref().map_or(String::new(), |(id, t)| {
        format!("; no clear path: its path touches logged actor {id} at t0 + {:.1} s first", t - world.t0)
    });
    format!(
        "{} {} is {:.1} m {} and {:.1} m {} of the ego at {:.1} m/s; {} brings it into the {} zone at t0 + {:.1} s with a predicted centre MinTTC of {:.2} s",
        v.class.as_str(),
        c.vehicle_id,
        l.x.abs(),
        if l.x >= 0.0 { "ahead" } else { "behind" },
        l.y.abs(),
        if l.y >= 0.0 { "left" } else { "right" },
        v.now.speed(),
        c.behavior.as_str(),
        c.zone.as_str(),
        c.ttc_s,
        c.predicted_min_ttc
    ) + &contact
        + &format!("; path: {} ({})", c.path.as_str(), c.path_note)
}

pub(crate) fn decision_of(world: &World, c: &Candidate) -> ZoneDecision {
    ZoneDecision {
        vehicle_id: c.vehicle_id.clone(),
        zone: c.zone,
        behavior: c.behavior,
        ttc_s: c.ttc_s,
        risk: c.risk(),
        analysis: String::new(),
        reasoning: describe_candidate(world, c),
    }
}

/// The Zone and Trajectory agents on an LLM backend.
pub fn run_llm(world: &World, o: &ReasonOptions, backend: &mut dyn Backend) -> Result<Outcome, ReasonError> {
    let best = match best_candidate(world, o) {
        Ok(c) => c,
        Err(reason) => return Ok(Outcome::NoFeasible { reason }),
    };
    let behaviours: Vec<Behavior> = o.behavior.map_or_else(|| auto_behaviours(world), |b| vec![b]);
    let small = backend.capability() == Capability::LabelsOnly;
    let labels_only = small && o.protocol == Protocol::Ours;
    let agent = backend.name();
    // Small models get a compact scene (fewer vehicles, 1 s samples) and short replies.
    let (max_tokens, summary_opts) = if small {
        (256, SummaryOptions { history_s: o.history_s, sample_every_s: 1.0, max_vehicles: 6 })
    } else {
        (1500, SummaryOptions { history_s: o.history_s, ..SummaryOptions::default() })
    };
    let mut chat = Chat { backend, temperature: o.temperature, seed: o.seed };
    let summary = describe(world, o.behavior, &summary_opts);
    let req = Requested::of(o);

    // Every feasible candidate (labels-only backends choose among these; they also give TTCs).
    let feasible: Vec<Candidate> = behaviours.iter().filter_map(|b| search(world, *b, o).ok()).flatten().collect();
    let ids: Vec<String> = {
        let mut v: Vec<String> = feasible.iter().map(|c| c.vehicle_id.clone()).collect();
        v.sort();
        v.dedup();
        v
    };
    let zone_names: Vec<&str> =
        o.zone.map_or(scene::Zone::ALL.to_vec(), |z| vec![z]).iter().map(|z| z.as_str()).collect();
    let behaviour_names: Vec<&str> = behaviours.iter().map(|b| b.as_str()).collect();
    let zone_result = if labels_only {
        // Choices are pre-filtered by code: vehicles and zones that have feasible candidates.
        let mut feasible_zones: Vec<&str> = feasible.iter().map(|c| c.zone.as_str()).collect();
        feasible_zones.sort();
        feasible_zones.dedup();
        let schema = json!({
            "type": "object", "additionalProperties": false,
            "required": ["vehicle_id", "zone", "behavior", "risk", "reasoning"],
            "properties": {
                "vehicle_id": {"type": "string", "enum": ids},
                "zone": {"type": "string", "enum": feasible_zones},
                "behavior": {"type": "string", "enum": behaviour_names},
                "risk": {"type": "string", "enum": ["low", "medium", "high", "critical"]},
                "reasoning": {"type": "string", "maxLength": 160}
            }
        });
        let mut choices: Vec<String> = Vec::new();
        for c in &feasible {
            let line = format!("{} {} {}", c.vehicle_id, c.behavior.as_str(), c.zone.as_str());
            if !choices.contains(&line) && choices.len() < 8 {
                choices.push(line);
            }
        }
        let user = format!(
            "{}\nFeasible choices (vehicle behaviour zone): {}.",
            zone_user(world, o.layout, o.behavior, &summary, o.feedback.as_deref(), &req),
            choices.join("; ")
        );
        chat.ask(zone_system(true), user, schema, "zone", o.max_retries, max_tokens, |text| {
            let v = crate::reply::extract_json(text).map_err(|e| vec![e])?;
            let s = |k: &str| {
                v[k].as_str().map(str::to_string).ok_or_else(|| vec![Violation::new(k, "missing or not a string")])
            };
            let (vid, zone, beh) = (s("vehicle_id")?, s("zone")?, s("behavior")?);
            // TTC is computed in code: the best feasible candidate for this choice.
            let c = feasible
                .iter()
                .find(|c| c.vehicle_id == vid && c.zone.as_str() == zone && c.behavior.as_str() == beh)
                .ok_or_else(|| {
                    vec![Violation::new(
                        "zone",
                        format!("vehicle `{vid}` has no feasible trajectory into the {zone} zone for {beh}"),
                    )]
                })?;
            let reply = ZoneReply {
                analysis: String::new(),
                vehicle_id: vid,
                zone,
                behavior: beh,
                ttc_s: c.ttc_s,
                risk: s("risk")?,
                reasoning: s("reasoning")?,
            };
            validate_zone(world, &reply, &req)
        })?
    } else {
        let mut schema = crate::reply::zone_schema(
            &world.actors().map(|v| v.id.clone()).collect::<Vec<_>>(),
            &zone_names,
            &behaviour_names,
        );
        if small {
            // A grammar-constrained small model rambles inside free strings: bound them.
            schema["properties"]["analysis"]["maxLength"] = json!(200);
            schema["properties"]["reasoning"]["maxLength"] = json!(160);
        }
        chat.ask(
            zone_system(false),
            zone_user(world, o.layout, o.behavior, &summary, o.feedback.as_deref(), &req),
            schema,
            "zone",
            o.max_retries,
            if small { 400 } else { max_tokens },
            |text| validate_zone(world, &parse_zone(text)?, &req),
        )?
    };
    let (mut decision, zone_validity) = match zone_result {
        Ok(x) => x,
        Err(v) if o.repair == Repair::None => {
            let reason =
                format!("the Zone agent's reply stayed invalid after {} re-prompt(s): {}", o.max_retries, join(&v));
            let stats = ValidityStats { zone: invalid(&v), trajectory: invalid(&[Violation::new("", "not run")]) };
            return Ok(Outcome::Rejected { stats, reason });
        }
        Err(v) => (decision_of(world, &best), repaired(&v)),
    };

    let ask = TrajectoryAsk { world, o, labels_only, small, max_tokens };
    let (waypoints, target, traj_validity) = match trajectory_agent(&ask, &mut chat, &decision)? {
        Ok(((w, target), validity)) => (w, target, validity),
        Err(v) if o.repair == Repair::None => {
            let reason = format!(
                "the Trajectory agent's reply stayed invalid after {} re-prompt(s): {}",
                o.max_retries,
                join(&v)
            );
            return Ok(Outcome::Rejected {
                stats: ValidityStats { zone: zone_validity, trajectory: invalid(&v) },
                reason,
            });
        }
        Err(v) => match crate::trajectory_agent::repair(world, o, &decision) {
            Some((w, target)) => (w, target, repaired(&v)),
            None => {
                decision = decision_of(world, &best);
                (best.waypoints.clone(), best.target, repaired(&v))
            }
        },
    };
    Ok(Outcome::Plan {
        plan: crate::make_plan(world, o, &decision, waypoints, target, &agent),
        stats: Some(ValidityStats { zone: zone_validity, trajectory: traj_validity }),
    })
}

fn join(v: &[Violation]) -> String {
    v.iter().map(|x| x.to_string()).collect::<Vec<_>>().join("; ")
}

/// Whether a validity counts as valid without the planner's help.
pub fn valid_by_itself(v: &Validity) -> bool {
    matches!(v, Validity::RawValid | Validity::ValidAfterRetry { .. })
}

/// The planner as an agent.
pub fn run_planner(world: &World, o: &ReasonOptions) -> Outcome {
    match best_candidate(world, o) {
        Ok(c) => Outcome::Plan { plan: plan_of_candidate(world, o, &c), stats: None },
        Err(reason) => Outcome::NoFeasible { reason },
    }
}

/// The plan the planner hands over for candidate `c`.
pub fn plan_of_candidate(world: &World, o: &ReasonOptions, c: &Candidate) -> scene::Plan {
    let d = decision_of(world, c);
    scene::Plan { path: Some(c.path), ..crate::make_plan(world, o, &d, c.waypoints.clone(), c.target, "planner") }
}
