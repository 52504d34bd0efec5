//! `bench.md`: the stress bench's tables in Markdown, one table per grouping (behaviour, corpus
//! subset), the sudden cut-in adjacency line and the throughput, with every rate as `k/N` so a
//! reader sees each denominator.

use super::bench::{BenchReport, BenchRow};
use crate::tables::frac;
use std::fmt::Write;

fn rate(x: Option<f64>) -> String {
    x.map_or("-".into(), |v| format!("{v:.3}"))
}

fn table(s: &mut String, first: &str, rows: &[BenchRow]) {
    let _ = writeln!(
        s,
        "| {first} | agent | variant | attempts | planned | no plan (failed) | invalid / rollouts (contact with other, left road, friction limit, tracking diverged) | Zone Hit per rollout | Success per rollout | verified / attempts | (scene, t0) with a verified case | why no plan |\n|{}",
        "---|".repeat(12)
    );
    for r in rows {
        let why: Vec<String> =
            r.why_no_plan.iter().map(|(c, n)| format!("{n} {}", c.trim_start_matches("no feasible: "))).collect();
        let i = &r.invalid;
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} ({}) | {}/{} ({}, {}, {}, {}) | {} | {} | {} | {} | {} |",
            r.label,
            r.agent.as_str(),
            r.variant,
            r.attempts,
            r.planned,
            r.no_plan,
            r.failed,
            i.invalid,
            r.rollouts,
            i.contact_with_other,
            i.left_road,
            i.friction_limit,
            i.tracking_diverged,
            rate(r.zone_hit_per_rollout),
            rate(r.success_per_rollout),
            frac(r.verified, r.attempts),
            frac(r.pairs_verified, r.pairs),
            if why.is_empty() { "-".into() } else { why.join("; ") }
        );
    }
}

/// The whole `bench.md`.
pub fn markdown(r: &BenchReport) -> String {
    let mut subsets: Vec<&str> = Vec::new();
    for l in &r.scenes {
        if !subsets.contains(&l.perturbation.as_str()) {
            subsets.push(&l.perturbation);
        }
    }
    let mut s = format!(
        "# Stress corpus bench\n\n{} scenes ({}), t0 `{}`, seed {}: {} attempts (scene, behaviour, t0) per agent. Per-rollout columns count over the planned attempts (one rollout each); `/ attempts` columns over every attempt. A rollout can be invalid for several reasons.\n\n## Per behaviour\n\n",
        r.scenes.len(),
        subsets.join(", "),
        r.t0,
        r.seed,
        r.attempts
    );
    table(&mut s, "behaviour", &r.by_behavior);
    s.push_str("\n## Per perturbation (every source)\n\n");
    table(&mut s, "perturbation", &r.by_subset);
    s.push_str("\n## Per log source (every perturbation)\n\n");
    table(&mut s, "source", &r.by_source);
    s.push_str("\n## Sudden cut-in where an adjacent-lane vehicle exists\n\nAdjacent-lane vehicle: a vehicle or cyclist present at t0 within the planner's radius whose lateral offset in the ego frame rounds to one lane (3.6 m) either side and that heads the ego's way (within 45°), anywhere along the ego (`reason::behavior::Relation`). Positioned: one of them also passes the cut-in's own gate (`candidate_zones`).\n\n| agent | cut-in attempts | with adjacent-lane vehicle | planned of those | positioned | planned of those |\n|---|---|---|---|---|---|\n");
    for c in &r.cut_in {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} |",
            c.agent.map_or("", |a| a.as_str()),
            c.attempts,
            c.with_adjacent,
            frac(c.planned_with_adjacent, c.with_adjacent),
            c.positioned,
            frac(c.planned_positioned, c.positioned)
        );
    }
    s.push_str("\n## Throughput\n\n| agent | cases | wall (s) | cases/s |\n|---|---|---|---|\n");
    for t in &r.timing {
        let _ = writeln!(s, "| {} | {} | {:.2} | {:.1} |", t.agent.as_str(), t.cases, t.wall_s, t.cases_per_s);
    }
    let _ = writeln!(
        s,
        "\nCorpus assembly (reading the logs, perturbing) {:.2} s; the whole bench {:.2} s.",
        r.corpus_wall_s, r.bench_wall_s
    );
    if !r.skipped_copies.is_empty() {
        s.push_str("\nCopies not made (not in the corpus):\n\n");
        for c in &r.skipped_copies {
            let _ = writeln!(s, "- {c}");
        }
    }
    s
}
