//! The merge of shard runs (`carla-gs tables <dir>...`): reads every shard record found in the
//! given directories (or their direct subdirectories), checks that they are one run cut into
//! pieces, reads each attempt's case files back and builds the report one `eval-cases` run over
//! all attempts would have built (`report::build`, same case order: the tables are the same
//! bytes; only the timing differs, summed over the shards).
//!
//! Nothing is averaged over what happens to be there: a missing or duplicated shard, shards of
//! another attempt list or run with other settings, and a missing or foreign case file are
//! refused with the file and what was expected. Each record is checked before it is compared
//! (its shard, horizon and timings; `attempts_total` against the attempts the records hold,
//! before anything is allocated from it), and each case file's numbers
//! ([`crate::case_check`]) before the tables count them.

use crate::result::CaseResult;
use crate::shard::{ShardRecord, RECORD_FORMAT, RECORD_VERSION};
use crate::{report, AgentTiming, Report};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A shard record larger than this is not one (100k attempts take about 10 MB).
pub const MAX_RECORD_BYTES: u64 = 256 << 20;
/// A case file larger than this is not one (a case with refinement rounds is a few kB).
pub const MAX_CASE_BYTES: u64 = 64 << 20;
/// A shard's wall time past this (about 30 years) is not a measurement.
const MAX_WALL_S: f64 = 1e9;
/// Records read at most: [`crate::shard::MAX_SHARDS`].
const MAX_RECORDS: usize = crate::shard::MAX_SHARDS;

#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error("no shard record (shard-I-of-N.json) in {0} or its subdirectories")]
    NoRecords(String),
    #[error(transparent)]
    Read(#[from] scene::SceneError),
    #[error("{file}: {message}")]
    Invalid { file: PathBuf, message: String },
    #[error("{a} and {b} were run with different settings: {fields}")]
    Mixed { a: PathBuf, b: PathBuf, fields: String },
    #[error("shard {shard} is given twice: {a} and {b}")]
    Duplicate { shard: String, a: PathBuf, b: PathBuf },
    #[error("{count} of {of} shards missing: {list} (expected shard-I-of-{of}.json for each)")]
    Missing { count: usize, of: usize, list: String },
    #[error("{path}: missing: the case `{case}` of {record} was not written (did its shard finish?)")]
    CaseMissing { path: PathBuf, case: String, record: PathBuf },
}

fn invalid(file: &Path, message: impl Into<String>) -> MergeError {
    MergeError::Invalid { file: file.to_path_buf(), message: message.into() }
}

/// Shard records in `dir` (a record file itself, a directory holding records, or a directory
/// whose direct subdirectories hold them), sorted by path.
fn find_records(dir: &Path, out: &mut Vec<PathBuf>) -> Result<(), MergeError> {
    let is_record = |p: &Path| {
        p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n.starts_with("shard-") && n.ends_with(".json"))
    };
    if dir.is_file() {
        out.push(dir.to_path_buf());
        return Ok(());
    }
    let list = |d: &Path| -> Result<Vec<PathBuf>, MergeError> {
        let rd = std::fs::read_dir(d).map_err(|e| scene::SceneError::io(d, e))?;
        let mut v: Vec<PathBuf> = rd.filter_map(|e| e.ok().map(|e| e.path())).collect();
        v.sort();
        Ok(v)
    };
    let entries = list(dir)?;
    let here: Vec<PathBuf> = entries.iter().filter(|p| p.is_file() && is_record(p)).cloned().collect();
    if !here.is_empty() {
        out.extend(here);
        return Ok(());
    }
    let before = out.len();
    for sub in entries.iter().filter(|p| p.is_dir()) {
        out.extend(list(sub)?.into_iter().filter(|p| p.is_file() && is_record(p)));
        if out.len() > MAX_RECORDS {
            return Err(invalid(dir, format!("more than {MAX_RECORDS} shard records")));
        }
    }
    if out.len() == before {
        return Err(MergeError::NoRecords(dir.display().to_string()));
    }
    Ok(())
}

/// Reads `file` as JSON of `T`, refusing it past `max` bytes.
fn read_bounded<T: serde::de::DeserializeOwned>(file: &Path, max: u64) -> Result<T, MergeError> {
    let len = std::fs::metadata(file).map_err(|e| scene::SceneError::io(file, e))?.len();
    if len > max {
        return Err(invalid(file, format!("is {len} bytes; expected at most {max}")));
    }
    Ok(scene::format::read_json(file)?)
}

/// Reads and checks the shard records under `dirs`, then every case they name, and builds the
/// whole run's report.
pub fn merge(dirs: &[PathBuf]) -> Result<Report, MergeError> {
    let mut files = Vec::new();
    for d in dirs {
        find_records(d, &mut files)?;
    }
    files.sort();
    files.dedup();
    let mut records: Vec<(PathBuf, ShardRecord)> = Vec::with_capacity(files.len());
    for f in files {
        let r: ShardRecord = read_bounded(&f, MAX_RECORD_BYTES)?;
        if r.format != RECORD_FORMAT || r.version != RECORD_VERSION {
            return Err(invalid(
                &f,
                format!("format {} v{}; expected {RECORD_FORMAT} v{RECORD_VERSION}", r.format, r.version),
            ));
        }
        check_record(&f, &r)?;
        records.push((f, r));
    }
    check_one_run(&records)?;
    let (first_file, first) = &records[0];
    let total = first.attempts_total;
    let settings = first.settings.clone();
    // Every attempt is in exactly one record: the records' attempts bound the list's length
    // before anything is allocated from `attempts_total`.
    let held: usize = records.iter().map(|(_, r)| r.attempts.len()).sum();
    if held != total {
        return Err(invalid(
            first_file,
            format!(
                "attempts_total: {total}, but the {} records hold {held} attempts: {}",
                records.len(),
                if held < total { "the records are incomplete" } else { "an attempt is in two records" }
            ),
        ));
    }
    // Each attempt's place in the whole list, and the record (dir) that ran it.
    let mut slots: Vec<Option<(usize, &crate::shard::RecordedAttempt)>> = vec![None; total];
    for (k, (file, r)) in records.iter().enumerate() {
        for a in &r.attempts {
            match slots.get_mut(a.position) {
                Some(slot @ None) => *slot = Some((k, a)),
                Some(Some((j, _))) => {
                    return Err(invalid(file, format!("attempt `{}` is also in {}", a.id, records[*j].0.display())))
                }
                None => return Err(invalid(file, format!("attempt `{}` at position {} of {total}", a.id, a.position))),
            }
        }
    }
    if let Some(p) = slots.iter().position(Option::is_none) {
        return Err(invalid(first_file, format!("no shard ran attempt {p} of {total}: the records are incomplete")));
    }
    let mut cases: Vec<CaseResult> = Vec::with_capacity(total * settings.agents.len());
    for (k, a) in slots.into_iter().flatten() {
        let (file, _) = &records[k];
        let dir = file.parent().unwrap_or(Path::new("."));
        for agent in &settings.agents {
            let id = format!("{}_{}", a.id, agent.as_str());
            let path = dir.join("cases").join(&id).join("case.json");
            if !path.is_file() {
                return Err(MergeError::CaseMissing { path, case: id, record: file.clone() });
            }
            let c: CaseResult = read_bounded(&path, MAX_CASE_BYTES)?;
            crate::case_check::check(&c).map_err(|m| invalid(&path, m))?;
            if c.spec.id() != id || c.spec.agent != *agent || c.spec.seed != a.seed {
                return Err(invalid(
                    &path,
                    format!(
                        "holds case `{}` (seed {}); expected `{id}` (seed {}): a case of another run?",
                        c.spec.id(),
                        c.spec.seed,
                        a.seed
                    ),
                ));
            }
            cases.push(c);
        }
    }
    let timing = sum_timing(&records, &settings.agents);
    let plot_errors = records.iter().flat_map(|(_, r)| r.plot_errors.iter().cloned()).collect();
    Ok(report::build(first.scenes.clone(), &settings, total, cases, timing, plot_errors))
}

/// What one record must hold before it is compared with the others: a shard `I/N` with
/// `0 <= I < N <=` [`crate::shard::MAX_SHARDS`], a horizon of positive seconds, and timings of
/// at most its own attempts over a wall time of at most [`MAX_WALL_S`].
fn check_record(file: &Path, r: &ShardRecord) -> Result<(), MergeError> {
    let crate::shard::Shard { index, count } = r.shard;
    if count == 0 || count > crate::shard::MAX_SHARDS || index >= count {
        return Err(invalid(
            file,
            format!("shard: {index}/{count}; expected I/N with 0 <= I < N <= {}", crate::shard::MAX_SHARDS),
        ));
    }
    if let crate::window::Horizon::Seconds(h) = r.settings.window.horizon {
        if !(h > 0.0 && h.is_finite()) {
            return Err(invalid(
                file,
                format!("settings.window.horizon: {h} s; expected a positive number of seconds"),
            ));
        }
    }
    for (i, t) in r.timing.iter().enumerate() {
        if t.cases > r.attempts.len() || !(0.0..=MAX_WALL_S).contains(&t.wall_s) {
            return Err(invalid(
                file,
                format!(
                    "timing[{i}]: {} cases in {} s; expected at most the record's {} attempts in 0 to {MAX_WALL_S:e} s",
                    t.cases,
                    t.wall_s,
                    r.attempts.len()
                ),
            ));
        }
    }
    Ok(())
}

/// The records are the shards of one run: same settings, shard count and attempt list, each
/// shard once, none missing.
fn check_one_run(records: &[(PathBuf, ShardRecord)]) -> Result<(), MergeError> {
    let (f0, r0) = &records[0];
    for (f, r) in &records[1..] {
        let mut fields = r0.settings.differences(&r.settings);
        if r.shard.count != r0.shard.count {
            fields.push(format!("shard count ({} vs {})", r0.shard.count, r.shard.count));
        }
        if r.attempts_digest != r0.attempts_digest || r.attempts_total != r0.attempts_total || r.scenes != r0.scenes {
            fields.push(format!(
                "attempt list ({} attempts over {}, digest {} vs {} over {}, digest {})",
                r0.attempts_total,
                r0.scenes.join(","),
                r0.attempts_digest,
                r.attempts_total,
                r.scenes.join(","),
                r.attempts_digest
            ));
        }
        if !fields.is_empty() {
            return Err(MergeError::Mixed { a: f0.clone(), b: f.clone(), fields: fields.join("; ") });
        }
    }
    let mut by_index: BTreeMap<usize, &PathBuf> = BTreeMap::new();
    for (f, r) in records {
        if let Some(prev) = by_index.insert(r.shard.index, f) {
            return Err(MergeError::Duplicate { shard: r.shard.to_string(), a: prev.clone(), b: f.clone() });
        }
    }
    let n = r0.shard.count;
    let missing: Vec<usize> = (0..n).filter(|i| !by_index.contains_key(i)).collect();
    if !missing.is_empty() {
        let mut list: Vec<String> = missing.iter().take(20).map(|i| format!("{i}/{n}")).collect();
        if missing.len() > 20 {
            list.push(format!("and {} more", missing.len() - 20));
        }
        return Err(MergeError::Missing { count: missing.len(), of: n, list: list.join(", ") });
    }
    Ok(())
}

/// Cases and wall time per agent, summed over the shards (shards may have run at once: the sum
/// is machine time, not elapsed time).
fn sum_timing(records: &[(PathBuf, ShardRecord)], agents: &[crate::spec::AgentName]) -> Vec<AgentTiming> {
    agents
        .iter()
        .map(|agent| {
            let (cases, wall_s) = records
                .iter()
                .flat_map(|(_, r)| r.timing.iter().filter(|t| t.agent == *agent))
                .fold((0, 0.0), |(c, w), t| (c + t.cases, w + t.wall_s));
            AgentTiming { agent: *agent, cases, wall_s, cases_per_s: cases as f64 / f64::max(wall_s, 1e-9) }
        })
        .collect()
}
