//! Tables that make the agents comparable attempt by attempt.
//! * Paired comparison (`table1_paired.{md,csv}`): only the attempts that **every** agent planned
//!   (same scene, behaviour, t0, horizon), per agent and variant: Zone Hit, Success and verified
//!   as k/n, MinTTC, and against the first row (the reference, normally the planner as planned)
//!   the discordant pairs on *verified* (this row only / reference only) with the exact two-sided
//!   sign test (McNemar's exact test) p-value. Per-agent rates over different subsets hide which
//!   agent wins on the same attempt; this does not.
//! * Why no plan: for each agent, the attempts without a rollout by reason (no feasible, by the
//!   agent's reason in a few classes; failed, by stage).

use crate::result::{CaseResult, Round, Status};
use crate::spec::AgentName;
use crate::tables::{frac, stat, verified, Stat, AS_PLANNED, REFINED};
use serde::{Deserialize, Serialize};
use std::collections::BTreeSet;
use std::fmt::Write;

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PairedRow {
    pub agent: AgentName,
    pub variant: String,
    /// Attempts every agent planned.
    pub attempts: usize,
    pub zone_hit_k: usize,
    pub success_k: usize,
    pub verified_k: usize,
    pub min_ttc_center_s: Option<Stat>,
    /// Verified here but not by the reference row, and the other way round.
    pub only_this: usize,
    pub only_reference: usize,
    /// Exact two-sided sign test on the discordant pairs (1 when there are none).
    pub p_value: f64,
}

/// Exact two-sided sign test: P(|X - n/2| >= |b - n/2|), X ~ Binomial(b + c, 1/2).
pub fn sign_test(b: usize, c: usize) -> f64 {
    let n = b + c;
    if n == 0 {
        return 1.0;
    }
    let k = b.min(c);
    // log C(n, i) summed in floating point; n is at most a few thousand.
    let mut tail = 0.0;
    let mut log_c = 0.0f64; // log C(n, 0)
    for i in 0..=k {
        if i > 0 {
            log_c += ((n - i + 1) as f64).ln() - (i as f64).ln();
        }
        tail += (log_c - n as f64 * std::f64::consts::LN_2).exp();
    }
    (2.0 * tail).min(1.0)
}

/// The attempt ids every agent in `agents` planned, in order.
pub fn common_attempts(results: &[CaseResult], agents: &[AgentName]) -> BTreeSet<String> {
    let done = |a: AgentName| -> BTreeSet<String> {
        results
            .iter()
            .filter(|r| r.spec.agent == a && matches!(r.status, Status::Done { .. }))
            .map(|r| r.spec.attempt_id())
            .collect()
    };
    let mut it = agents.iter();
    let Some(first) = it.next() else { return BTreeSet::new() };
    it.fold(done(*first), |acc, a| acc.intersection(&done(*a)).cloned().collect())
}

pub fn table1_paired(results: &[CaseResult], agents: &[AgentName]) -> Vec<PairedRow> {
    let common = common_attempts(results, agents);
    // Per row: (attempt id, the measured round).
    type Measured<'a> = Vec<(String, &'a Round)>;
    let mut rows: Vec<(AgentName, &str, Measured)> = Vec::new();
    for a in agents {
        let mine: Vec<&CaseResult> =
            results.iter().filter(|r| r.spec.agent == *a && common.contains(&r.spec.attempt_id())).collect();
        let pick = |f: fn(&CaseResult) -> Option<&Round>| -> Vec<(String, &Round)> {
            mine.iter().filter_map(|r| f(r).map(|x| (r.spec.attempt_id(), x))).collect()
        };
        rows.push((*a, AS_PLANNED, pick(CaseResult::first)));
        if a.refines() {
            rows.push((*a, REFINED, pick(CaseResult::best)));
        }
    }
    let reference: Vec<(String, bool)> =
        rows.first().map_or(vec![], |r| r.2.iter().map(|(id, x)| (id.clone(), verified(&x.metrics))).collect());
    rows.iter()
        .map(|(agent, variant, rounds)| {
            let count = |f: &dyn Fn(&Round) -> bool| rounds.iter().filter(|(_, r)| f(r)).count();
            let (mut only_this, mut only_reference) = (0, 0);
            for (id, r) in rounds {
                let here = verified(&r.metrics);
                let there = reference.iter().find(|(x, _)| x == id).is_some_and(|(_, v)| *v);
                only_this += usize::from(here && !there);
                only_reference += usize::from(there && !here);
            }
            PairedRow {
                agent: *agent,
                variant: variant.to_string(),
                attempts: rounds.len(),
                zone_hit_k: count(&|r| r.metrics.zone_hit),
                success_k: count(&|r| r.metrics.success_center),
                verified_k: count(&|r| verified(&r.metrics)),
                min_ttc_center_s: stat(&rounds.iter().map(|(_, r)| r.metrics.min_ttc_center_s).collect::<Vec<_>>()),
                only_this,
                only_reference,
                p_value: sign_test(only_this, only_reference),
            }
        })
        .collect()
}

pub fn paired_markdown(rows: &[PairedRow]) -> String {
    let reference = rows.first().map_or(String::new(), |r| format!("{} {}", r.agent.as_str(), r.variant));
    let mut s = format!("| agent | variant | attempts all agents planned | Zone Hit | Success (centre TTC < 1 s) | verified | MinTTC centre (s) | verified here, not by {reference} | verified by {reference}, not here | sign test p |\n|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.3} |",
            r.agent.as_str(),
            r.variant,
            r.attempts,
            frac(r.zone_hit_k, r.attempts),
            frac(r.success_k, r.attempts),
            frac(r.verified_k, r.attempts),
            r.min_ttc_center_s.map_or("-".into(), |s| format!("{:.3} ± {:.3}", s.mean, s.std)),
            r.only_this,
            r.only_reference,
            r.p_value
        );
    }
    s
}

pub fn paired_csv(rows: &[PairedRow]) -> String {
    let mut s = String::from("agent,variant,attempts,zone_hit_k,success_k,verified_k,min_ttc_center_mean,min_ttc_center_std,only_this,only_reference,p_value\n");
    for r in rows {
        let (m, sd) =
            r.min_ttc_center_s.map_or((String::new(), String::new()), |s| (s.mean.to_string(), s.std.to_string()));
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{m},{sd},{},{},{}",
            r.agent.as_str(),
            r.variant,
            r.attempts,
            r.zone_hit_k,
            r.success_k,
            r.verified_k,
            r.only_this,
            r.only_reference,
            r.p_value
        );
    }
    s
}

/// The class of a "no feasible" reason (the agents' own wording, shared by planner and baselines).
pub fn why_class(reason: &str) -> &'static str {
    if reason.contains("log ends") {
        "no feasible: log too short after t0"
    } else if reason.starts_with("no pedestrian within range is positioned") {
        "no feasible: no pedestrian positioned for the behaviour"
    } else if reason.starts_with("no vehicle") && reason.contains("within range is positioned") {
        // "no vehicle" or "no vehicle or cyclist" (the behaviours cyclists can also perform).
        "no feasible: no vehicle positioned for the behaviour"
    } else if reason.contains("the ego stands still") {
        "no feasible: positioned, but the ego stands still"
    } else if reason.starts_with(crate::choose::REFUSED_PREFIX) {
        "no feasible: positioned, but every rollout invalid"
    } else if reason.contains("none can reach") {
        "no feasible: positioned, but no trajectory within the limits"
    } else if reason.starts_with("no pedestrian within range") {
        "no feasible: no pedestrian in range"
    } else if reason.contains("no vehicle within range") || reason.contains("is not a vehicle within") {
        "no feasible: no vehicle in range"
    } else {
        "no feasible: other"
    }
}

/// Why attempts have no rollout: (class, count per agent in `agents` order).
pub fn why_no_plan(results: &[CaseResult], agents: &[AgentName]) -> Vec<(String, Vec<usize>)> {
    let class = |r: &CaseResult| match &r.status {
        Status::Done { .. } => None,
        Status::NoFeasible { reason } => Some(why_class(reason).to_string()),
        Status::Failed { stage, .. } => Some(format!("failed: {stage}")),
        Status::Rejected { .. } => Some("rejected: LLM reply invalid after re-prompts".to_string()),
    };
    let classes: BTreeSet<String> = results.iter().filter_map(class).collect();
    classes
        .into_iter()
        .map(|c| {
            let counts = agents
                .iter()
                .map(|a| results.iter().filter(|r| r.spec.agent == *a && class(r).as_deref() == Some(&c)).count())
                .collect();
            (c, counts)
        })
        .collect()
}

pub fn why_markdown(rows: &[(String, Vec<usize>)], agents: &[AgentName]) -> String {
    let names: Vec<&str> = agents.iter().map(|a| a.as_str()).collect();
    let mut s = format!("| why no plan | {} |\n|---|{}\n", names.join(" | "), "---|".repeat(agents.len()));
    for (c, n) in rows {
        let cells: Vec<String> = n.iter().map(|x| x.to_string()).collect();
        let _ = writeln!(s, "| {c} | {} |", cells.join(" | "));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sign_test_matches_binomial() {
        // 0 vs 5: 2 * 0.5^5 = 0.0625; 1 vs 9: 2 * 11 / 1024 = 0.021484375; equal -> 1.
        assert!((sign_test(0, 5) - 0.0625).abs() < 1e-12);
        assert!((sign_test(9, 1) - 0.021484375).abs() < 1e-12);
        assert_eq!(sign_test(3, 3), 1.0);
        assert_eq!(sign_test(0, 0), 1.0);
        assert_eq!(why_class("the log ends 1.0 s after t0, shorter than x"), "no feasible: log too short after t0");
        let cut_in = "no vehicle or cyclist within range is positioned for sudden_cut_in (a vehicle ...)";
        assert_eq!(why_class(cut_in), "no feasible: no vehicle positioned for the behaviour");
        let step_out = "no pedestrian within range is positioned for step_out (a pedestrian ...)";
        assert_eq!(why_class(step_out), "no feasible: no pedestrian positioned for the behaviour");
        let refused = format!("{} (3 rollout(s) tried ...): none handed over", crate::choose::REFUSED_PREFIX);
        assert_eq!(why_class(&refused), "no feasible: positioned, but every rollout invalid");
        let still = "1 vehicle(s) are positioned for sudden_cut_in, but the ego stands still (below 1 m/s) at ...";
        assert_eq!(why_class(still), "no feasible: positioned, but the ego stands still");
    }
}
