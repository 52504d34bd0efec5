//! `eval-drive`: many cases (run directories of one scene) driven by many policies, one episode
//! each, into one table per behaviour and policy: episodes, failures, collisions, collision
//! rate, mean NCAP score, mean MinTTC, mean smallest gap. Every (case, policy) pair is an
//! attempt and every attempt is counted: an episode that fails (a policy that dies, say) is a
//! row of `drive-eval.json` with its error, counted under "failed", never dropped. The attempt
//! list is cut into deterministic shards (`--shard I/N`: attempt k goes to shard k mod N) and
//! `drive-tables` merges the shards' `drive-eval.json` files into the table one run gives.

use crate::error::DriveError;
use crate::scores::Scores;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt::Write;
use std::path::{Path, PathBuf};

pub const EVAL_FORMAT: &str = "carla-gs-drive-eval/1";

/// One attempt's outcome.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Record {
    /// The case's name (its run directory's name) and behaviour, the policy.
    pub case: String,
    pub behavior: String,
    pub policy: String,
    /// The attempt's index in the whole list (before sharding).
    pub index: usize,
    /// The episode directory (relative to the eval directory), when it was written.
    pub episode: Option<String>,
    pub scores: Option<Scores>,
    /// Drawing plus deciding, seconds per tick (mean).
    pub step_s: Option<f64>,
    /// Why the episode failed, when it did.
    pub error: Option<String>,
}

/// `drive-eval.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EvalFile {
    pub format: String,
    pub scene: String,
    /// `I/N` of the attempts, or `all`.
    pub shard: String,
    pub attempts: usize,
    pub records: Vec<Record>,
}

/// The (case, policy) attempts in order: every case with every policy.
pub fn attempts(cases: usize, policies: usize) -> Vec<(usize, usize)> {
    (0..cases).flat_map(|c| (0..policies).map(move |p| (c, p))).collect()
}

/// Whether attempt `index` belongs to shard `i` of `n`.
pub fn in_shard(index: usize, shard: Option<(usize, usize)>) -> bool {
    shard.is_none_or(|(i, n)| index % n == i)
}

/// Parses `I/N` (0 <= I < N <= 10000).
pub fn parse_shard(text: &str) -> Result<(usize, usize), DriveError> {
    let bad = || DriveError::settings("--shard", format!("expected I/N with 0 <= I < N <= 10000, got `{text}`"));
    let (i, n) = text.split_once('/').ok_or_else(bad)?;
    let (i, n) = (i.trim().parse::<usize>().map_err(|_| bad())?, n.trim().parse::<usize>().map_err(|_| bad())?);
    if n == 0 || i >= n || n > 10_000 {
        return Err(bad());
    }
    Ok((i, n))
}

/// One row of the table: a behaviour and a policy.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Row {
    pub behavior: String,
    pub policy: String,
    pub episodes: usize,
    pub failed: usize,
    pub collisions: usize,
    /// Episodes in which a replayed road user ran into the ego from behind (not collisions).
    pub rear_ended: usize,
    /// Collisions over finished episodes.
    pub collision_rate: Option<f64>,
    pub ncap_mean: Option<f64>,
    pub min_ttc_mean_s: Option<f64>,
    pub min_gap_mean_m: Option<f64>,
}

fn mean(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

/// The table of `records`, per behaviour then policy, in the order they first appear.
pub fn table(records: &[Record]) -> Vec<Row> {
    let mut order: Vec<(String, String)> = Vec::new();
    let mut groups: BTreeMap<(String, String), Vec<&Record>> = BTreeMap::new();
    for r in records {
        let key = (r.behavior.clone(), r.policy.clone());
        if !groups.contains_key(&key) {
            order.push(key.clone());
        }
        groups.entry(key).or_default().push(r);
    }
    let behaviours: Vec<String> = order.iter().map(|k| k.0.clone()).collect();
    order.sort_by_key(|k| behaviours.iter().position(|b| *b == k.0));
    order
        .into_iter()
        .map(|key| {
            let rs = &groups[&key];
            let done: Vec<&Scores> = rs.iter().filter_map(|r| r.scores.as_ref()).collect();
            let collisions = done.iter().filter(|s| s.collision).count();
            let values = |f: &dyn Fn(&Scores) -> Option<f64>| done.iter().filter_map(|s| f(s)).collect::<Vec<_>>();
            Row {
                behavior: key.0.clone(),
                policy: key.1.clone(),
                episodes: rs.len(),
                failed: rs.len() - done.len(),
                collisions,
                rear_ended: done.iter().filter(|s| !s.rear_ended.is_empty()).count(),
                collision_rate: (!done.is_empty()).then(|| collisions as f64 / done.len() as f64),
                ncap_mean: mean(&values(&|s| Some(s.ncap_score))),
                min_ttc_mean_s: mean(&values(&|s| s.min_ttc_s)),
                min_gap_mean_m: mean(&values(&|s| s.min_gap_m)),
            }
        })
        .collect()
}

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".into(), |v| format!("{v:.digits$}"))
}

pub fn markdown(rows: &[Row]) -> String {
    let mut s = String::from(
        "| behaviour | policy | episodes | failed | collisions | collision rate | NCAP score | MinTTC (s) | min gap (m) | rear-ended by replay |\n\
         |---|---|---|---|---|---|---|---|---|---|\n",
    );
    for r in rows {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.behavior,
            r.policy,
            r.episodes,
            r.failed,
            r.collisions,
            r.collision_rate.map_or("-".into(), |v| format!("{:.0} %", 100.0 * v)),
            opt(r.ncap_mean, 2),
            opt(r.min_ttc_mean_s, 2),
            opt(r.min_gap_mean_m, 2),
            r.rear_ended
        );
    }
    s
}

pub fn csv(rows: &[Row]) -> String {
    let mut s = String::from("behavior,policy,episodes,failed,collisions,collision_rate,ncap_mean,min_ttc_mean_s,min_gap_mean_m,rear_ended\n");
    for r in rows {
        let f = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v}"));
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{}",
            r.behavior,
            r.policy,
            r.episodes,
            r.failed,
            r.collisions,
            f(r.collision_rate),
            f(r.ncap_mean),
            f(r.min_ttc_mean_s),
            f(r.min_gap_mean_m),
            r.rear_ended
        );
    }
    s
}

/// Writes `table.md`, `table.csv` and `drive-eval.json` into `dir`.
pub fn write_tables(dir: &Path, file: &EvalFile) -> Result<Vec<Row>, DriveError> {
    let rows = table(&file.records);
    scene::format::write_json_pretty(&dir.join("drive-eval.json"), file)?;
    for (name, text) in [("table.md", markdown(&rows)), ("table.csv", csv(&rows))] {
        scene::output::write_file_atomic(&dir.join(name), text.as_bytes())?;
    }
    Ok(rows)
}

/// The records of several shard directories as one run's: every shard of one scene and one
/// attempt list, no attempt twice.
pub fn merge(dirs: &[PathBuf]) -> Result<EvalFile, DriveError> {
    let mut merged: Option<EvalFile> = None;
    let mut seen = std::collections::BTreeSet::new();
    for d in dirs {
        let path = d.join("drive-eval.json");
        let f: EvalFile = scene::format::read_json(&path)?;
        if f.format != EVAL_FORMAT {
            return Err(DriveError::settings(
                path.display().to_string(),
                format!("format must be \"{EVAL_FORMAT}\", got \"{}\"", f.format),
            ));
        }
        for r in &f.records {
            if !seen.insert(r.index) {
                return Err(DriveError::settings(
                    path.display().to_string(),
                    format!("attempt {} ({} with {}) is in two shards", r.index, r.case, r.policy),
                ));
            }
        }
        match &mut merged {
            None => merged = Some(EvalFile { shard: "merged".into(), ..f }),
            Some(m) => {
                if m.scene != f.scene || m.attempts != f.attempts {
                    return Err(DriveError::settings(
                        path.display().to_string(),
                        format!(
                            "is of scene `{}` with {} attempts, the others of `{}` with {}",
                            f.scene, f.attempts, m.scene, m.attempts
                        ),
                    ));
                }
                m.records.extend(f.records);
            }
        }
    }
    let mut m = merged.ok_or_else(|| DriveError::settings("drive-tables", "no shard directory given"))?;
    m.records.sort_by_key(|r| r.index);
    if m.records.len() != m.attempts {
        eprintln!("note: {} of {} attempts are in the shards given", m.records.len(), m.attempts);
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn record(index: usize, behavior: &str, policy: &str, collision: Option<bool>) -> Record {
        let scores = collision.map(|c| Scores {
            collision: c,
            contact: None,
            rear_ended: vec![],
            ncap_score: if c { 1.0 } else { 5.0 },
            reference_impact_speed: Some(8.0),
            min_ttc_s: Some(if c { 0.0 } else { 2.0 }),
            t_min_ttc_s: Some(1.0),
            min_ttc_box_s: None,
            min_gap_m: Some(1.0),
            comfort: None,
            max_decel: 0.0,
            max_abs_accel_lat: 0.0,
        });
        let error = collision.is_none().then(|| "the policy ended".to_string());
        Record {
            case: format!("c{index}"),
            behavior: behavior.into(),
            policy: policy.into(),
            index,
            episode: None,
            scores,
            step_s: None,
            error,
        }
    }

    #[test]
    fn every_attempt_is_counted_and_shards_cover_the_list_once() {
        let recs = vec![
            record(0, "sudden_braking", "log", Some(true)),
            record(1, "sudden_braking", "idm-aeb", Some(false)),
            record(2, "opposing_drift", "log", Some(true)),
            record(3, "sudden_braking", "log", None),
        ];
        let rows = table(&recs);
        assert_eq!(rows.len(), 3);
        let log = &rows[0];
        assert_eq!((log.behavior.as_str(), log.policy.as_str()), ("sudden_braking", "log"));
        assert_eq!((log.episodes, log.failed, log.collisions), (2, 1, 1));
        assert_eq!(log.collision_rate, Some(1.0));
        assert_eq!(rows[1].ncap_mean, Some(5.0));
        assert_eq!(rows[2].behavior, "opposing_drift");
        let n = attempts(5, 3).len();
        let covered: usize = (0..4).map(|i| (0..n).filter(|k| in_shard(*k, Some((i, 4)))).count()).sum();
        assert_eq!(covered, n);
        assert_eq!(parse_shard("1/4").unwrap(), (1, 4));
        for bad in ["4/4", "1", "a/b", "0/0", "-1/3"] {
            assert!(parse_shard(bad).is_err(), "{bad}");
        }
    }
}
