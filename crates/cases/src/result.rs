//! What one case produced (`CaseResult`: its spec and status, the executed rounds) and how two
//! rollouts rank (valid, then zone hit, then success, then lower MinTTC): the types every table,
//! report and merge reads, below the runner that makes them.

use crate::spec::CaseSpec;
use metrics::CaseMetrics;
use reason::ValidityStats;
use scene::Plan;
use serde::{Deserialize, Serialize};

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

pub(crate) fn good(m: &CaseMetrics) -> bool {
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
