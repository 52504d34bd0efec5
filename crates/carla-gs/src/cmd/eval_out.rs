//! Where `eval-cases` writes. `--out` is new, empty, or an eval-cases output of ours
//! (`report.json`, or a shard's `shard-I-of-N.json`); anything else is refused, with or without
//! `--force`. Every run is built in a staging directory beside `--out` first, so a run killed at
//! any point leaves `--out` as it was and the next run completes:
//!
//! - a whole run replaces `--out` whole, in one rename at the end, and only with `--force` where
//!   an earlier output is there;
//! - a shard (`--shard I/N`) adds its case directories to `--out` (several shards share one
//!   directory), each replacing the same case's earlier directory, and its record
//!   `shard-I-of-N.json` last; an earlier record of the same shard is replaced only with `--force`.

use super::out_dir::{self, Kind};
use cases::shard::Shard;
use std::path::Path;

/// The files eval-cases writes in a case's directory.
const CASE_FILES: [&str; 5] = ["case.json", "scenario.json", "executed.json", "bev.png", "tracking.png"];

/// An eval-cases output: `report.json` that reads as a report, or a shard's record.
pub const EVAL_OUT: Kind =
    Kind { what: "an eval-cases output", marker: "report.json or shard-I-of-N.json", ours: is_eval_out };

fn is_eval_out(dir: &Path) -> bool {
    if scene::format::read_json::<cases::Report>(&dir.join("report.json")).is_ok() || is_partial_eval_out(dir) {
        return true;
    }
    let Ok(rd) = std::fs::read_dir(dir) else { return false };
    rd.flatten().any(|e| {
        let name = e.file_name().to_string_lossy().into_owned();
        name.starts_with("shard-")
            && name.ends_with(".json")
            && scene::has_format_marker(dir, &name, cases::shard::RECORD_FORMAT)
    })
}

/// What an eval-cases run killed part-way by an older carla-gs (which wrote in place) leaves:
/// a `cases/` of case directories (each with `case.json`, and only the files a case writes),
/// perhaps beside tables of ours, and nothing else.
fn is_partial_eval_out(dir: &Path) -> bool {
    const TOP: [&str; 4] = ["cases", "summary.md", "why_no_plan.md", "report.json"];
    let table = |n: &str| n.starts_with("table") && [".md", ".csv", ".png"].iter().any(|x| n.ends_with(x));
    let Ok(rd) = std::fs::read_dir(dir) else { return false };
    let top_ok = rd.flatten().all(|e| {
        let n = e.file_name().to_string_lossy().into_owned();
        TOP.contains(&n.as_str()) || table(&n) || (n.starts_with('.') && n.ends_with(".tmp"))
    });
    let cases = dir.join("cases");
    let Ok(rd) = std::fs::read_dir(&cases) else { return false };
    let cases_ok = rd.flatten().all(|e| {
        let Ok(files) = std::fs::read_dir(e.path()) else { return false };
        let files: Vec<String> = files.flatten().map(|f| f.file_name().to_string_lossy().into_owned()).collect();
        files.iter().any(|f| f == "case.json")
            && files.iter().all(|f| CASE_FILES.contains(&f.as_str()) || (f.starts_with('.') && f.ends_with(".tmp")))
    });
    top_ok && cases_ok
}

/// Checks `out` before any work (see the module's header).
pub fn check(out: &Path, inputs: &[&Path], force: bool, shard: Option<Shard>) -> anyhow::Result<()> {
    let Some(shard) = shard else { return out_dir::check_replaceable(out, inputs, force, &EVAL_OUT) };
    // A shard adds to an output of ours without --force (other shards' files stay).
    out_dir::check_replaceable(out, inputs, true, &EVAL_OUT)?;
    let record = out.join(shard.record_name());
    let ours = scene::has_format_marker(out, &shard.record_name(), cases::shard::RECORD_FORMAT);
    out_dir::check_out_file_in(&record, force, "a shard record of eval-cases", ours)
}

/// [`check`], then a staging directory beside `out` to build the run in.
pub fn stage(out: &Path, inputs: &[&Path], force: bool, shard: Option<Shard>) -> anyhow::Result<scene::StagedDir> {
    check(out, inputs, force, shard)?;
    let dest = if out.exists() { out.canonicalize()? } else { out.to_path_buf() };
    Ok(scene::StagedDir::new(&dest, true)?)
}

/// Moves the finished run in (see the module's header).
pub fn commit(staged: scene::StagedDir, shard: Option<Shard>) -> anyhow::Result<()> {
    let dest = staged.dest().to_path_buf();
    let Some(shard) = shard.filter(|_| dest.exists()) else {
        staged.commit()?;
        return Ok(());
    };
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |e: std::io::Error| anyhow::anyhow!("{}: {e}", p.display())
    };
    let cases_from = staged.path().join("cases");
    let cases_to = dest.join("cases");
    if cases_from.is_dir() {
        std::fs::create_dir_all(&cases_to).map_err(io(&cases_to))?;
        for e in std::fs::read_dir(&cases_from).map_err(io(&cases_from))? {
            let e = e.map_err(io(&cases_from))?;
            let to = cases_to.join(e.file_name());
            if std::fs::symlink_metadata(&to).is_ok() {
                remove_case_dir(&to)?;
            }
            std::fs::rename(e.path(), &to).map_err(io(&to))?;
        }
    }
    // The record says the shard is whole: it goes in last.
    let name = shard.record_name();
    let to = dest.join(&name);
    std::fs::rename(staged.path().join(&name), &to).map_err(io(&to))?;
    drop(staged);
    Ok(())
}

/// Removes an earlier run's directory of a case, refusing one that holds anything else.
fn remove_case_dir(dir: &Path) -> anyhow::Result<()> {
    let foreign = |p: &Path| {
        anyhow::anyhow!(
            "{}: was not written by eval-cases; move it away; the new case files were not moved in",
            p.display()
        )
    };
    if !std::fs::symlink_metadata(dir).is_ok_and(|m| m.is_dir()) {
        return Err(foreign(dir));
    }
    for e in std::fs::read_dir(dir)?.flatten() {
        let name = e.file_name().to_string_lossy().into_owned();
        if !CASE_FILES.contains(&name.as_str()) || !e.file_type().is_ok_and(|t| t.is_file()) {
            return Err(foreign(&e.path()));
        }
    }
    std::fs::remove_dir_all(dir).map_err(|e| anyhow::anyhow!("{}: {e}", dir.display()))
}
