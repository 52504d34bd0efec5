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

pub use crate::case_config::{execute, CaseConfig, SceneRequest, SimulateFn, MAX_REFINE_ROUNDS};
pub use crate::refine::zone_of;
pub use crate::result::{CaseResult, Round, Status};

use crate::choose::Choice;
use crate::refine::{feedback, refine_planner, MAX_PLANNER_STRATEGY};
use crate::result::{cmp_rank, good};
use crate::spec::{AgentName, CaseSpec};
use reason::backend::Backend;
use reason::{Agent, Outcome, ReasonOptions};
use scene::{Executed, Plan, Scene};

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
