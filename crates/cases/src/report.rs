//! The report of an evaluation, built from its cases (one run, or the merge of shard runs:
//! `build` is the one place both go through, so their tables are the same bytes), and written
//! as Markdown, CSV and JSON: the summary, Table I, the paired table, why no plan, Table II and
//! the LLM reply validity.

use crate::result::{CaseResult, Status};
use crate::shard::Settings;
use crate::{llm_validity, paired, plots, tables, window, AgentTiming, EvalError, Failure, Report};
use std::fmt::Write;
use std::path::Path;

/// The report over `cases` (in the whole attempt list's order, each attempt once per agent).
pub fn build(
    scenes: Vec<String>,
    settings: &Settings,
    attempts: usize,
    cases: Vec<CaseResult>,
    timing: Vec<AgentTiming>,
    plot_errors: Vec<String>,
) -> Report {
    let agents = &settings.agents;
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
    Report {
        scenes,
        seed: settings.seed,
        refine_rounds: settings.refine_rounds,
        window: settings.window,
        attempts,
        table1: tables::table1(&cases, agents),
        table1_paired: paired::table1_paired(&cases, agents),
        why_no_plan: paired::why_no_plan(&cases, agents),
        agents: agents.clone(),
        table2: tables::table2(&cases, agents),
        validity: tables::validity(&cases, agents),
        llm_validity: llm_validity::rows(&cases, agents),
        failures,
        timing,
        plot_errors,
        cases,
    }
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

/// Every file [`write`] may write at the top of an output, `report.json` (the one that says the
/// set is whole) last.
pub const FILES: [&str; 12] = [
    "table1.md",
    "table1.csv",
    "table1_paired.md",
    "table1_paired.csv",
    "why_no_plan.md",
    "table2.md",
    "table2.csv",
    "table_llm_validity.md",
    "table_llm_validity.csv",
    "summary.md",
    "table1.png",
    "report.json",
];

pub fn write(out: &Path, r: &Report, plots: bool) -> Result<(), EvalError> {
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
