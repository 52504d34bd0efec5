//! `carla-gs tables <dir>... --out <dir>`: merges the outputs of `eval-cases --shard I/N` runs
//! into the tables one run over all attempts writes (`cases::merge`); refuses missing or
//! duplicated shards and shards run with other settings. `--out` is new, empty or an eval-cases
//! output of ours (it may be the shards' own directory); a person's folder is refused, so that
//! its `summary.md` or `report.json` is never overwritten.
use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// Shard output directories (each holding shard-I-of-N.json and cases/), directories whose
    /// subdirectories are such, or record files.
    #[arg(required = true)]
    dirs: Vec<PathBuf>,
    #[arg(long)]
    out: PathBuf,
    /// Skip the Table I bar chart.
    #[arg(long)]
    no_plots: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    super::out_dir::check_replaceable(&a.out, &[], true, &super::eval_out::EVAL_OUT)?;
    let report = cases::merge::merge(&a.dirs)?;
    std::fs::create_dir_all(&a.out).map_err(|e| anyhow::anyhow!("{}: {e}", a.out.display()))?;
    cases::report::write(&a.out, &report, !a.no_plots)?;
    println!("{}", cases::summary_markdown(&report));
    println!(
        "merged {} attempts x {} agents; wrote {}/summary.md, table1.{{md,csv}}, table1_paired.{{md,csv}}, why_no_plan.md, table2.{{md,csv}}, table_llm_validity.{{md,csv}} (LLM agents) and report.json",
        report.attempts,
        report.agents.len(),
        a.out.display()
    );
    Ok(())
}
