//! The planner's choice, checked by rollouts. The planner ranks its candidates by what it
//! predicts from the logged motion (centre MinTTC, zone, a clear path past the logged road
//! users), but only the executed rollout says whether the tracked adversary touches a third road
//! user, leaves the road or slides past the friction limit. The simulator is cheap (hundreds of
//! rollouts a second), so the planner agent's case takes the first candidate, in the planner's
//! order, whose rollout over the case's window is physically valid, hits its zone and succeeds;
//! it tries at most [`MAX_ROLLOUTS`] candidates an attempt, and where none at the attempt's t0
//! succeeds, the same search from later start times within the attempt ([`START_OFFSETS_S`]).
//! Failing that it keeps the best rollout seen (valid first, then zone hit, success, lower
//! MinTTC), so a candidate that touches a bystander is never handed over when another would not.
//! Every rollout tried is counted in the case's `how`.

use crate::runner::{cmp_rank, execute, CaseConfig};
use crate::tables::verified;
use metrics::CaseMetrics;
use reason::agents::{plan_of_candidate, ranked_candidates};
use reason::world::World;
use reason::ReasonOptions;
use scene::{Plan, Scene};

/// Rollouts tried at most for one attempt (over every start time).
pub const MAX_ROLLOUTS: usize = 48;
/// Start times tried after the attempt's t0 (s) when no candidate at t0 succeeds.
pub const START_OFFSETS_S: [f64; 4] = [0.0, 0.5, 1.0, 1.5];

/// A checked choice: the plan, its rollout's metrics, and how it was found.
pub struct Checked {
    pub plan: Plan,
    pub metrics: CaseMetrics,
    pub how: String,
}

/// The rollout-checked choice for options `o` (the attempt's t0, behaviour and constraints), or
/// `None` when no start time yields a candidate. A failing rollout stage is an error naming it.
pub fn choose(scene: &Scene, o: &ReasonOptions, cfg: &CaseConfig) -> Result<Option<Checked>, String> {
    let mut best: Option<(Checked, usize, f64)> = None;
    let mut tried = 0;
    for off in START_OFFSETS_S {
        let o2 = ReasonOptions { t0: o.t0 + off, ..o.clone() };
        let Some(world) = World::for_options(scene, &o2) else { break };
        let Ok(ranked) = ranked_candidates(&world, &o2) else { continue };
        let budget = MAX_ROLLOUTS.saturating_sub(tried);
        for (rank, c) in ranked.iter().take(budget).enumerate() {
            tried += 1;
            let plan = plan_of_candidate(&world, &o2, c);
            let executed = execute(scene, &plan, cfg).map_err(|e| format!("simulate: {e}"))?;
            let metrics = metrics::evaluate(&executed).map_err(|e| format!("metrics: {e}"))?;
            let done = verified(&metrics);
            if best.as_ref().is_none_or(|(b, _, _)| cmp_rank(&metrics, &b.metrics).is_gt()) {
                best = Some((Checked { plan, metrics, how: String::new() }, rank + 1, off));
            }
            if done {
                break;
            }
        }
        if tried >= MAX_ROLLOUTS || best.as_ref().is_some_and(|(b, _, _)| verified(&b.metrics)) {
            break;
        }
    }
    Ok(best.map(|(mut b, rank, off)| {
        let verdict = if verified(&b.metrics) {
            "the first valid with zone hit and success"
        } else {
            "the best, none valid with zone hit and success"
        };
        b.how = format!("rollout-checked: candidate ranked {rank} at t0 + {off:.1} s, {verdict} of {tried} rollouts");
        b
    }))
}
