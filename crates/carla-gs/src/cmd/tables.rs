//! `carla-gs tables <dir>... --out <dir>`: merges the outputs of `eval-cases --shard I/N` runs
//! into the tables one run over all attempts writes (`cases::merge`); refuses missing or
//! duplicated shards and shards run with other settings. `--out` is new, empty or an eval-cases
//! output of ours (it may be the shards' own directory); a person's folder is refused, so that
//! its `summary.md` or `report.json` is never overwritten.
//!
//! The tables are written in a staging directory beside `--out` first, so that a `tables` killed
//! while merging or drawing leaves `--out` as it was. An output of tables alone is then replaced
//! whole in one rename; beside shards (their records and `cases/`, which stay) the new files are
//! moved in one by one, `report.json`, which says the set is whole, removed first and moved in
//! last, and an earlier merge's tables that this one does not write removed.
use std::path::{Path, PathBuf};

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
    let staged = super::out_dir::stage(&a.out, &[], true, &super::eval_out::EVAL_OUT)?;
    cases::report::write(staged.path(), &report, !a.no_plots)?;
    commit(staged)?;
    println!("{}", cases::summary_markdown(&report));
    println!(
        "merged {} attempts x {} agents; wrote {}/summary.md, table1.{{md,csv}}, table1_paired.{{md,csv}}, why_no_plan.md, table2.{{md,csv}}, table_llm_validity.{{md,csv}} (LLM agents) and report.json",
        report.attempts,
        report.agents.len(),
        a.out.display()
    );
    Ok(())
}

/// Moves the staged tables into `--out` (see the module's header).
fn commit(staged: scene::StagedDir) -> anyhow::Result<()> {
    let dest = staged.dest().to_path_buf();
    if !holds_more_than_tables(&dest) {
        staged.commit()?;
        return Ok(());
    }
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |e: std::io::Error| anyhow::anyhow!("{}: {e}", p.display())
    };
    let report = dest.join("report.json");
    if std::fs::symlink_metadata(&report).is_ok() {
        std::fs::remove_file(&report).map_err(io(&report))?;
    }
    for name in cases::report::FILES {
        let (from, to) = (staged.path().join(name), dest.join(name));
        if from.is_file() {
            std::fs::rename(&from, &to).map_err(io(&to))?;
        } else if std::fs::symlink_metadata(&to).is_ok_and(|m| m.is_file()) {
            std::fs::remove_file(&to).map_err(io(&to))?;
        }
    }
    drop(staged);
    Ok(())
}

/// Whether `dir` holds anything but tables (shard records, `cases/`), which a merge keeps.
fn holds_more_than_tables(dir: &Path) -> bool {
    let Ok(rd) = std::fs::read_dir(dir) else { return false };
    rd.flatten().any(|e| {
        let name = e.file_name().to_string_lossy().into_owned();
        let ours = cases::report::FILES.contains(&name.as_str()) || (name.starts_with('.') && name.ends_with(".tmp"));
        !ours
    })
}
