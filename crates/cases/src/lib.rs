//! `cases`: the evaluation harness behind `carla-gs eval-cases`. One list of attempts (scene x
//! behaviour x analysis time, `spec`) is given to every agent: reason -> simulate -> measure over
//! one window for all (`window`), with closed-loop refinement (`runner`); then the paper's Table I
//! and Table II (`tables`), the paired comparison and the reasons for no plan (`paired`) as
//! Markdown, CSV and JSON, per-case files and plots (`plots`). Deterministic agents run in parallel (rayon), LLM agents one case at a time;
//! results do not depend on the thread count (every case has its own seed).

pub mod choose;
pub mod describe;
pub mod llm_validity;
pub mod paired;
pub mod plots;
pub mod runner;
pub mod spec;
pub mod tables;
pub mod window;

use indicatif::ProgressBar;
use rayon::prelude::*;
use reason::backend::Backend;
use runner::{run_case, CaseConfig, CaseResult, Status};
use scene::{Behavior, Executed, Scene};
use serde::{Deserialize, Serialize};
use spec::{attempts, AgentName, CaseSpec, T0Spec};
use std::fmt::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub type BackendFactory = dyn Fn(AgentName) -> Result<Box<dyn Backend>, String>;

pub struct EvalConfig {
    pub agents: Vec<AgentName>,
    pub behaviors: Vec<Behavior>,
    pub t0: T0Spec,
    pub seed: u64,
    pub out: PathBuf,
    pub plots: bool,
    pub case: CaseConfig,
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

/// Runs every case and writes the report under `cfg.out`.
pub fn run_eval(
    scenes: &[Scene],
    cfg: &EvalConfig,
    backends: &BackendFactory,
    progress: &ProgressBar,
) -> Result<Report, EvalError> {
    let mut attempts = attempts(scenes, &cfg.behaviors, &cfg.t0, cfg.seed);
    // A scene with a `--describe` reading is attempted with its behaviour only.
    attempts.retain(|a| cfg.case.requests.get(&a.scene).is_none_or(|r| r.behavior == a.behavior));
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
    let cases: Vec<CaseResult> = results.into_iter().map(|(_, r)| r).collect();
    let failures = cases
        .iter()
        .filter_map(|r| match &r.status {
            Status::Failed { stage, reason } => {
                Some(Failure { case: r.spec.id(), stage: stage.clone(), reason: reason.clone() })
            }
            Status::Rejected { reason, .. } => {
                Some(Failure { case: r.spec.id(), stage: "reply".into(), reason: reason.clone() })
            }
            _ => None,
        })
        .collect();
    let report = Report {
        scenes: scenes.iter().map(|s| s.name.clone()).collect(),
        seed: cfg.seed,
        refine_rounds: cfg.case.refine_rounds,
        window: cfg.case.window,
        attempts: attempts.len(),
        table1: tables::table1(&cases, &cfg.agents),
        table1_paired: paired::table1_paired(&cases, &cfg.agents),
        why_no_plan: paired::why_no_plan(&cases, &cfg.agents),
        agents: cfg.agents.clone(),
        table2: tables::table2(&cases, &cfg.agents),
        validity: tables::validity(&cases, &cfg.agents),
        llm_validity: llm_validity::rows(&cases, &cfg.agents),
        failures,
        timing,
        plot_errors,
        cases,
    };
    write_report(&cfg.out, &report, cfg.plots)?;
    Ok(report)
}

/// The summary in Markdown: tables, validity, refinement effect, failures, timing.
pub fn summary_markdown(r: &Report) -> String {
    let horizon = match r.window.horizon {
        window::Horizon::Seconds(h) => format!(
            "{h} s from t0 (clipped at the log's end; after its plan the adversary does `{}`; contact with the ego ends the window)",
            match r.window.after_plan {
                window::AfterPlan::Stop => "stop",
                window::AfterPlan::Hold => "hold",
            }
        ),
        window::Horizon::Plan => "each plan's own end (`--horizon plan`)".into(),
    };
    let mut s = format!(
        "# Corner-case evaluation\n\nScenes: {}. Seed {}. Refinement rounds: {}. Attempts (scene, behaviour, t0) per agent: {}. Horizon: {horizon}.\n\n",
        r.scenes.join(", "),
        r.seed,
        r.refine_rounds,
        r.attempts
    );
    s.push_str("## Table I: controllability and success\n\nEvery agent is given the same attempts. `/ attempts` columns count over **all** attempts (no plan = not a corner case); *verified* = Zone Hit and Success (centre TTC < 1 s) on a physically valid rollout. `as planned`: the agent's first plan; `+ refine`: the best round of closed-loop refinement (`refine rounds`: rounds used beyond the first plan). Per-rollout columns: mean ± std over the attempts with a rollout. `invalid`: executed rollouts that are not physically valid (they count as not successful), then the count per reason (a rollout can have several).\n\n");
    s.push_str(&tables::table1_markdown(&r.table1));
    s.push_str("\n### Paired: the attempts every agent planned\n\n");
    s.push_str(&paired::paired_markdown(&r.table1_paired));
    s.push_str("\n### Why no plan\n\n");
    s.push_str(&paired::why_markdown(&r.why_no_plan, &r.agents));
    s.push_str("\n## Table II: feasibility and ride comfort (agent waypoints vs executed)\n\n");
    s.push_str(&tables::table2_markdown(&r.table2));
    if !r.validity.is_empty() {
        s.push_str("\n## Validity of LLM replies\n\n| agent | zone raw-valid | zone valid after retry | zone repaired | trajectory raw-valid | trajectory after retry | trajectory repaired |\n|---|---|---|---|---|---|---|\n");
        for v in &r.validity {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} |",
                v.agent.map_or("", |a| a.as_str()),
                v.zone[0],
                v.zone[1],
                v.zone[2],
                v.trajectory[0],
                v.trajectory[1],
                v.trajectory[2]
            );
        }
    }
    if !r.llm_validity.is_empty() {
        s.push_str("\n## LLM reply validity: the paper's way (first try) and ours\n\n");
        s.push_str(&llm_validity::markdown(&r.llm_validity));
    }
    s.push_str("\n## Failures\n\n");
    if r.failures.is_empty() {
        s.push_str("None.\n");
    }
    for f in &r.failures {
        let _ = writeln!(s, "- `{}` ({}): {}", f.case, f.stage, f.reason);
    }
    s.push_str("\n## Timing\n\n| agent | cases | wall (s) | cases/s |\n|---|---|---|---|\n");
    for t in &r.timing {
        let _ = writeln!(s, "| {} | {} | {:.2} | {:.2} |", t.agent.as_str(), t.cases, t.wall_s, t.cases_per_s);
    }
    if !r.plot_errors.is_empty() {
        let _ = writeln!(s, "\n{} plots could not be drawn; first: {}", r.plot_errors.len(), r.plot_errors[0]);
    }
    s
}

fn write_report(out: &Path, r: &Report, plots: bool) -> Result<(), EvalError> {
    let w = |name: &str, text: String| scene::write_file_atomic(&out.join(name), text.as_bytes());
    w("table1.md", tables::table1_markdown(&r.table1))?;
    w("table1.csv", tables::table1_csv(&r.table1))?;
    w("table1_paired.md", paired::paired_markdown(&r.table1_paired))?;
    w("table1_paired.csv", paired::paired_csv(&r.table1_paired))?;
    w("why_no_plan.md", paired::why_markdown(&r.why_no_plan, &r.agents))?;
    w("table2.md", tables::table2_markdown(&r.table2))?;
    w("table2.csv", tables::table2_csv(&r.table2))?;
    if !r.llm_validity.is_empty() {
        w("table_llm_validity.md", llm_validity::markdown(&r.llm_validity))?;
        w("table_llm_validity.csv", llm_validity::csv(&r.llm_validity))?;
    }
    w("summary.md", summary_markdown(r))?;
    scene::format::write_json_pretty(&out.join("report.json"), r)?;
    if plots {
        // A missing font must not lose the tables: the summary says so.
        if let Err(e) = plots::table1_bars(&out.join("table1.png"), &r.table1) {
            tracing::warn!("table1.png: {e}");
        }
    }
    Ok(())
}
