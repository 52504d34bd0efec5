//! The stress bench's table (issue 27) from the harness's per-case results, per behaviour, per
//! corpus subset and in total, for every agent and variant (`as planned`, `+ refine`): attempts,
//! planned, invalid rollouts with counts per reason, Zone Hit and Success per rollout, verified
//! (Zone Hit + Success + valid) per attempt, (scene, t0) pairs with at least one verified case,
//! why no plan, and for sudden cut-in the plan rate over the attempts where an adjacent-lane
//! vehicle exists ([`adjacent_lane_vehicle`]). Every number comes from [`crate::tables`] and
//! [`crate::paired`] over a subset of the cases, so no attempt leaves a denominator.

use crate::result::{CaseResult, Status};
use crate::spec::AgentName;
use crate::tables::{self, InvalidCounts};
use crate::{paired, Report};
use reason::behavior::{class_can, Relation};
use reason::world::World;
use reason::ReasonOptions;
use scene::{Behavior, Scene};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;

/// One row of the bench table.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BenchRow {
    /// A behaviour, a corpus subset, or `total`.
    pub label: String,
    pub agent: AgentName,
    pub variant: String,
    pub attempts: usize,
    pub planned: usize,
    pub no_plan: usize,
    pub failed: usize,
    /// Measured rollouts (one per planned attempt): the per-rollout denominator.
    pub rollouts: usize,
    pub invalid: InvalidCounts,
    pub zone_hit_per_rollout: Option<f64>,
    pub success_per_rollout: Option<f64>,
    /// Attempts whose rollout is verified (Zone Hit + Success + valid).
    pub verified: usize,
    /// (scene, t0) pairs among the row's attempts, and those with at least one verified case.
    pub pairs: usize,
    pub pairs_verified: usize,
    /// Why attempts have no rollout: (class, count); failures included.
    pub why_no_plan: Vec<(String, usize)>,
}

/// Sudden cut-in where an adjacent-lane vehicle exists.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct CutInAdjacent {
    pub agent: Option<AgentName>,
    /// Sudden cut-in attempts in all, with an adjacent-lane vehicle, and of those planned.
    pub attempts: usize,
    pub with_adjacent: usize,
    pub planned_with_adjacent: usize,
    /// Attempts with a vehicle the behaviour's own gate accepts (adjacent lane, not behind).
    pub positioned: usize,
    pub planned_positioned: usize,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BenchReport {
    pub seed: u64,
    pub t0: String,
    /// The corpus's scenes in harness order.
    pub scenes: Vec<SceneLabel>,
    pub attempts: usize,
    pub by_behavior: Vec<BenchRow>,
    /// Per perturbation (`log`, `noise`, ...) over every source.
    pub by_subset: Vec<BenchRow>,
    /// Per log source (`womd`, `pandaset`, `kitti`) over every perturbation.
    pub by_source: Vec<BenchRow>,
    pub cut_in: Vec<CutInAdjacent>,
    pub timing: Vec<crate::AgentTiming>,
    /// Wall time of the whole bench: corpus assembly plus every agent's cases (s).
    pub bench_wall_s: f64,
    pub corpus_wall_s: f64,
    /// Perturbed copies that could not be made (scene, perturbation: why); not in the corpus.
    #[serde(default)]
    pub skipped_copies: Vec<String>,
}

/// Whether a vehicle (or cyclist, who can also cut in) is in a lane adjacent to the ego's at
/// `t0` (scene clock): in the world the planner sees (`reason::world::World` at `t0` within
/// `o.radius`, the ego's own track left out), with `reason::behavior::Relation`'s lane logic:
/// its lateral offset in the ego frame rounds to one lane (`LANE_WIDTH` 3.6 m) to either side and
/// it heads the ego's way (within 45 degrees), wherever it is along the ego (ahead, beside or
/// behind). The second value: such a vehicle also passes the cut-in's own gate (not behind the
/// ego's rear axle position, `reason::behavior::candidate_zones`).
pub fn adjacent_lane_vehicle(scene: &Scene, t0: f64, o: &ReasonOptions) -> (bool, bool) {
    let Some(w) = World::new(scene, t0, o.radius) else { return (false, false) };
    let adjacent: Vec<_> = w
        .actors()
        .filter(|v| class_can(v.class, Behavior::SuddenCutIn))
        .filter(|v| {
            let r = Relation::of(&w, v);
            r.lane.abs() == 1 && r.same_direction()
        })
        .collect();
    let positioned = adjacent.iter().any(|v| reason::behavior::candidate_zones(&w, v, Behavior::SuddenCutIn).is_ok());
    (!adjacent.is_empty(), positioned)
}

fn rows_for(label: &str, cases: &[&CaseResult], agents: &[AgentName]) -> Vec<BenchRow> {
    let owned: Vec<CaseResult> = cases.iter().map(|c| (*c).clone()).collect();
    let t1 = tables::table1(&owned, agents);
    let why = paired::why_no_plan(&owned, agents);
    t1.iter()
        .map(|r| {
            let ai = agents.iter().position(|a| *a == r.agent).unwrap_or(0);
            let mine: Vec<&CaseResult> = cases.iter().copied().filter(|c| c.spec.agent == r.agent).collect();
            // The split rows (`..., logged adversaries`) count only cases with that kind of adversary.
            let kind = if r.variant.ends_with(tables::LOGGED_ROWS) {
                Some(false)
            } else if r.variant.ends_with(tables::INSERTED_ROWS) {
                Some(true)
            } else {
                None
            };
            let any = |c: &CaseResult| {
                if r.variant.starts_with(tables::REFINED) {
                    c.best().cloned()
                } else {
                    c.first().cloned()
                }
            };
            let pick = |c: &CaseResult| any(c).filter(|x| kind.is_none_or(|k| x.plan.inserted.is_some() == k));
            // Attempts planned with the other kind of adversary have no plan in this row: say so.
            let other = kind.map(|k| {
                let n = mine.iter().filter(|c| any(c).is_some_and(|x| x.plan.inserted.is_some() != k)).count();
                let what = if k { "planned with a logged adversary" } else { "planned with an inserted adversary" };
                (what.to_string(), n)
            });
            let pair = |c: &CaseResult| (c.spec.scene.clone(), format!("{:.3}", c.spec.t0_s));
            let pairs: BTreeSet<_> = mine.iter().map(|c| pair(c)).collect();
            let good: BTreeSet<_> = mine
                .iter()
                .filter(|c| pick(c).is_some_and(|x| tables::verified(&x.metrics)))
                .map(|c| pair(c))
                .collect();
            BenchRow {
                label: label.to_string(),
                agent: r.agent,
                variant: r.variant.clone(),
                attempts: r.attempts,
                planned: r.planned,
                no_plan: r.attempts - r.planned,
                failed: r.failed,
                rollouts: r.cases,
                invalid: r.validity,
                zone_hit_per_rollout: r.zone_hit.map(|s| s.mean),
                success_per_rollout: r.success_center.map(|s| s.mean),
                verified: r.verified_k,
                pairs: pairs.len(),
                pairs_verified: good.len(),
                why_no_plan: why.iter().map(|(c, n)| (c.clone(), n[ai])).chain(other).filter(|(_, n)| *n > 0).collect(),
            }
        })
        .collect()
}

/// Where a corpus scene comes from: its log source (`womd`, `pandaset`, `kitti`) and its
/// perturbation (`log` for the unperturbed scene).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct SceneLabel {
    pub name: String,
    pub source: String,
    pub perturbation: String,
}

/// The bench report of a harness run over `scenes` (`labels[i]` describes scene `i`);
/// `opts` are the reason options the run used (for the adjacent-lane check).
pub fn bench_report(
    report: &Report,
    scenes: &[Scene],
    labels: &[SceneLabel],
    opts: &ReasonOptions,
    t0: &str,
    corpus_wall_s: f64,
) -> BenchReport {
    let agents = &report.agents;
    let all: Vec<&CaseResult> = report.cases.iter().collect();
    let behaviours: Vec<Behavior> =
        Behavior::EVERY.into_iter().filter(|b| all.iter().any(|c| c.spec.behavior == *b)).collect();
    let mut by_behavior = Vec::new();
    for b in &behaviours {
        let sub: Vec<&CaseResult> = all.iter().copied().filter(|c| c.spec.behavior == *b).collect();
        by_behavior.extend(rows_for(b.as_str(), &sub, agents));
    }
    by_behavior.extend(rows_for("total", &all, agents));
    let group = |key: &dyn Fn(&SceneLabel) -> &str| -> Vec<BenchRow> {
        let key_of = |c: &CaseResult| labels.get(c.spec.scene_index).map_or("", key);
        let mut names: Vec<&str> = Vec::new();
        for l in labels {
            if !names.contains(&key(l)) {
                names.push(key(l));
            }
        }
        names
            .into_iter()
            .flat_map(|n| {
                let sub: Vec<&CaseResult> = all.iter().copied().filter(|c| key_of(c) == n).collect();
                rows_for(n, &sub, agents)
            })
            .collect()
    };
    let by_subset = group(&|l| l.perturbation.as_str());
    let by_source = group(&|l| l.source.as_str());
    let cut_in = agents
        .iter()
        .map(|a| {
            let mut c = CutInAdjacent { agent: Some(*a), ..Default::default() };
            for r in all.iter().filter(|r| r.spec.agent == *a && r.spec.behavior == Behavior::SuddenCutIn) {
                let Some(s) = scenes.get(r.spec.scene_index) else { continue };
                let t0 = s.frames.first().map_or(0.0, |f| f.timestamp_s) + r.spec.t0_s;
                let (adjacent, positioned) = adjacent_lane_vehicle(s, t0, opts);
                let planned = matches!(r.status, Status::Done { .. });
                c.attempts += 1;
                c.with_adjacent += usize::from(adjacent);
                c.planned_with_adjacent += usize::from(adjacent && planned);
                c.positioned += usize::from(positioned);
                c.planned_positioned += usize::from(positioned && planned);
            }
            c
        })
        .collect();
    BenchReport {
        seed: report.seed,
        t0: t0.to_string(),
        scenes: labels.to_vec(),
        attempts: report.attempts,
        by_behavior,
        by_subset,
        by_source,
        cut_in,
        timing: report.timing.clone(),
        bench_wall_s: corpus_wall_s + report.timing.iter().map(|t| t.wall_s).sum::<f64>(),
        corpus_wall_s,
        skipped_copies: Vec::new(),
    }
}
