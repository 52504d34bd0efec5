//! What every case of a run shares (`CaseConfig`: reason options, rollout settings, the physics
//! as a function, the evaluation window, refinement rounds) and the one way a plan is executed
//! over that window ([`execute`]): the lowest layer of a case, used by the rollout check
//! (`choose`), the refinement (`refine`) and the runner alike.

use crate::window::{self, Horizon, Window};
use reason::ReasonOptions;
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
    /// The insertion's per-scene street (`reason::insert::Street`), built once per scene of the
    /// run rather than once per attempt.
    pub streets: reason::insert::Streets,
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
