//! The two-agent chain. The Zone agent proposes (vehicle, zone, behaviour, TTC, risk); the
//! Trajectory agent proposes waypoints to a collision target sampled in that zone. Every reply
//! is parsed and validated; on failure the agent is re-prompted with the list of violations (up
//! to `max_retries` times), then the planner repairs it. Small models ([`Capability::LabelsOnly`])
//! only choose: the vehicle and zone from code-checked candidates, and a trajectory style among
//! code-generated ones; every number comes from code.

use crate::backend::{Backend, Capability, ChatRequest, Message, Role};
use crate::planner::{search, search_vehicle_zone, trajectory_to, Candidate};
use crate::prompt::{trajectory_system, trajectory_user, violations_text, zone_system, zone_user};
use crate::reply::{parse_trajectory, parse_zone, Violation, ZoneReply};
use crate::summary::{describe, SummaryOptions};
use crate::target::sample_target;
use crate::validate::{validate_trajectory, validate_zone, ZoneDecision};
use crate::world::World;
use crate::{Outcome, ReasonError, ReasonOptions, Validity, ValidityStats};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use scene::{Behavior, Waypoint};
use serde_json::json;

/// The planner's best candidate for the behaviour (or for every behaviour when `None`).
pub fn best_candidate(world: &World, o: &ReasonOptions) -> Result<Candidate, String> {
    let behaviours: Vec<Behavior> = o.behavior.map_or(Behavior::ALL.to_vec(), |b| vec![b]);
    let mut reasons = Vec::new();
    let mut best: Option<Candidate> = None;
    for b in behaviours {
        match search(world, b, o.layout, o.dt, o.seed) {
            Ok(c) => {
                if best.as_ref().is_none_or(|x| c[0].score < x.score) {
                    best = Some(c[0].clone());
                }
            }
            Err(e) => reasons.push(e),
        }
    }
    best.ok_or_else(|| reasons.join("; "))
}

pub fn describe_candidate(world: &World, c: &Candidate) -> String {
    let v = world.vehicle(&c.vehicle_id).expect("candidate vehicles are in the world");
    let l = world.to_ego_now(v.now.p);
    let contact = c.predicted_contact_with.as_ref().map_or(String::new(), |(id, t)| {
        format!("; no clear path: its path touches logged actor {id} at t0 + {:.1} s first", t - world.t0)
    });
    format!(
        "vehicle {} is {:.1} m {} and {:.1} m {} of the ego at {:.1} m/s; {} brings it into the {} zone at t0 + {:.1} s with a predicted centre MinTTC of {:.2} s",
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
}

fn decision_of(world: &World, c: &Candidate) -> ZoneDecision {
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

struct Chat<'b> {
    backend: &'b mut dyn Backend,
    temperature: f64,
    seed: u64,
    max_tokens: u32,
}

impl Chat<'_> {
    /// Runs one agent: ask, check with `check`, re-prompt with the violations, up to `retries`.
    fn ask<T>(
        &mut self,
        system: String,
        user: String,
        schema: serde_json::Value,
        name: &str,
        retries: usize,
        mut check: impl FnMut(&str) -> Result<T, Vec<Violation>>,
    ) -> Result<Result<(T, Validity), Vec<Violation>>, ReasonError> {
        let mut messages =
            vec![Message { role: Role::System, content: system }, Message { role: Role::User, content: user }];
        let mut last = Vec::new();
        for attempt in 0..=retries {
            let req = ChatRequest {
                messages: messages.clone(),
                schema: schema.clone(),
                schema_name: name.into(),
                temperature: self.temperature,
                seed: self.seed.wrapping_add(attempt as u64),
                max_tokens: self.max_tokens,
            };
            let reply = self.backend.complete(&req)?;
            tracing::debug!("{name} reply (attempt {}): {reply}", attempt + 1);
            match check(&reply) {
                Ok(v) => {
                    return Ok(Ok((
                        v,
                        if attempt == 0 { Validity::RawValid } else { Validity::ValidAfterRetry { retries: attempt } },
                    )))
                }
                Err(violations) => {
                    tracing::info!(
                        "{name}: reply rejected: {}",
                        violations.iter().map(|v| v.to_string()).collect::<Vec<_>>().join("; ")
                    );
                    messages.push(Message { role: Role::Assistant, content: reply });
                    messages.push(Message { role: Role::User, content: violations_text(&violations) });
                    last = violations;
                }
            }
        }
        Ok(Err(last))
    }
}

fn repaired(v: &[Violation]) -> Validity {
    Validity::Repaired { violations: v.iter().map(|x| x.to_string()).collect() }
}

/// The Zone and Trajectory agents on an LLM backend.
pub fn run_llm(world: &World, o: &ReasonOptions, backend: &mut dyn Backend) -> Result<Outcome, ReasonError> {
    let best = match best_candidate(world, o) {
        Ok(c) => c,
        Err(reason) => return Ok(Outcome::NoFeasible { reason }),
    };
    let behaviours: Vec<Behavior> = o.behavior.map_or(Behavior::ALL.to_vec(), |b| vec![b]);
    let labels_only = backend.capability() == Capability::LabelsOnly;
    let agent = backend.name();
    // Small models get a compact scene (fewer vehicles, 1 s samples) and short replies.
    let (max_tokens, summary_opts) = if labels_only {
        (256, SummaryOptions { history_s: o.history_s, sample_every_s: 1.0, max_vehicles: 6 })
    } else {
        (1500, SummaryOptions { history_s: o.history_s, ..SummaryOptions::default() })
    };
    let mut chat = Chat { backend, temperature: o.temperature, seed: o.seed, max_tokens };
    let summary = describe(world, o.behavior, &summary_opts);

    // Every feasible candidate (labels-only backends choose among these; they also give TTCs).
    let feasible: Vec<Candidate> =
        behaviours.iter().filter_map(|b| search(world, *b, o.layout, o.dt, o.seed).ok()).flatten().collect();
    let ids: Vec<String> = {
        let mut v: Vec<String> = feasible.iter().map(|c| c.vehicle_id.clone()).collect();
        v.sort();
        v.dedup();
        v
    };
    let zone_names: Vec<&str> = scene::Zone::ALL.iter().map(|z| z.as_str()).collect();
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
            zone_user(world, o.layout, o.behavior, &summary, o.feedback.as_deref()),
            choices.join("; ")
        );
        chat.ask(zone_system(true), user, schema, "zone", o.max_retries, |text| {
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
            validate_zone(world, &reply, o.behavior)
        })?
    } else {
        let schema = crate::reply::zone_schema(
            &world.vehicles.iter().map(|v| v.id.clone()).collect::<Vec<_>>(),
            &zone_names,
            &behaviour_names,
        );
        chat.ask(
            zone_system(false),
            zone_user(world, o.layout, o.behavior, &summary, o.feedback.as_deref()),
            schema,
            "zone",
            o.max_retries,
            |text| validate_zone(world, &parse_zone(text)?, o.behavior),
        )?
    };
    let (mut decision, zone_validity) = match zone_result {
        Ok(x) => x,
        Err(v) => (decision_of(world, &best), repaired(&v)),
    };

    // Trajectory agent.
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed ^ 0x7472_616a);
    let vehicle = world.vehicle(&decision.vehicle_id).expect("validated").clone();
    let grid = [decision.ttc_s];
    let (waypoints, target, traj_validity): (Vec<Waypoint>, scene::glam::DVec2, Validity) = if labels_only {
        let options =
            search_vehicle_zone(world, &vehicle, decision.behavior, decision.zone, o.layout, &grid, o.dt, &mut rng);
        let schema = json!({"type": "object", "additionalProperties": false, "required": ["style"],
            "properties": {"style": {"type": "string", "enum": ["smooth", "assertive"]}}});
        let user = format!(
            "{}\nChoose the style of vehicle {}'s manoeuvre: smooth (gentlest accelerations) or assertive (most critical time to collision).",
            trajectory_user(world, decision.behavior, &vehicle.id, vehicle.now.p, vehicle.now.v, options.first().map_or(vehicle.now.p, |c| c.target), decision.ttc_s, o.dt),
            vehicle.id
        );
        let r = chat.ask(trajectory_system(), user, schema, "trajectory", o.max_retries, |text| {
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
                    format!("no feasible trajectory for vehicle {} at TTC {:.1} s", vehicle.id, decision.ttc_s),
                )]
            })?;
            let w: Vec<_> =
                pick.waypoints.iter().map(|w| crate::reply::WaypointReply { t: w.t, x: w.x, y: w.y }).collect();
            Ok((validate_trajectory(world, &decision, pick.target, &w, o.dt)?, pick.target))
        })?;
        match r {
            Ok(((w, target), validity)) => (w, target, validity),
            Err(v) => {
                decision = decision_of(world, &best);
                (best.waypoints.clone(), best.target, repaired(&v))
            }
        }
    } else {
        let target = sample_target(world, decision.zone, o.layout, decision.ttc_s, &mut rng);
        let user = trajectory_user(
            world,
            decision.behavior,
            &vehicle.id,
            vehicle.now.p,
            vehicle.now.v,
            target,
            decision.ttc_s,
            o.dt,
        );
        let r = chat.ask(
            trajectory_system(),
            user,
            crate::reply::trajectory_schema(),
            "trajectory",
            o.max_retries,
            |text| validate_trajectory(world, &decision, target, &parse_trajectory(text)?.waypoints, o.dt),
        )?;
        match r {
            Ok((w, validity)) => (w, target, validity),
            Err(v) => match trajectory_to(world, &vehicle, decision.behavior, target, decision.ttc_s, o.dt) {
                Some(p) => (p.waypoints, target, repaired(&v)),
                None => {
                    decision = decision_of(world, &best);
                    (best.waypoints.clone(), best.target, repaired(&v))
                }
            },
        }
    };
    Ok(Outcome::Plan {
        plan: crate::make_plan(world, o, &decision, waypoints, target, &agent),
        stats: Some(ValidityStats { zone: zone_validity, trajectory: traj_validity }),
    })
}

/// The planner as an agent.
pub fn run_planner(world: &World, o: &ReasonOptions) -> Outcome {
    match best_candidate(world, o) {
        Ok(c) => {
            let d = decision_of(world, &c);
            Outcome::Plan {
                plan: crate::make_plan(world, o, &d, c.waypoints.clone(), c.target, "planner"),
                stats: None,
            }
        }
        Err(reason) => Outcome::NoFeasible { reason },
    }
}
