//! Deterministic shards of the attempt list, for runs spread over machines (Ray tasks, a Slurm
//! array). An attempt's shard depends only on its identity (scene name, behaviour, t0), never on
//! the order the scenes were given or on the other attempts' order:
//! * every attempt has a stable 64-bit key (FNV-1a of its identity, [`attempt_key`]);
//! * the attempts are ranked by their scene's hash, then their key, and the ranking is cut into N
//!   consecutive runs ([`assign`]), so the N shards are a partition of the list (union = all, no
//!   overlap), differ in size by at most one attempt (a hash modulo N leaves small lists
//!   lopsided), and each holds few scenes (a worker loads only those).
//!
//! A shard run (`eval-cases --shard I/N`) writes its per-case files as any run does, plus a
//! [`ShardRecord`] (`shard-I-of-N.json`): the settings that decide the results, a digest of the
//! whole attempt list, and its own attempts with their place in the whole list. `crate::merge`
//! reads any set of such records back into the tables one run over all attempts writes.

pub use crate::spec::attempt_key;
use crate::spec::{fnv1a, AgentName, Attempt, FNV_OFFSET};
use crate::window::Window;
use crate::AgentTiming;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// More shards than this is a typo (a 10,000-log sweep needs far fewer).
pub const MAX_SHARDS: usize = 1 << 20;

/// The shard record's format tag and version.
pub const RECORD_FORMAT: &str = "carla-gs-eval-cases-shard";
pub const RECORD_VERSION: u32 = 1;

/// Shard `index` of `count` (0-based: `0/4` .. `3/4`, as `SLURM_ARRAY_TASK_ID` with
/// `--array=0-3`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Shard {
    pub index: usize,
    pub count: usize,
}

impl std::str::FromStr for Shard {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = || format!("`{s}`: expected I/N with 0 <= I < N <= {MAX_SHARDS} (0-based, e.g. 0/4)");
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let index: usize = i.trim().parse().map_err(|_| bad())?;
        let count: usize = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || count > MAX_SHARDS || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    /// The record's file name: shards can share one output directory.
    pub fn record_name(&self) -> String {
        format!("shard-{}-of-{}.json", self.index, self.count)
    }
}

/// Each attempt's shard (same order as `attempts`): the attempts ranked by their scene name's
/// hash, then their own key (ties, which need equal keys of different attempts, by id), and the
/// ranking cut into `count` runs of equal length (+-1). A shard so holds few scenes: a worker
/// loads and keeps only those.
pub fn assign(attempts: &[Attempt], count: usize) -> Vec<usize> {
    let count = count.max(1);
    let mut order: Vec<usize> = (0..attempts.len()).collect();
    order.sort_by_cached_key(|&i| {
        let a = &attempts[i];
        (fnv1a(a.scene.as_bytes(), FNV_OFFSET), attempt_key(&a.scene, a.behavior, a.t0_s), a.id())
    });
    let mut shard = vec![0; attempts.len()];
    let n = attempts.len().max(1);
    for (rank, i) in order.into_iter().enumerate() {
        shard[i] = rank * count / n;
    }
    shard
}

/// A digest of the whole attempt list (its keys, in key order): shards of different lists do
/// not merge.
pub fn digest(attempts: &[Attempt]) -> String {
    let mut keys: Vec<u64> = attempts.iter().map(|a| attempt_key(&a.scene, a.behavior, a.t0_s)).collect();
    keys.sort_unstable();
    let h = keys.iter().fold(FNV_OFFSET, |h, k| fnv1a(&k.to_le_bytes(), h));
    format!("{h:016x}-{}", attempts.len())
}

/// What decides a run's results, compared field by field before shards are merged. `cli` holds
/// what only the binary knows (physics backend, LLM endpoint and model, a `--describe` text).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Settings {
    /// The `cases` crate version that ran it.
    pub version: String,
    pub agents: Vec<AgentName>,
    pub behaviors: Vec<scene::Behavior>,
    pub t0: String,
    pub seed: u64,
    pub window: Window,
    pub refine_rounds: usize,
    pub check_rollouts: bool,
    /// The reasoning options every case starts from (constraints, protocol, repair), as debug text.
    pub reason: String,
    pub cli: BTreeMap<String, String>,
}

impl Settings {
    /// The fields whose values differ between `self` and `other`, by name.
    pub fn differences(&self, other: &Settings) -> Vec<String> {
        let a = serde_json::to_value(self).unwrap_or_default();
        let b = serde_json::to_value(other).unwrap_or_default();
        let mut out = Vec::new();
        if let (Some(a), Some(b)) = (a.as_object(), b.as_object()) {
            for (k, va) in a {
                let vb = b.get(k).cloned().unwrap_or_default();
                if k == "cli" {
                    let keys: std::collections::BTreeSet<&String> =
                        va.as_object().into_iter().chain(vb.as_object()).flat_map(|m| m.keys()).collect();
                    out.extend(keys.into_iter().filter(|c| va.get(c) != vb.get(c)).map(|c| {
                        format!(
                            "{c} ({va_c} vs {vb_c})",
                            va_c = va.get(c).unwrap_or(&serde_json::Value::Null),
                            vb_c = vb.get(c).unwrap_or(&serde_json::Value::Null)
                        )
                    }));
                } else if *va != vb {
                    out.push(format!("{k} ({va} vs {vb})"));
                }
            }
        }
        out
    }
}

/// One attempt of a shard: its id (the case files' directory names, with the agent appended)
/// and its place in the whole attempt list (the order one run would report it in).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RecordedAttempt {
    pub id: String,
    pub position: usize,
    pub seed: u64,
}

/// What a shard run leaves beside its case files (`cases/<id>_<agent>/case.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ShardRecord {
    pub format: String,
    pub version: u32,
    pub shard: Shard,
    pub settings: Settings,
    /// Scene names of the whole run, sorted.
    pub scenes: Vec<String>,
    /// Attempts in the whole list (all shards), and the list's [`digest`].
    pub attempts_total: usize,
    pub attempts_digest: String,
    pub attempts: Vec<RecordedAttempt>,
    pub timing: Vec<AgentTiming>,
    pub plot_errors: Vec<String>,
}

impl ShardRecord {
    pub fn path(&self, out: &Path) -> PathBuf {
        out.join(self.shard.record_name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn attempt(scene: &str, b: scene::Behavior, t0: f64) -> Attempt {
        Attempt { scene_index: 0, scene: scene.into(), behavior: b, t0_s: t0, seed: 0 }
    }

    #[test]
    fn parses_shards() {
        assert_eq!("1/4".parse::<Shard>().unwrap(), Shard { index: 1, count: 4 });
        assert_eq!("0/1".parse::<Shard>().unwrap().to_string(), "0/1");
        for bad in ["4/4", "1/0", "-1/4", "1", "a/b", "1/99999999999"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }

    #[test]
    fn keys_and_digest_are_stable() {
        // Pinned: a change here moves attempts between shards of runs already under way.
        assert_eq!(
            attempt_key("s", scene::Behavior::SuddenBraking, 1.0),
            attempt_key("s", scene::Behavior::SuddenBraking, 1.0004)
        );
        assert_ne!(
            attempt_key("s", scene::Behavior::SuddenBraking, 1.0),
            attempt_key("s", scene::Behavior::SuddenBraking, 1.1)
        );
        let a =
            vec![attempt("a", scene::Behavior::SuddenBraking, 1.0), attempt("b", scene::Behavior::SuddenCutIn, 2.0)];
        let mut b = a.clone();
        b.reverse();
        assert_eq!(digest(&a), digest(&b));
        assert_ne!(digest(&a), digest(&a[..1]));
    }

    #[test]
    fn assignment_is_balanced() {
        let list: Vec<Attempt> =
            (0..103).map(|k| attempt(&format!("s{}", k % 7), scene::Behavior::ALL[k % 8], k as f64)).collect();
        let s = assign(&list, 4);
        let mut sizes = [0usize; 4];
        for x in s {
            sizes[x] += 1;
        }
        assert_eq!(sizes.iter().sum::<usize>(), 103);
        assert!(sizes.iter().max().unwrap() - sizes.iter().min().unwrap() <= 1, "{sizes:?}");
    }
}
