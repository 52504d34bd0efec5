//! The paper's tables from case results. Every agent runs the same attempts (`spec`) over the same
//! window (`window`), so every per-attempt column has the same denominator for every agent.
//! * Table I (controllability): per agent, one row `as planned` (round 0) and, for agents that
//!   refine, one row `+ refine` (the best round of closed-loop refinement, with the refinement
//!   rounds it used). Per-attempt columns count over **all** attempts: planned, no feasible,
//!   failed, and Zone Hit, Success and *verified* (Zone Hit and Success and a valid rollout) as
//!   k/N. Then, per executed rollout: validity in all and per reason, and Zone Hit, Success and
//!   MinTTC as mean +- std (population std, like numpy) with centre-TTC and box-TTC variants.
//! * The paired comparison and the reasons for no plan: [`crate::paired`].
//! * Table II (comfort): per agent, |a_lat|95, |kappa_dot|95 and ComfortViol of the raw waypoints
//!   vs the physically executed trajectory (round 0), both over the evaluation window (the plan
//!   as executed, continued or cut to the horizon).
//! * Physical validity of the rollouts (both tables): how many executed cases are invalid and
//!   how many for each reason (`tracking_diverged`, `friction_limit`, `contact_with_other`,
//!   `left_road`; a case can have several). Invalid cases stay in every denominator and count
//!   as not successful (the metrics already fold validity into Success).
//! * Validity of LLM replies (raw-valid, valid after retry, repaired), case counts, failures.

use crate::result::{CaseResult, Round, Status};
use crate::spec::AgentName;
use reason::Validity;
use scene::executed::InvalidReason;
use serde::{Deserialize, Serialize};
use std::fmt::Write;

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Stat {
    pub mean: f64,
    pub std: f64,
    pub n: usize,
}

pub fn stat(v: &[f64]) -> Option<Stat> {
    if v.is_empty() {
        return None;
    }
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let var = v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    Some(Stat { mean, std: var.sqrt(), n: v.len() })
}

fn fmt(s: &Option<Stat>, digits: usize) -> String {
    s.map_or("-".into(), |s| format!("{:.*} ± {:.*}", digits, s.mean, digits, s.std))
}

/// Invalid executed cases, in all and per reason (a case can have several reasons).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct InvalidCounts {
    pub invalid: usize,
    pub tracking_diverged: usize,
    pub friction_limit: usize,
    pub contact_with_other: usize,
    pub left_road: usize,
}

impl InvalidCounts {
    pub fn of(rounds: &[&Round]) -> Self {
        let mut c = InvalidCounts::default();
        for r in rounds {
            let v = &r.metrics.validity;
            c.invalid += usize::from(!v.valid);
            for reason in &v.reasons {
                match reason {
                    InvalidReason::TrackingDiverged { .. } => c.tracking_diverged += 1,
                    InvalidReason::FrictionLimit { .. } => c.friction_limit += 1,
                    InvalidReason::ContactWithOther { .. } => c.contact_with_other += 1,
                    InvalidReason::LeftRoad { .. } => c.left_road += 1,
                }
            }
        }
        c
    }

    fn cells(&self) -> String {
        format!(
            "{} | {} | {} | {} | {}",
            self.invalid, self.tracking_diverged, self.friction_limit, self.contact_with_other, self.left_road
        )
    }

    fn csv(&self) -> String {
        format!(
            "{},{},{},{},{}",
            self.invalid, self.tracking_diverged, self.friction_limit, self.contact_with_other, self.left_road
        )
    }
}

const INVALID_MD_HEADER: &str = "invalid | diverged | friction limit | contact with other | left road";
const INVALID_CSV_HEADER: &str = "invalid,tracking_diverged,friction_limit,contact_with_other,left_road";

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Table1Row {
    pub agent: AgentName,
    /// `as planned` (round 0) or `+ refine` (best round).
    pub variant: String,
    /// Attempts given to the agent (the same for every agent).
    pub attempts: usize,
    /// Attempts that produced a plan (and a rollout).
    pub planned: usize,
    pub no_feasible: usize,
    /// A stage returned an error (agent, simulation or metrics).
    pub failed: usize,
    /// Rollouts executed (`+ refine`: over every round).
    pub rollouts: usize,
    /// Refinement rounds used beyond the first plan (`+ refine` rows only).
    pub refine_rounds_used: Option<usize>,
    /// Measured cases (one rollout per planned attempt): the per-rollout columns' denominator.
    pub cases: usize,
    pub valid: usize,
    pub validity: InvalidCounts,
    /// Over all attempts: Zone Hit, Success, and verified (Zone Hit and Success, valid rollout).
    pub zone_hit_k: usize,
    pub success_k: usize,
    pub verified_k: usize,
    pub zone_hit: Option<Stat>,
    pub zone_hit_paper_axes: Option<Stat>,
    pub success_center: Option<Stat>,
    pub min_ttc_center_s: Option<Stat>,
    pub success_box: Option<Stat>,
    pub min_ttc_box_s: Option<Stat>,
}

/// A verified corner case: Zone Hit and Success (centre TTC < 1 s) on a physically valid rollout.
pub fn verified(m: &metrics::CaseMetrics) -> bool {
    m.validity.valid && m.zone_hit && m.success_center
}

/// `k/N (rate)`.
pub fn frac(k: usize, n: usize) -> String {
    if n == 0 {
        format!("{k}/0")
    } else {
        format!("{k}/{n} ({:.3})", k as f64 / n as f64)
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Table2Row {
    pub agent: AgentName,
    pub cases: usize,
    pub validity: InvalidCounts,
    pub a_lat_p95_raw: Option<Stat>,
    pub a_lat_p95_executed: Option<Stat>,
    pub kappa_dot_p95_raw: Option<Stat>,
    pub kappa_dot_p95_executed: Option<Stat>,
    pub comfort_viol_raw: Option<Stat>,
    pub comfort_viol_executed: Option<Stat>,
    /// First plans that follow the map's lanes (`Plan::path`), for agents whose plans say.
    pub lane_following: Option<usize>,
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct ValidityRow {
    pub agent: Option<AgentName>,
    /// raw-valid, valid after retry, repaired
    pub zone: [usize; 3],
    pub trajectory: [usize; 3],
}

fn b(x: bool) -> f64 {
    if x {
        1.0
    } else {
        0.0
    }
}

fn row1(
    agent: AgentName,
    variant: &str,
    results: &[&CaseResult],
    pick: impl Fn(&CaseResult) -> Option<&Round>,
    refine: bool,
    split: bool,
) -> Table1Row {
    let rounds: Vec<&Round> = results.iter().filter_map(|r| pick(r)).collect();
    let col = |f: &dyn Fn(&Round) -> f64| stat(&rounds.iter().map(|r| f(r)).collect::<Vec<_>>());
    let count = |f: &dyn Fn(&Round) -> bool| rounds.iter().filter(|r| f(r)).count();
    let all_rounds: usize = results
        .iter()
        .filter(|r| !split || pick(r).is_some())
        .map(|r| match &r.status {
            Status::Done { rounds, .. } => rounds.len(),
            _ => 0,
        })
        .sum();
    let planned =
        if split { rounds.len() } else { results.iter().filter(|r| matches!(r.status, Status::Done { .. })).count() };
    Table1Row {
        agent,
        variant: variant.into(),
        attempts: results.len(),
        planned,
        no_feasible: results.iter().filter(|r| matches!(r.status, Status::NoFeasible { .. })).count(),
        failed: results.iter().filter(|r| matches!(r.status, Status::Failed { .. } | Status::Rejected { .. })).count(),
        rollouts: if refine { all_rounds } else { rounds.len() },
        refine_rounds_used: refine.then(|| all_rounds - planned),
        cases: rounds.len(),
        valid: count(&|r| r.metrics.validity.valid),
        validity: InvalidCounts::of(&rounds),
        zone_hit_k: count(&|r| r.metrics.zone_hit),
        success_k: count(&|r| r.metrics.success_center),
        verified_k: count(&|r| verified(&r.metrics)),
        zone_hit: col(&|r| b(r.metrics.zone_hit)),
        zone_hit_paper_axes: col(&|r| b(r.metrics.zone_hit_paper_axes)),
        success_center: col(&|r| b(r.metrics.success_center)),
        min_ttc_center_s: col(&|r| r.metrics.min_ttc_center_s),
        success_box: col(&|r| b(r.metrics.success_box)),
        min_ttc_box_s: col(&|r| r.metrics.min_ttc_box_s),
    }
}

pub const AS_PLANNED: &str = "as planned";
pub const REFINED: &str = "+ refine";

/// Suffixes of the rows that split an agent's planned attempts by adversary: logged road users
/// and inserted ones ([`reason::insert`]); written only where some plan has an inserted one.
/// These rows keep every attempt in their `attempts` (and in the `/ attempts` columns); their
/// `planned` counts the attempts whose case has that kind of adversary, and their per-rollout
/// columns are over those cases only. `no feasible` and `failed` are the agent's.
pub const LOGGED_ROWS: &str = ", logged adversaries";
pub const INSERTED_ROWS: &str = ", inserted adversaries";

pub fn table1(results: &[CaseResult], agents: &[AgentName]) -> Vec<Table1Row> {
    let mut rows = Vec::new();
    for a in agents {
        let mine: Vec<&CaseResult> = results.iter().filter(|r| r.spec.agent == *a).collect();
        rows.push(row1(*a, AS_PLANNED, &mine, |r| r.first(), false, false));
        if a.refines() {
            rows.push(row1(*a, REFINED, &mine, |r| r.best(), true, false));
        }
        let inserted = |r: &Round| r.plan.inserted.is_some();
        if mine.iter().any(|r| r.first().is_some_and(inserted) || r.best().is_some_and(inserted)) {
            for (suffix, want) in [(LOGGED_ROWS, false), (INSERTED_ROWS, true)] {
                let variant = format!("{AS_PLANNED}{suffix}");
                rows.push(row1(*a, &variant, &mine, |r| r.first().filter(|x| inserted(x) == want), false, true));
                if a.refines() {
                    let variant = format!("{REFINED}{suffix}");
                    rows.push(row1(*a, &variant, &mine, |r| r.best().filter(|x| inserted(x) == want), true, true));
                }
            }
        }
    }
    rows
}

pub fn table2(results: &[CaseResult], agents: &[AgentName]) -> Vec<Table2Row> {
    agents
        .iter()
        .map(|a| {
            let rounds: Vec<&Round> = results.iter().filter(|r| r.spec.agent == *a).filter_map(|r| r.first()).collect();
            let col = |f: &dyn Fn(&Round) -> Option<f64>| stat(&rounds.iter().filter_map(|r| f(r)).collect::<Vec<_>>());
            Table2Row {
                agent: *a,
                cases: rounds.len(),
                validity: InvalidCounts::of(&rounds),
                a_lat_p95_raw: col(&|r| r.metrics.comfort_reference.map(|c| c.a_lat_p95)),
                a_lat_p95_executed: col(&|r| r.metrics.comfort_executed.map(|c| c.a_lat_p95)),
                kappa_dot_p95_raw: col(&|r| r.metrics.comfort_reference.map(|c| c.kappa_dot_p95)),
                kappa_dot_p95_executed: col(&|r| r.metrics.comfort_executed.map(|c| c.kappa_dot_p95)),
                comfort_viol_raw: col(&|r| r.metrics.comfort_reference.map(|c| c.comfort_viol_pct)),
                comfort_viol_executed: col(&|r| r.metrics.comfort_executed.map(|c| c.comfort_viol_pct)),
                lane_following: rounds
                    .iter()
                    .any(|r| r.plan.path.is_some())
                    .then(|| rounds.iter().filter(|r| r.plan.path == Some(scene::PlanPath::LaneFollowing)).count()),
            }
        })
        .collect()
}

fn slot(v: &Validity) -> usize {
    match v {
        Validity::RawValid => 0,
        Validity::ValidAfterRetry { .. } => 1,
        // `Invalid` is only in rejected cases (no round): see `llm_validity`.
        Validity::Repaired { .. } | Validity::Invalid { .. } => 2,
    }
}

/// Validity of every LLM reply chain (first attempts and refinement rounds), per agent.
pub fn validity(results: &[CaseResult], agents: &[AgentName]) -> Vec<ValidityRow> {
    agents
        .iter()
        .filter(|a| a.is_llm())
        .map(|a| {
            let mut row = ValidityRow { agent: Some(*a), ..Default::default() };
            for r in results.iter().filter(|r| r.spec.agent == *a) {
                if let Status::Done { rounds, .. } = &r.status {
                    for v in rounds.iter().filter_map(|x| x.validity.as_ref()) {
                        row.zone[slot(&v.zone)] += 1;
                        row.trajectory[slot(&v.trajectory)] += 1;
                    }
                }
            }
            row
        })
        .collect()
}

pub fn table1_markdown(rows: &[Table1Row]) -> String {
    let mut s = format!("| agent | variant | attempts | planned | no feasible | failed | rollouts | refine rounds | Zone Hit / attempts | Success / attempts | verified / attempts | valid | {INVALID_MD_HEADER} | Zone Hit per rollout | Success (centre TTC < 1 s) per rollout | MinTTC centre (s) | Success (box TTC < 1 s) per rollout | MinTTC box (s) | Zone Hit, paper axes |\n|{}\n", "---|".repeat(23));
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.agent.as_str(),
            r.variant,
            r.attempts,
            r.planned,
            r.no_feasible,
            r.failed,
            r.rollouts,
            r.refine_rounds_used.map_or("-".into(), |n| n.to_string()),
            frac(r.zone_hit_k, r.attempts),
            frac(r.success_k, r.attempts),
            frac(r.verified_k, r.attempts),
            r.valid,
            r.validity.cells(),
            fmt(&r.zone_hit, 3),
            fmt(&r.success_center, 3),
            fmt(&r.min_ttc_center_s, 3),
            fmt(&r.success_box, 3),
            fmt(&r.min_ttc_box_s, 3),
            fmt(&r.zone_hit_paper_axes, 3)
        );
    }
    s
}

fn frac_plain(k: usize, n: usize) -> String {
    format!("{k}/{n}")
}

pub fn table2_markdown(rows: &[Table2Row]) -> String {
    let mut s = format!("| agent | cases | {INVALID_MD_HEADER} | \\|a_lat\\|95 raw (m/s²) | \\|a_lat\\|95 executed | \\|κ̇\\|95 raw (1/(m s)) | \\|κ̇\\|95 executed | ComfortViol raw (%) | ComfortViol executed | lane-following plans |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.agent.as_str(),
            r.cases,
            r.validity.cells(),
            fmt(&r.a_lat_p95_raw, 2),
            fmt(&r.a_lat_p95_executed, 2),
            fmt(&r.kappa_dot_p95_raw, 3),
            fmt(&r.kappa_dot_p95_executed, 3),
            fmt(&r.comfort_viol_raw, 2),
            fmt(&r.comfort_viol_executed, 2),
            r.lane_following.map_or("-".to_string(), |k| frac_plain(k, r.cases))
        );
    }
    s
}

fn csv_stat(s: &Option<Stat>) -> String {
    s.map_or(",".into(), |s| format!("{},{}", s.mean, s.std))
}

pub fn table1_csv(rows: &[Table1Row]) -> String {
    let mut s = format!("agent,variant,attempts,planned,no_feasible,failed,rollouts,refine_rounds_used,zone_hit_k,success_k,verified_k,valid,{INVALID_CSV_HEADER},zone_hit_mean,zone_hit_std,success_center_mean,success_center_std,min_ttc_center_mean,min_ttc_center_std,success_box_mean,success_box_std,min_ttc_box_mean,min_ttc_box_std,zone_hit_paper_axes_mean,zone_hit_paper_axes_std\n");
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.agent.as_str(),
            r.variant,
            r.attempts,
            r.planned,
            r.no_feasible,
            r.failed,
            r.rollouts,
            r.refine_rounds_used.map_or(String::new(), |n| n.to_string()),
            r.zone_hit_k,
            r.success_k,
            r.verified_k,
            r.valid,
            r.validity.csv(),
            csv_stat(&r.zone_hit),
            csv_stat(&r.success_center),
            csv_stat(&r.min_ttc_center_s),
            csv_stat(&r.success_box),
            csv_stat(&r.min_ttc_box_s),
            csv_stat(&r.zone_hit_paper_axes)
        );
    }
    s
}

pub fn table2_csv(rows: &[Table2Row]) -> String {
    let mut s = format!("agent,cases,{INVALID_CSV_HEADER},a_lat_p95_raw_mean,a_lat_p95_raw_std,a_lat_p95_executed_mean,a_lat_p95_executed_std,kappa_dot_p95_raw_mean,kappa_dot_p95_raw_std,kappa_dot_p95_executed_mean,kappa_dot_p95_executed_std,comfort_viol_raw_mean,comfort_viol_raw_std,comfort_viol_executed_mean,comfort_viol_executed_std,lane_following\n");
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{}",
            r.agent.as_str(),
            r.cases,
            r.validity.csv(),
            csv_stat(&r.a_lat_p95_raw),
            csv_stat(&r.a_lat_p95_executed),
            csv_stat(&r.kappa_dot_p95_raw),
            csv_stat(&r.kappa_dot_p95_executed),
            csv_stat(&r.comfort_viol_raw),
            csv_stat(&r.comfort_viol_executed),
            r.lane_following.map_or(String::new(), |k| k.to_string())
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn population_std_like_numpy() {
        // numpy.std([0, 1, 1, 1]) = 0.4330127...
        let s = stat(&[0.0, 1.0, 1.0, 1.0]).unwrap();
        assert!((s.mean - 0.75).abs() < 1e-12 && (s.std - 0.4330127018922193).abs() < 1e-12);
        assert!(stat(&[]).is_none());
    }
}
