//! One case end to end: reason -> simulate -> measure over the evaluation window (`window`: one
//! horizon for every agent), then closed-loop refinement while the
//! executed trajectory misses the zone or MinTTC >= 1 s (up to `refine_rounds` times):
//! * planner: round 1 aims the target ahead of the observed end-point error (pre-compensation)
//!   and closes in harder (aimed TTC 0.3 s); later rounds take the next-ranked candidate;
//! * LLM agents: the Zone agent is asked again with the executed outcome (closest distance, where
//!   the adversary was relative to the ego, the zone it reached, MinTTC) in its prompt.
//!
//! The best round (physically valid, then zone hit, then success, then lower MinTTC) is the
//! refined result; round 0 is reported separately; an invalid rollout is never `good` (its
//! Success is false), so it is refined like a miss. Errors of any stage end the case as a
//! failure with its reason.

use crate::choose::Choice;
use crate::spec::{AgentName, CaseSpec};
use crate::window::{self, Horizon, Window};
use metrics::CaseMetrics;
use reason::backend::Backend;
use reason::constraints::search;
use reason::planner::trajectory_to_aim;
use reason::world::World;
use reason::{Agent, Outcome, ReasonOptions, ValidityStats};
use scene::glam::DVec2;
use scene::zones::zone_rect;
use scene::{Behavior, Executed, Plan, Scene, Zone};
use serde::{Deserialize, Serialize};
use sim::{RolloutConfig, SimError};
use std::collections::BTreeMap;

/// The physics stage as a function (tests substitute a failing one).
pub type SimulateFn = dyn Fn(&Scene, &Plan, &RolloutConfig) -> Result<Executed, SimError> + Sync + Send;

/// Refinement rounds a case runs at most (`--refine-rounds`): a budget on time; refinement
/// settles within a few rounds.
pub const MAX_REFINE_ROUNDS: usize = 100;

pub struct CaseConfig {
    pub reason: ReasonOptions,
    pub rollout: RolloutConfig,
    /// At most [`MAX_REFINE_ROUNDS`].
    pub refine_rounds: usize,
    pub simulate: Box<SimulateFn>,
    /// The window every plan is executed and measured over (one horizon for every agent).
    pub window: Window,
    /// What a `--describe` sentence was read as, by scene name: that scene's attempts use its
    /// behaviour only and its constraints where `reason` leaves them open.
    pub requests: BTreeMap<String, SceneRequest>,
    /// The planner agent chooses among its candidates by their rollouts (`choose`); off: its
    /// first-ranked candidate, as predicted.
    pub check_rollouts: bool,
}

/// A sentence's reading in one scene (`reason::intent`): the behaviour, and the adversary, zone
/// and TTC when it named them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SceneRequest {
    pub behavior: Behavior,
    pub adversary: Option<String>,
    pub zone: Option<Zone>,
    pub ttc_s: Option<f64>,
}

impl SceneRequest {
    pub fn of(i: &reason::intent::Intent) -> Self {
        SceneRequest { behavior: i.behavior, adversary: i.adversary.clone(), zone: i.zone, ttc_s: i.ttc_s }
    }
}

/// Executes `plan` over the window: cut or extended to the horizon, and cut again at a contact
/// with the ego (re-run up to the first control step at or after it; the prefix is identical,
/// the simulation being deterministic).
pub fn execute(scene: &Scene, plan: &Plan, cfg: &CaseConfig) -> Result<Executed, SimError> {
    let windowed = cfg.window.apply(scene, plan);
    let e = (cfg.simulate)(scene, &windowed, &cfg.rollout)?;
    let Some(c) = e.first_contact.as_ref().filter(|c| c.other == "ego") else { return Ok(e) };
    if cfg.window.horizon == Horizon::Plan {
        return Ok(e);
    }
    let (t0, dt) = (windowed.start_time_s, windowed.dt_s);
    let t_cut = t0 + ((c.t - t0) / dt - 1e-6).ceil().max(1.0) * dt;
    if t_cut >= windowed.end_time_s() - 1e-6 {
        return Ok(e);
    }
    (cfg.simulate)(scene, &window::cut(&windowed, t_cut), &cfg.rollout)
}

/// One executed attempt.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Round {
    pub plan: Plan,
    pub metrics: CaseMetrics,
    pub validity: Option<ValidityStats>,
    /// How this round's plan was made (`agent`, `rollout-checked: ...` for the checked planner,
    /// `pre-compensated target`, `next candidate`, `agent with feedback`).
    pub how: String,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "status")]
pub enum Status {
    Done {
        rounds: Vec<Round>,
        best: usize,
    },
    NoFeasible {
        reason: String,
    },
    Failed {
        stage: String,
        reason: String,
    },
    /// An LLM agent's reply stayed invalid after the re-prompts and no repair was asked
    /// (`--repair none`, the paper protocol's default): no plan; counted with the failures.
    Rejected {
        validity: ValidityStats,
        reason: String,
    },
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct CaseResult {
    pub spec: CaseSpec,
    #[serde(flatten)]
    pub status: Status,
}

impl CaseResult {
    pub fn first(&self) -> Option<&Round> {
        match &self.status {
            Status::Done { rounds, .. } => rounds.first(),
            _ => None,
        }
    }

    pub fn best(&self) -> Option<&Round> {
        match &self.status {
            Status::Done { rounds, best } => rounds.get(*best),
            _ => None,
        }
    }
}

fn good(m: &CaseMetrics) -> bool {
    m.zone_hit && m.success_center
}

/// Physically valid first, then zone hit, success, lower MinTTC.
fn rank(m: &CaseMetrics) -> (bool, bool, bool, f64) {
    (m.validity.valid, m.zone_hit, m.success_center, -m.min_ttc_center_s)
}

/// Total order on [`rank`] (a NaN MinTTC ranks as the worst, never panics).
pub(crate) fn cmp_rank(a: &CaseMetrics, b: &CaseMetrics) -> std::cmp::Ordering {
    let (ra, rb) = (rank(a), rank(b));
    let key = |x: f64| if x.is_nan() { f64::NEG_INFINITY } else { x };
    (ra.0, ra.1, ra.2).cmp(&(rb.0, rb.1, rb.2)).then(key(ra.3).total_cmp(&key(rb.3)))
}

/// The zone (if any) containing a point of the ego frame.
pub fn zone_of(local: DVec2, plan: &Plan, l: f64, w: f64) -> Option<Zone> {
    Zone::ALL.into_iter().find(|z| zone_rect(*z, plan.zone_layout, l, w).contains(local))
}

fn feedback(plan: &Plan, e: &Executed, m: &CaseMetrics) -> String {
    let [l, w, _] = e.ego.size_lwh;
    let local = DVec2::new(m.adversary_in_ego_frame[0], m.adversary_in_ego_frame[1]);
    let reached = zone_of(local, plan, l, w).map_or("no zone".to_string(), |z| format!("the {} zone", z.as_str()));
    format!(
        "vehicle {} aiming at the {} zone with TTC {:.1} s came closest to the ego ({:.1} m) at t0 + {:.1} s, at ({:.1}, {:.1}) m in the ego frame, i.e. in {reached}; the minimum time to collision was {:.2} s.",
        plan.adversary_track,
        plan.target_zone.as_str(),
        plan.ttc_s,
        m.min_distance_m,
        m.t_min_distance_s - plan.start_time_s,
        local.x,
        local.y,
        m.min_ttc_center_s
    )
}

/// Planner refinement strategies: 1 = pre-compensated target, k >= 2 = the k-th ranked candidate.
const MAX_PLANNER_STRATEGY: usize = 8;

/// The planner's refinement strategy `r` (1-based); `None` if it has nothing to offer.
pub(crate) fn refine_planner(
    scene: &Scene,
    o: &ReasonOptions,
    r: usize,
    last: &Plan,
    e: &Executed,
) -> Option<(Plan, String)> {
    // An inserted adversary is a candidate like a logged one in the scene it was inserted into.
    let scene = &*scene::inserted::with_inserted(scene, last).ok()?;
    // `--insert always`: the next candidates are the inserted car's own, never a logged car.
    let only_inserted = o.insert == reason::insert::InsertMode::Always && last.inserted.is_some();
    let adversary = if only_inserted { Some(last.adversary_track.clone()) } else { o.adversary.clone() };
    let o = &ReasonOptions { adversary, ..o.clone() };
    let world = World::for_options(scene, &ReasonOptions { t0: last.start_time_s, ..o.clone() })?;
    if r == 1 {
        let target = DVec2::from(last.target?);
        // Where the adversary was when its plan ended (the window may run on after it).
        let t_end = last.end_time_s();
        let end = e.steps.iter().min_by(|a, b| (a.t - t_end).abs().total_cmp(&(b.t - t_end).abs()))?;
        let aim = target + (target - DVec2::new(end.x, end.y));
        let v = world.vehicle(&last.adversary_track)?;
        let planned = trajectory_to_aim(&world, v, last.behavior, aim, last.ttc_s, o.dt, 0.3)?;
        let plan = Plan {
            waypoints: planned.waypoints,
            path: Some(planned.path),
            reasoning: format!("{} (refined: target pre-compensated by the executed end-point error)", last.reasoning),
            ..last.clone()
        };
        return Some((plan, "pre-compensated target".into()));
    }
    let ranked = search(&world, last.behavior, o).ok()?;
    let c = ranked.get(r - 1)?;
    let plan = Plan {
        adversary_track: c.vehicle_id.clone(),
        target_zone: c.zone,
        ttc_s: c.ttc_s,
        risk: c.risk(),
        waypoints: c.waypoints.clone(),
        target: Some([c.target.x, c.target.y]),
        path: Some(c.path),
        reasoning: format!("refined: candidate ranked {r} by the planner"),
        inserted: last.inserted.clone().filter(|_| c.vehicle_id == last.adversary_track),
        ..last.clone()
    };
    Some((plan, format!("candidate ranked {r}")))
}

fn reason_once(
    scene: &Scene,
    o: &ReasonOptions,
    agent: AgentName,
    backend: Option<&mut dyn Backend>,
    placed: Option<&[reason::insert::Placement]>,
) -> Result<Outcome, String> {
    let a = match (agent, backend) {
        (AgentName::Planner, _) => Agent::Planner,
        (AgentName::Rule, _) => Agent::Rule,
        (AgentName::Random, _) => Agent::Random,
        (_, Some(b)) => Agent::Llm(b),
        (_, None) => return Err(format!("agent {} needs a backend", agent.as_str())),
    };
    reason::reason_placed(scene, o, a, placed).map_err(|e| e.to_string())
}

/// Runs one case. `backend` is the LLM for LLM agents.
pub fn run_case(
    scene: &Scene,
    spec: &CaseSpec,
    cfg: &CaseConfig,
    mut backend: Option<&mut dyn Backend>,
) -> (CaseResult, Option<Executed>) {
    let mut o = ReasonOptions {
        t0: scene.frames[0].timestamp_s + spec.t0_s,
        behavior: Some(spec.behavior),
        seed: spec.seed,
        ..cfg.reason.clone()
    };
    if let Some(r) = cfg.requests.get(&scene.name) {
        // Explicit flags (already in `o`) win over the sentence.
        o.adversary = o.adversary.or_else(|| r.adversary.clone());
        o.zone = o.zone.or(r.zone);
        o.ttc_s = o.ttc_s.or(r.ttc_s);
    }
    let fail = |stage: &str, reason: String| {
        (CaseResult { spec: spec.clone(), status: Status::Failed { stage: stage.into(), reason } }, None)
    };
    // The planner's choice checked by rollouts, also where nothing at t0 itself was feasible
    // (a later start time or the wider search may be). It searches the agent's candidates (and
    // insertions) itself, so the agent runs alone only where it chose nothing: for the reason
    // why, or the unchecked plan.
    let planner_checked = spec.agent == AgentName::Planner && cfg.check_rollouts;
    if planner_checked {
        if let Err(e) = reason::budget::check(scene, &o) {
            return fail("reason", e.to_string());
        }
    }
    let checked = if planner_checked {
        match crate::choose::choose(scene, &o, cfg) {
            Ok(Choice::Chosen(c)) => Ok((c.plan, None, c.how)),
            Ok(Choice::Refused(reason)) => {
                return (CaseResult { spec: spec.clone(), status: Status::NoFeasible { reason } }, None)
            }
            Ok(Choice::NoCandidate(placed)) => Err(placed),
            Err(e) => return fail("simulate", format!("checking the planner's candidates: {e}")),
        }
    } else {
        Err(None)
    };
    let (mut plan, mut validity, mut how) = match checked {
        Ok(c) => c,
        Err(placed) => match reason_once(
            scene,
            &o,
            spec.agent,
            backend.as_mut().map(|b| &mut **b as &mut dyn Backend),
            placed.as_deref(),
        ) {
            Err(e) => return fail("reason", e),
            Ok(Outcome::Rejected { stats, reason }) => {
                return (CaseResult { spec: spec.clone(), status: Status::Rejected { validity: stats, reason } }, None)
            }
            Ok(Outcome::NoFeasible { reason }) => {
                return (CaseResult { spec: spec.clone(), status: Status::NoFeasible { reason } }, None)
            }
            Ok(Outcome::Plan { plan, stats }) => (plan, stats, "agent".to_string()),
        },
    };
    let mut strategy = 1; // the planner's next refinement strategy
    let mut rounds: Vec<Round> = Vec::new();
    let mut best_exec: Option<Executed> = None;
    for r in 0..=cfg.refine_rounds {
        let executed = match execute(scene, &plan, cfg) {
            Ok(e) => e,
            Err(e) => return fail("simulate", format!("round {r}: {e}")),
        };
        let m = match metrics::evaluate(&executed) {
            Ok(m) => m,
            Err(e) => return fail("metrics", format!("round {r}: {e}")),
        };
        let improved = rounds.iter().all(|x| cmp_rank(&m, &x.metrics).is_gt());
        let done = good(&m);
        let next = (!done && spec.agent.refines() && r < cfg.refine_rounds)
            .then(|| (feedback(&plan, &executed, &m), plan.clone()));
        rounds.push(Round { plan: plan.clone(), metrics: m, validity: validity.clone(), how: how.clone() });
        if improved {
            best_exec = Some(executed.clone());
        }
        let Some((fb, last)) = next else { break };
        // Next round's plan: the next strategy that yields one.
        let refined = if spec.agent.is_llm() {
            let o2 = ReasonOptions { feedback: Some(fb), seed: spec.seed.wrapping_add(r as u64 + 1), ..o.clone() };
            match reason_once(scene, &o2, spec.agent, backend.as_mut().map(|b| &mut **b as &mut dyn Backend), None) {
                Ok(Outcome::Plan { plan, stats }) => Some((plan, stats, "agent with feedback".to_string())),
                Ok(Outcome::NoFeasible { .. } | Outcome::Rejected { .. }) => None,
                Err(e) => return fail("reason", format!("refinement round {}: {e}", r + 1)),
            }
        } else {
            let tried: Vec<&Plan> = rounds.iter().map(|x| &x.plan).collect();
            (strategy..=MAX_PLANNER_STRATEGY).find_map(|k| {
                strategy = k + 1;
                refine_planner(scene, &o, k, &last, &executed)
                    .filter(|(p, _)| !tried.contains(&p))
                    .map(|(p, h)| (p, None, h))
            })
        };
        match refined {
            Some((p, v, h)) => {
                plan = p;
                validity = v;
                how = h;
            }
            None => break,
        }
    }
    let best =
        (0..rounds.len()).max_by(|a, b| cmp_rank(&rounds[*a].metrics, &rounds[*b].metrics).then(b.cmp(a))).unwrap_or(0);
    (CaseResult { spec: spec.clone(), status: Status::Done { rounds, best } }, best_exec)
}
