//! Validity of LLM replies, the paper's way beside ours: for each LLM agent and each of its two
//! agents (Zone, Trajectory), over every reply chain (each case's first plan and each refinement
//! round, plus the cases whose reply was rejected): how many were valid at the first try (the
//! paper's "valid" share, 29.4 % by manual inspection), valid after re-prompts with the
//! violations, repaired by the planner (`--repair planner`), and still invalid with no repair
//! asked (the case is `rejected`, no plan). Shares are over all chains, so every reply counts.
//! Written as `table_llm_validity.{md,csv}`.

use crate::result::{CaseResult, Status};
use crate::spec::AgentName;
use reason::{Validity, ValidityStats};
use serde::{Deserialize, Serialize};
use std::fmt::Write;

/// Counts of one agent (Zone or Trajectory) of one LLM backend.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LlmValidityRow {
    pub agent: Option<AgentName>,
    /// `zone` or `trajectory`.
    pub role: String,
    pub replies: usize,
    pub first_try: usize,
    pub after_reprompt: usize,
    pub repaired: usize,
    pub invalid: usize,
}

impl LlmValidityRow {
    fn add(&mut self, v: &Validity) {
        self.replies += 1;
        match v {
            Validity::RawValid => self.first_try += 1,
            Validity::ValidAfterRetry { .. } => self.after_reprompt += 1,
            Validity::Repaired { .. } => self.repaired += 1,
            Validity::Invalid { .. } => self.invalid += 1,
        }
    }

    fn share(&self, n: usize) -> Option<f64> {
        (self.replies > 0).then(|| n as f64 / self.replies as f64)
    }

    /// The paper's share: valid at the first try.
    pub fn first_try_share(&self) -> Option<f64> {
        self.share(self.first_try)
    }

    /// Valid by the model itself, re-prompts included.
    pub fn valid_share(&self) -> Option<f64> {
        self.share(self.first_try + self.after_reprompt)
    }

    /// A plan came out (the planner's repairs included).
    pub fn usable_share(&self) -> Option<f64> {
        self.share(self.first_try + self.after_reprompt + self.repaired)
    }
}

/// Every reply chain's validity of one case.
fn chains(r: &CaseResult) -> Vec<&ValidityStats> {
    match &r.status {
        Status::Done { rounds, .. } => rounds.iter().filter_map(|x| x.validity.as_ref()).collect(),
        Status::Rejected { validity, .. } => vec![validity],
        _ => Vec::new(),
    }
}

pub fn rows(results: &[CaseResult], agents: &[AgentName]) -> Vec<LlmValidityRow> {
    let mut out = Vec::new();
    for a in agents.iter().filter(|a| a.is_llm()) {
        let mut zone = LlmValidityRow { agent: Some(*a), role: "zone".into(), ..Default::default() };
        let mut traj = LlmValidityRow { agent: Some(*a), role: "trajectory".into(), ..Default::default() };
        for r in results.iter().filter(|r| r.spec.agent == *a) {
            for s in chains(r) {
                zone.add(&s.zone);
                traj.add(&s.trajectory);
            }
        }
        out.push(zone);
        out.push(traj);
    }
    out
}

fn pct(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{:.1} %", 100.0 * v))
}

/// The counted columns, shared by the Markdown and CSV tables.
fn counts(r: &LlmValidityRow) -> [String; 7] {
    [
        r.agent.map_or("", |a| a.as_str()).to_string(),
        r.role.clone(),
        r.replies.to_string(),
        r.first_try.to_string(),
        r.after_reprompt.to_string(),
        r.repaired.to_string(),
        r.invalid.to_string(),
    ]
}

pub fn markdown(rows: &[LlmValidityRow]) -> String {
    let mut s = String::from("| LLM | agent | replies | valid at first try (paper) | valid after re-prompt | repaired by planner | invalid, no repair | first-try share | valid share (re-prompts) | usable share (repairs) |\n|---|---|---|---|---|---|---|---|---|---|\n");
    for r in rows {
        let shares = [pct(r.first_try_share()), pct(r.valid_share()), pct(r.usable_share())];
        let _ =
            writeln!(s, "| {} |", counts(r).iter().chain(&shares).map(String::as_str).collect::<Vec<_>>().join(" | "));
    }
    s
}

pub fn csv(rows: &[LlmValidityRow]) -> String {
    let mut s = String::from("llm,agent,replies,first_try,after_reprompt,repaired,invalid\n");
    for r in rows {
        let _ = writeln!(s, "{}", counts(r).join(","));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_chain_counts_once_in_its_column() {
        let mut r = LlmValidityRow::default();
        for v in [
            Validity::RawValid,
            Validity::ValidAfterRetry { retries: 1 },
            Validity::Repaired { violations: vec![] },
            Validity::Invalid { violations: vec![] },
        ] {
            r.add(&v);
        }
        r.add(&Validity::RawValid);
        assert_eq!((r.replies, r.first_try, r.after_reprompt, r.repaired, r.invalid), (5, 2, 1, 1, 1));
        assert_eq!(r.first_try_share(), Some(0.4));
        assert_eq!(r.valid_share(), Some(0.6));
        assert_eq!(r.usable_share(), Some(0.8));
        assert!(markdown(&[r.clone()]).contains("| 5 | 2 | 1 | 1 | 1 | 40.0 % | 60.0 % | 80.0 % |"));
        assert_eq!(LlmValidityRow::default().first_try_share(), None);
    }
}
