//! `cases`: the evaluation harness behind `carla-gs eval-cases`. One list of attempts (scene x
//! behaviour x analysis time, `spec`) is given to every agent: reason -> simulate -> measure over
//! one window for all (`window`), with closed-loop refinement (`runner`); then the paper's Table I
//! and Table II (`tables`), the paired comparison and the reasons for no plan (`paired`) as
//! Markdown, CSV and JSON, per-case files and plots (`plots`). Deterministic agents run in parallel (rayon), LLM agents one case at a time;
//! results do not depend on the thread count (every case has its own seed).

pub mod case_check;
pub mod case_config;
pub mod choose;
pub mod describe;
pub mod llm_validity;
pub mod merge;
pub mod paired;
pub mod plots;
pub mod refine;
pub mod report;
pub mod result;
pub mod runner;
pub mod shard;
pub mod spec;
pub mod stress;
pub mod tables;
pub mod window;

use indicatif::ProgressBar;
use rayon::prelude::*;
use reason::backend::Backend;
use runner::{run_case, CaseConfig, CaseResult};
use scene::{Behavior, Executed, Scene};
use serde::{Deserialize, Serialize};
use spec::{attempts_of, AgentName, CaseSpec, SceneMeta, T0Spec};
use std::path::{Path, PathBuf};
use std::time::Instant;

pub use report::summary_markdown;

pub type BackendFactory = dyn Fn(AgentName) -> Result<Box<dyn Backend>, String>;

pub struct EvalConfig {
    pub agents: Vec<AgentName>,
    pub behaviors: Vec<Behavior>,
    pub t0: T0Spec,
    pub seed: u64,
    pub out: PathBuf,
    pub plots: bool,
    pub case: CaseConfig,
    /// Run only this shard of the attempts (`shard`); `None`: all of them.
    pub shard: Option<shard::Shard>,
    /// Settings only the caller knows (physics backend, LLM endpoint, ...), recorded with a
    /// shard so that shards run differently are not merged.
    pub cli_settings: std::collections::BTreeMap<String, String>,
}

impl EvalConfig {
    /// What decides this run's results ([`shard::Settings`]).
    pub fn settings(&self) -> shard::Settings {
        shard::Settings {
            version: env!("CARGO_PKG_VERSION").into(),
            agents: self.agents.clone(),
            behaviors: self.behaviors.clone(),
            t0: format!("{:?}", self.t0),
            seed: self.seed,
            window: self.case.window,
            refine_rounds: self.case.refine_rounds,
            check_rollouts: self.case.check_rollouts,
            reason: format!("{:?}", self.case.reason),
            cli: self.cli_settings.clone(),
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct AgentTiming {
    pub agent: AgentName,
    pub cases: usize,
    pub wall_s: f64,
    pub cases_per_s: f64,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Failure {
    pub case: String,
    pub stage: String,
    pub reason: String,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Report {
    pub scenes: Vec<String>,
    pub seed: u64,
    pub refine_rounds: usize,
    /// The evaluation window (horizon, what the adversary does after its plan).
    pub window: window::Window,
    /// Attempts (scene, behaviour, t0) given to every agent.
    pub attempts: usize,
    pub table1: Vec<tables::Table1Row>,
    pub table1_paired: Vec<paired::PairedRow>,
    /// Why attempts have no rollout: (class, count per agent in `agents` order).
    pub why_no_plan: Vec<(String, Vec<usize>)>,
    pub agents: Vec<AgentName>,
    pub table2: Vec<tables::Table2Row>,
    pub validity: Vec<tables::ValidityRow>,
    /// LLM reply validity, the paper's way (first try) beside ours ([`llm_validity`]).
    #[serde(default)]
    pub llm_validity: Vec<llm_validity::LlmValidityRow>,
    pub failures: Vec<Failure>,
    pub timing: Vec<AgentTiming>,
    pub plot_errors: Vec<String>,
    pub cases: Vec<CaseResult>,
}

#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    #[error("{0}")]
    Backend(String),
    #[error(transparent)]
    Output(#[from] scene::SceneError),
    /// The request cannot be run as given (duplicate scene names, colliding attempt ids).
    #[error("{0}")]
    Input(String),
    /// The request is well formed but holds no attempt (the logs are too short for its t0).
    #[error("{0}")]
    NoAttempt(String),
}

/// Writes one case's files: plan, executed trajectory, rounds and metrics, plots.
fn write_case(
    dir: &Path,
    scene: &Scene,
    r: &CaseResult,
    executed: Option<&Executed>,
    plots: bool,
) -> Result<Vec<String>, scene::SceneError> {
    let d = dir.join(r.spec.id());
    scene::format::write_json_pretty(&d.join("case.json"), r)?;
    let mut errors = Vec::new();
    if let (Some(round), Some(e)) = (r.best(), executed) {
        scene::format::write_json_pretty(&d.join("scenario.json"), &round.plan)?;
        scene::format::write_json_pretty(&d.join("executed.json"), e)?;
        if plots {
            if let Err(x) = plots::bev(&d.join("bev.png"), scene, &round.plan, e, &round.metrics) {
                errors.push(format!("{}: bev: {x}", r.spec.id()));
            }
            if let Err(x) = plots::tracking(&d.join("tracking.png"), &round.plan, e) {
                errors.push(format!("{}: tracking: {x}", r.spec.id()));
            }
        }
    }
    Ok(errors)
}

/// Runs every case (or, with `cfg.shard`, that shard's) and writes the report under `cfg.out`
/// (a shard writes its record instead: its tables would be partial; `merge` makes them).
pub fn run_eval(
    scenes: &[Scene],
    cfg: &EvalConfig,
    backends: &BackendFactory,
    progress: &ProgressBar,
) -> Result<Report, EvalError> {
    let universe: Vec<SceneMeta> = scenes.iter().map(SceneMeta::of).collect();
    run_eval_in(&universe, scenes, cfg, backends, progress)
}

/// The whole attempt list over `universe`, `cfg.shard`'s part of it (or all), in the order one
/// run over all attempts has them, with their positions in the whole list.
pub fn shard_attempts(universe: &[SceneMeta], cfg: &EvalConfig) -> Result<ShardAttempts, EvalError> {
    spec::check_t0(universe, cfg.behaviors.len(), &cfg.t0)?;
    let mut all = attempts_of(universe, &cfg.behaviors, &cfg.t0, cfg.seed);
    // A scene with a `--describe` reading is attempted with its behaviour only.
    all.retain(|a| cfg.case.requests.get(&a.scene).is_none_or(|r| r.behavior == a.behavior));
    check_unique(universe, &all)?;
    let total = all.len();
    let digest = shard::digest(&all);
    let mut positions: Vec<usize> = (0..total).collect();
    if let Some(sh) = cfg.shard {
        let which = shard::assign(&all, sh.count);
        positions.retain(|&i| which[i] == sh.index);
    }
    let mine = positions.iter().map(|&i| all[i].clone()).collect();
    Ok(ShardAttempts { attempts: mine, positions, total, digest })
}

/// A shard's attempts ([`shard_attempts`]).
pub struct ShardAttempts {
    pub attempts: Vec<spec::Attempt>,
    pub positions: Vec<usize>,
    pub total: usize,
    pub digest: String,
}

/// [`run_eval`] where the attempt list is made over `universe` (every scene's name and length)
/// and only `scenes` are loaded: those `cfg.shard`'s attempts use (more may be given).
pub fn run_eval_in(
    universe: &[SceneMeta],
    scenes: &[Scene],
    cfg: &EvalConfig,
    backends: &BackendFactory,
    progress: &ProgressBar,
) -> Result<Report, EvalError> {
    let ShardAttempts { mut attempts, positions, total, digest } = shard_attempts(universe, cfg)?;
    // Scene names are unique (`check_unique`): one lookup table, not a scan per attempt.
    let loaded: std::collections::HashMap<&str, usize> =
        scenes.iter().enumerate().map(|(i, s)| (s.name.as_str(), i)).collect();
    for a in &mut attempts {
        a.scene_index = *loaded.get(a.scene.as_str()).ok_or_else(|| {
            EvalError::Input(format!("scene `{}` is in the attempt list but was not loaded", a.scene))
        })?;
    }
    let settings = cfg.settings();
    let mut names: Vec<String> = universe.iter().map(|s| s.name.clone()).collect();
    names.sort();
    let (cases, timing, plot_errors) = run_attempts(scenes, &attempts, cfg, backends, progress)?;
    if let Some(sh) = cfg.shard {
        let record = shard::ShardRecord {
            format: shard::RECORD_FORMAT.into(),
            version: shard::RECORD_VERSION,
            shard: sh,
            settings: settings.clone(),
            scenes: names.clone(),
            attempts_total: total,
            attempts_digest: digest,
            attempts: attempts
                .iter()
                .zip(&positions)
                .map(|(a, &position)| shard::RecordedAttempt { id: a.id(), position, seed: a.seed })
                .collect(),
            timing: timing.clone(),
            plot_errors: plot_errors.clone(),
        };
        scene::format::write_json_pretty(&record.path(&cfg.out), &record)?;
        return Ok(report::build(names, &settings, attempts.len(), cases, timing, plot_errors));
    }
    let report = report::build(names, &settings, total, cases, timing, plot_errors);
    report::write(&cfg.out, &report, cfg.plots)?;
    Ok(report)
}

/// Scene names and attempt ids name the case files: two equal ones would overwrite each other.
fn check_unique(scenes: &[SceneMeta], attempts: &[spec::Attempt]) -> Result<(), EvalError> {
    let mut seen = std::collections::BTreeSet::new();
    if let Some(s) = scenes.iter().find(|s| !seen.insert(s.name.as_str())) {
        return Err(EvalError::Input(format!(
            "two scenes are named `{}`: scene names must be unique (they name the case files)",
            s.name
        )));
    }
    let mut ids = std::collections::BTreeSet::new();
    if let Some(a) = attempts.iter().find(|a| !ids.insert(a.id())) {
        return Err(EvalError::Input(format!(
            "two attempts share the id `{}` (t0 values closer than 0.05 s?): give t0 at least 0.1 s apart",
            a.id()
        )));
    }
    Ok(())
}

type Ran = (Vec<CaseResult>, Vec<AgentTiming>, Vec<String>);

/// Runs `attempts` with every agent (deterministic agents in parallel, LLM agents one case at a
/// time) and writes each case's files; cases come back in attempt order, then agent order.
fn run_attempts(
    scenes: &[Scene],
    attempts: &[spec::Attempt],
    cfg: &EvalConfig,
    backends: &BackendFactory,
    progress: &ProgressBar,
) -> Result<Ran, EvalError> {
    let all: Vec<CaseSpec> = attempts.iter().flat_map(|a| cfg.agents.iter().map(|g| a.for_agent(*g))).collect();
    progress.set_length(all.len() as u64);
    let case_dir = cfg.out.join("cases");
    let mut results: Vec<(usize, CaseResult)> = Vec::new();
    let mut timing = Vec::new();
    let mut plot_errors = Vec::new();
    for agent in &cfg.agents {
        let mine: Vec<(usize, &CaseSpec)> = all.iter().enumerate().filter(|(_, c)| c.agent == *agent).collect();
        let start = Instant::now();
        let run_one = |spec: &CaseSpec, backend: Option<&mut dyn Backend>| {
            let scene = &scenes[spec.scene_index];
            let (r, e) = run_case(scene, spec, &cfg.case, backend);
            let errs = write_case(&case_dir, scene, &r, e.as_ref(), cfg.plots);
            progress.inc(1);
            (r, errs)
        };
        type Done = (usize, (CaseResult, Result<Vec<String>, scene::SceneError>));
        let out: Vec<Done> = if agent.is_llm() {
            let mut b = backends(*agent).map_err(EvalError::Backend)?;
            mine.iter().map(|(i, s)| (*i, run_one(s, Some(b.as_mut())))).collect()
        } else {
            mine.par_iter().map(|(i, s)| (*i, run_one(s, None))).collect()
        };
        let wall = start.elapsed().as_secs_f64();
        timing.push(AgentTiming {
            agent: *agent,
            cases: mine.len(),
            wall_s: wall,
            cases_per_s: mine.len() as f64 / wall.max(1e-9),
        });
        for (i, (r, errs)) in out {
            plot_errors.extend(errs?);
            results.push((i, r));
        }
    }
    results.sort_by_key(|(i, _)| *i);
    Ok((results.into_iter().map(|(_, r)| r).collect(), timing, plot_errors))
}
