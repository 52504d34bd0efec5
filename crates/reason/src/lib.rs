//! `reason`: the Reason stage. A Zone agent picks the adversarial vehicle, the collision zone,
//! TTC and risk for a dangerous behaviour; a Trajectory agent writes timed waypoints to a
//! collision target in that zone. LLMs propose (`backend`), code checks (`reply`, `validate`) and
//! repairs (`planner`). Baselines write the same plan format. Imports nothing of the visual half.

pub mod agents;
pub mod backend;
pub mod baselines;
pub mod behavior;
pub mod budget;
mod chat;
pub mod clearance;
pub mod constraints;
pub mod early_lateral;
pub mod frenet;
pub mod from_rest;
pub mod insert;
pub mod insert_check;
pub mod intent;
pub mod lane_motion;
pub mod lanes;
pub mod planned;
pub mod planner;
pub mod prompt;
pub mod quintic;
pub mod reply;
pub mod sampling;
pub mod street;
pub mod summary;
pub mod target;
pub mod trajectory_agent;
pub mod validate;
pub mod vru;
pub mod world;

use scene::glam::DVec2;
use scene::plan::{Plan, PLAN_FORMAT};
use scene::{Behavior, Scene, Waypoint, Zone, ZoneLayout};
use serde::{Deserialize, Serialize};
use validate::ZoneDecision;
use world::World;

#[derive(Clone, Debug)]
pub struct ReasonOptions {
    /// Analysis time t0 on the scene clock (s).
    pub t0: f64,
    /// The requested behaviour; `None` = auto (the agent chooses).
    pub behavior: Option<Behavior>,
    pub layout: ZoneLayout,
    /// Waypoint spacing (s).
    pub dt: f64,
    pub seed: u64,
    /// Vehicles farther than this from the ego at t0 are ignored (m).
    pub radius: f64,
    /// History given to the agents (s).
    pub history_s: f64,
    /// Re-prompts after an invalid reply before the planner repairs it.
    pub max_retries: usize,
    pub temperature: f64,
    /// Outcome of a previous attempt, appended to the Zone agent's prompt (closed-loop refinement).
    pub feedback: Option<String>,
    /// Only this track may be the adversary (`--adversary`); the agents see no other candidate
    /// vehicle (every actor still counts for contacts in the simulator).
    pub adversary: Option<String>,
    /// Only this collision zone (`--zone`).
    pub zone: Option<Zone>,
    /// This TTC (s, put on the dt grid) instead of the behaviour's range (`--ttc`).
    pub ttc_s: Option<f64>,
    /// Who writes the numbers: see [`Protocol`].
    pub protocol: Protocol,
    /// What happens to a reply still invalid after the re-prompts: see [`Repair`].
    pub repair: Repair,
    /// When an adversary may be inserted where the log has none ([`insert`]).
    pub insert: insert::InsertMode,
    /// The inserted vehicle's box (m; from the caller's asset library), else
    /// [`insert::DEFAULT_CAR_LWH`].
    pub insert_size_lwh: Option<[f64; 3]>,
}

/// How the LLM agents work.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Protocol {
    /// Ours: small models ([`backend::Capability::LabelsOnly`]) only choose among code-checked
    /// options; models that write numbers write the TTC and world-frame waypoints.
    #[default]
    Ours,
    /// The paper's: every model writes the Zone agent's TTC and the Trajectory agent's timed
    /// waypoints itself, in the ego frame at t0 (x forward, y left, t in seconds after t0).
    Paper,
}

/// What is done with a reply still invalid after `max_retries` re-prompts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Repair {
    /// The planner replaces it (counted as `repaired`).
    #[default]
    Planner,
    /// Nothing: the run ends with [`Outcome::Rejected`] (counted as `invalid`).
    None,
}

impl Default for ReasonOptions {
    fn default() -> Self {
        ReasonOptions {
            t0: 0.0,
            behavior: None,
            layout: ZoneLayout::Adjacent,
            dt: 0.1,
            seed: 0,
            radius: 60.0,
            history_s: 2.0,
            max_retries: 2,
            temperature: 0.7,
            feedback: None,
            adversary: None,
            zone: None,
            ttc_s: None,
            protocol: Protocol::Ours,
            repair: Repair::Planner,
            insert: insert::InsertMode::Fallback,
            insert_size_lwh: None,
        }
    }
}

/// How an agent's reply became valid (the paper counts `RawValid` only: valid at the first try).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum Validity {
    RawValid,
    ValidAfterRetry {
        retries: usize,
    },
    Repaired {
        violations: Vec<String>,
    },
    /// Still invalid after the re-prompts and no repair asked ([`Repair::None`]); only in
    /// [`Outcome::Rejected`].
    Invalid {
        violations: Vec<String>,
    },
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ValidityStats {
    pub zone: Validity,
    pub trajectory: Validity,
}

#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)] // one per run; boxing buys nothing
pub enum Outcome {
    Plan {
        plan: Plan,
        stats: Option<ValidityStats>,
    },
    /// No vehicle can perform the behaviour here (a result, not an error).
    NoFeasible {
        reason: String,
    },
    /// An agent's reply stayed invalid after the re-prompts and no repair was asked
    /// ([`Repair::None`]): no plan. `stats` says which agent (its validity is `Invalid`); an agent
    /// that never ran (the Trajectory agent after a rejected Zone reply) is `Invalid` too.
    Rejected {
        stats: ValidityStats,
        reason: String,
    },
}

#[derive(Debug, thiserror::Error)]
pub enum ReasonError {
    #[error("t0 = {t0:.3} s is outside the ego's logged span [{first:.3}, {last:.3}] s")]
    TimeOutsideScene { t0: f64, first: f64, last: f64 },
    #[error("{0}")]
    Options(String),
    /// An input beyond the limits of [`budget`]: the option or map field and why.
    #[error("{field}: {message}")]
    Input { field: String, message: String },
    #[error(transparent)]
    Backend(#[from] backend::BackendError),
}

/// Which agent writes the plan.
pub enum Agent<'a> {
    Planner,
    Llm(&'a mut dyn backend::Backend),
    Rule,
    Random,
}

pub(crate) fn make_plan(
    world: &World,
    o: &ReasonOptions,
    d: &ZoneDecision,
    waypoints: Vec<Waypoint>,
    target: DVec2,
    agent: &str,
) -> Plan {
    let reasoning = if d.analysis.is_empty() { d.reasoning.clone() } else { format!("{} {}", d.analysis, d.reasoning) };
    Plan {
        format: PLAN_FORMAT.into(),
        scene: world.scene.name.clone(),
        behavior: d.behavior,
        adversary_track: d.vehicle_id.clone(),
        target_zone: d.zone,
        zone_layout: o.layout,
        start_time_s: world.t0,
        ttc_s: d.ttc_s,
        risk: d.risk,
        agent: agent.into(),
        reasoning,
        dt_s: o.dt,
        waypoints,
        target: Some([target.x, target.y]),
        seed: Some(o.seed),
        path: None,
        inserted: None,
    }
}

/// Runs an agent at t0. Every plan returned passes `Plan::validate`.
/// Refuses options and maps beyond the limits of [`budget`] first. Where the planner finds no
/// logged road user for the behaviour (or `o.insert` is `always`), it plans an inserted one
/// ([`insert::plan_inserted`]) unless `o.insert` is `never` or an adversary was named.
pub fn reason(scene: &Scene, o: &ReasonOptions, agent: Agent) -> Result<Outcome, ReasonError> {
    reason_placed(scene, o, agent, None)
}

/// [`reason`] with the insertion's placements already built ([`insert::placements`] of the same
/// scene and options), or `None` to build them where needed.
pub fn reason_placed(
    scene: &Scene,
    o: &ReasonOptions,
    agent: Agent,
    placed: Option<&[insert::Placement]>,
) -> Result<Outcome, ReasonError> {
    budget::check(scene, o)?;
    let (first, last) = (scene.frames[0].timestamp_s, scene.frames[scene.frames.len() - 1].timestamp_s);
    let world = World::for_options(scene, o).ok_or(ReasonError::TimeOutsideScene { t0: o.t0, first, last })?;
    // The planner inserts (the baselines and the LLM agents choose among the logged road users).
    let may_insert = o.adversary.is_none() && o.behavior.is_some() && matches!(agent, Agent::Planner);
    let plan_inserted = || match placed {
        Some(all) => insert::plan_placed(all, o),
        None => insert::plan_inserted(scene, o),
    };
    if may_insert && o.insert == insert::InsertMode::Always {
        return Ok(plan_inserted());
    }
    if let Err(reason) = constraints::check(scene, &world, o) {
        return Ok(Outcome::NoFeasible { reason });
    }
    let mut out = match agent {
        Agent::Planner => agents::run_planner(&world, o),
        Agent::Llm(b) => agents::run_llm(&world, o, b)?,
        Agent::Rule => baselines::rule_based(&world, o),
        Agent::Random => baselines::random(&world, o),
    };
    if let (Outcome::NoFeasible { reason }, true) = (&out, may_insert && o.insert == insert::InsertMode::Fallback) {
        out = match plan_inserted() {
            Outcome::NoFeasible { reason: why } => Outcome::NoFeasible { reason: format!("{reason}; {why}") },
            planned => planned,
        };
    }
    if let Outcome::Plan { plan, .. } = &out {
        debug_assert!(plan.validate().is_ok(), "agents must return valid plans: {:?}", plan.validate());
    }
    Ok(out)
}
