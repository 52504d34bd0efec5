//! The batch manifest (TOML): the logs and the stages to run on them. Paths are relative to the
//! manifest's directory. Example (docs/batch.md has the whole reference):
//!
//! ```toml
//! [[log]]
//! name = "womd-a"                       # unique; names the log's output directories
//! input = "data/womd_a.tfrecord"        # anything `carla-gs ingest` reads (or a list)
//!
//! [[log]]
//! name = "street"
//! scene = "scenes/street"               # an existing scene directory: no ingest
//!
//! [train]                               # optional: one model per log
//! device = "cuda"
//! config = "configs/real-street-gpu.toml"
//!
//! [eval_cases]                          # optional: one sweep over every log, in shards
//! agents = "planner"
//! t0 = "every:1s"
//! shards = 4
//!
//! [run]                                 # optional: one `run` per log and behaviour
//! behaviors = ["sudden_cut_in"]
//! ```
//!
//! Every count read here (logs, shards, behaviours, resources) is checked against a budget
//! (shards: `super::budget`).

use super::BatchError;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// More logs than this in one manifest: split it (a plan node per log and stage).
pub const MAX_LOGS: usize = 100_000;
/// A manifest larger than this is not one.
pub const MAX_MANIFEST_BYTES: u64 = 64 << 20;
/// Per-node resources beyond these are typos.
pub const MAX_CPUS: u32 = 1024;
pub const MAX_GPUS: u32 = 64;
pub const MAX_MEMORY_GB: f64 = 65_536.0;

#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum OneOrMany {
    One(PathBuf),
    Many(Vec<PathBuf>),
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Log {
    pub name: String,
    /// Files or folders for `carla-gs ingest`.
    pub input: Option<OneOrMany>,
    /// `--format` for ingest (detected from the content when absent).
    pub format: Option<String>,
    /// An existing scene directory (instead of `input`).
    pub scene: Option<PathBuf>,
}

impl Log {
    pub fn inputs(&self) -> Vec<PathBuf> {
        match &self.input {
            None => Vec::new(),
            Some(OneOrMany::One(p)) => vec![p.clone()],
            Some(OneOrMany::Many(v)) => v.clone(),
        }
    }
}

/// Resources a stage's nodes ask the engine for (defaults per stage in [`super::plan`]).
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Resources {
    pub cpus: Option<u32>,
    pub gpus: Option<u32>,
    pub memory_gb: Option<f64>,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Priors {
    #[serde(default)]
    pub args: Vec<String>,
    #[serde(flatten)]
    pub resources: Resources,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Train {
    /// `cpu` or `cuda`.
    pub device: Option<String>,
    pub config: Option<PathBuf>,
    pub iters: Option<usize>,
    pub scale: Option<f64>,
    pub seed: Option<u64>,
    #[serde(default)]
    pub args: Vec<String>,
    #[serde(flatten)]
    pub resources: Resources,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EvalCases {
    pub agents: Option<String>,
    pub behaviors: Option<String>,
    pub t0: Option<String>,
    pub seed: Option<u64>,
    pub horizon: Option<String>,
    /// Shards of the attempt list (one node each).
    pub shards: Option<usize>,
    #[serde(default)]
    pub args: Vec<String>,
    #[serde(flatten)]
    pub resources: Resources,
}

#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Run {
    pub behaviors: Vec<String>,
    pub agent: Option<String>,
    pub seed: Option<u64>,
    #[serde(default)]
    pub args: Vec<String>,
    #[serde(flatten)]
    pub resources: Resources,
}

#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    #[serde(rename = "log", default)]
    pub logs: Vec<Log>,
    pub priors: Option<Priors>,
    pub train: Option<Train>,
    pub eval_cases: Option<EvalCases>,
    pub run: Option<Run>,
}

/// A log name becomes a directory name: letters, digits, `.`, `_`, `-`, at most 100.
fn valid_name(n: &str) -> bool {
    !n.is_empty()
        && n.len() <= 100
        && !n.starts_with('.')
        && n.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '.' | '_' | '-'))
}

fn check_resources(file: &Path, stage: &str, r: &Resources) -> Result<(), BatchError> {
    let bad = |what: &str| BatchError::invalid(file, format!("[{stage}] {what}"));
    if r.cpus.is_some_and(|c| c == 0 || c > MAX_CPUS) {
        return Err(bad(&format!("cpus: expected 1 to {MAX_CPUS}")));
    }
    if r.gpus.is_some_and(|g| g > MAX_GPUS) {
        return Err(bad(&format!("gpus: expected 0 to {MAX_GPUS}")));
    }
    if r.memory_gb.is_some_and(|m| !(m > 0.0 && m <= MAX_MEMORY_GB)) {
        return Err(bad(&format!("memory_gb: expected a number in (0, {MAX_MEMORY_GB}]")));
    }
    Ok(())
}

impl Manifest {
    /// The shape checks of [`Manifest::read`] (`checks` adds the values').
    pub(super) fn check(&self, file: &Path) -> Result<(), BatchError> {
        let bad = |m: String| BatchError::invalid(file, m);
        if self.logs.is_empty() {
            return Err(bad("no [[log]]: nothing to run".into()));
        }
        if self.logs.len() > MAX_LOGS {
            return Err(bad(format!("{} logs; expected at most {MAX_LOGS} (split the manifest)", self.logs.len())));
        }
        let mut seen = std::collections::BTreeSet::new();
        for (i, l) in self.logs.iter().enumerate() {
            if !valid_name(&l.name) {
                return Err(bad(format!(
                    "log[{i}].name `{}`: expected 1-100 of A-Z a-z 0-9 . _ - (not starting with .)",
                    l.name
                )));
            }
            if !seen.insert(l.name.as_str()) {
                return Err(bad(format!("log[{i}].name `{}` is used twice", l.name)));
            }
            match (l.inputs().is_empty(), &l.scene) {
                (true, None) => return Err(bad(format!("log `{}`: give `input` (to ingest) or `scene`", l.name))),
                (false, Some(_)) => return Err(bad(format!("log `{}`: give `input` or `scene`, not both", l.name))),
                _ => {}
            }
        }
        if self.priors.is_none() && self.train.is_none() && self.eval_cases.is_none() && self.run.is_none() {
            return Err(bad("no stage ([priors], [train], [eval_cases] or [run]): nothing to run".into()));
        }
        if let Some(p) = &self.priors {
            check_resources(file, "priors", &p.resources)?;
        }
        if let Some(t) = &self.train {
            check_resources(file, "train", &t.resources)?;
            if let Some(d) = &t.device {
                if d != "cpu" && d != "cuda" {
                    return Err(bad(format!("[train] device `{d}`: expected cpu or cuda")));
                }
            }
        }
        if let Some(e) = &self.eval_cases {
            check_resources(file, "eval_cases", &e.resources)?;
            let n = e.shards.unwrap_or(1);
            let most = super::budget::max_shards(self.logs.len()).min(cases::shard::MAX_SHARDS);
            if n == 0 || n > most {
                return Err(bad(format!(
                    "[eval_cases] shards = {n}: expected 1 to {most} for {} log(s) (at most {} per log and {} in \
                     all; more shards than attempts are empty nodes)",
                    self.logs.len(),
                    super::budget::MAX_SHARDS_PER_LOG,
                    super::budget::MAX_PLAN_SHARDS
                )));
            }
        }
        if let Some(r) = &self.run {
            check_resources(file, "run", &r.resources)?;
            if self.train.is_none() {
                return Err(bad("[run] renders with each log's model: add a [train] stage".into()));
            }
            if r.behaviors.is_empty() || r.behaviors.len() > 64 {
                return Err(bad("[run] behaviors: expected 1 to 64 behaviours".into()));
            }
            for b in &r.behaviors {
                b.parse::<scene::Behavior>().map_err(|e| bad(format!("[run] behaviors: {e}")))?;
            }
        }
        Ok(())
    }

    /// `p` relative to the manifest's directory (absolute paths stay).
    pub fn resolve(base: &Path, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            base.join(p)
        }
    }
}
