//! `carla-gs batch exec <plan.json> <node>`: runs one node of a plan, idempotently. A node that
//! finished leaves a stamp (`<out>/.batch/<node>.json`): its key (the node's arguments and
//! environment, a fingerprint of every input: each file's path, size and modification time,
//! hashed, and the program's: `crate::fingerprint`) and its exit code. The next exec skips the
//! node when the stamp holds the same key and every output exists; anything else (no stamp, a
//! changed input or setting, a removed output, another carla-gs binary) runs it again. Our
//! commands swap their outputs in whole, so a re-run upstream node changes its outputs' times and
//! with them every downstream key. (Workers that each hold their own copy of the binary count as
//! other programs: give them one shared file, as a Slurm job on a shared file system does.)
//!
//! Exit codes are the command's: 0 done, 3 no case possible (stamped: a final outcome, not a
//! failure to retry), 2 bad input; a killed command leaves no stamp.

use super::plan::{Node, Plan, PLAN_FORMAT, PLAN_VERSION};
use super::BatchError;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::time::Instant;

pub const STAMP_DIR: &str = ".batch";
/// A plan larger than this is not one (100k logs x 4 stages is about 200 MB: split it).
pub const MAX_PLAN_BYTES: u64 = 1 << 30;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Stamp {
    pub key: Value,
    pub exit_code: i32,
    pub seconds: f64,
}

/// What `exec` did.
#[derive(Debug)]
pub enum Outcome {
    /// Finished before with the same inputs and settings: its stamp.
    Skipped(Stamp),
    /// Ran now, with this exit code.
    Ran { exit_code: i32, seconds: f64 },
}

/// The `carla-gs` commands a plan's nodes run (`super::plan`): never `batch` itself, which
/// (`batch exec` of the node's own plan) would recurse without bound.
pub const NODE_COMMANDS: [&str; 6] = ["ingest", "priors", "train", "eval-cases", "tables", "run"];

/// Refuses a node whose command is not one of [`NODE_COMMANDS`] (a hand-edited plan).
pub fn check_command(node: &Node) -> Result<(), BatchError> {
    match node.args.first().map(String::as_str) {
        Some(c) if NODE_COMMANDS.contains(&c) => Ok(()),
        other => Err(BatchError::Node {
            node: node.id.clone(),
            message: format!(
                "runs `carla-gs {}`; a plan's node runs one of {} (a hand-edited plan?)",
                other.unwrap_or(""),
                NODE_COMMANDS.join(", ")
            ),
        }),
    }
}

pub fn read_plan(file: &Path) -> Result<Plan, BatchError> {
    let bytes = scene::input::read_capped(file, MAX_PLAN_BYTES, "a batch plan")?;
    let plan: Plan = serde_json::from_slice(&bytes).map_err(|e| BatchError::invalid(file, e.to_string()))?;
    if plan.format != PLAN_FORMAT || plan.version != PLAN_VERSION {
        return Err(BatchError::invalid(
            file,
            format!("format {} v{}; expected {PLAN_FORMAT} v{PLAN_VERSION}", plan.format, plan.version),
        ));
    }
    Ok(plan)
}

/// The node named `id`, or the `index`-th node of `stage`.
pub fn find<'a>(plan: &'a Plan, id: Option<&str>, stage: Option<(&str, usize)>) -> Result<&'a Node, BatchError> {
    let found = match (id, stage) {
        (Some(id), _) => plan.nodes.iter().find(|n| n.id == id),
        (None, Some((s, i))) => plan.nodes.iter().find(|n| n.stage == s && n.index == i),
        (None, None) => None,
    };
    found.ok_or_else(|| BatchError::Node {
        node: id.map_or_else(|| stage.map_or(String::new(), |(s, i)| format!("{s}[{i}]")), str::to_string),
        message: format!("not in the plan (its stages: {})", plan.stages.join(", ")),
    })
}

/// `path`'s fingerprint (`crate::fingerprint::folder`), our stamps and temporary files left out.
fn fingerprint(node: &str, path: &Path) -> Result<Value, BatchError> {
    let ours = |p: &Path| p.file_name().and_then(|n| n.to_str()).is_some_and(|n| n == STAMP_DIR || n.ends_with(".tmp"));
    crate::fingerprint::folder(path, ours).map_err(|e| BatchError::Node {
        node: node.into(),
        message: match e {
            crate::fingerprint::FingerprintError::Missing(_) => {
                format!("input {} does not exist (has the node making it run?)", path.display())
            }
            e => format!("input {e}"),
        },
    })
}

/// The node's key: what it runs and what it reads.
pub fn key(node: &Node) -> Result<Value, BatchError> {
    let inputs = node.inputs.iter().map(|p| fingerprint(&node.id, p)).collect::<Result<Vec<_>, _>>()?;
    Ok(json!({ "args": node.args, "env": node.env, "inputs": inputs, "program": crate::fingerprint::program() }))
}

pub fn stamp_path(plan: &Plan, node: &Node) -> PathBuf {
    plan.out.join(STAMP_DIR).join(format!("{}.json", node.id.replace('/', "__")))
}

fn read_stamp(plan: &Plan, node: &Node) -> Option<Stamp> {
    // A stamp is a few hundred bytes; anything else (a FIFO, a huge file) is no stamp.
    let text = scene::input::read_capped(&stamp_path(plan, node), 1 << 20, "a batch stamp").ok()?;
    serde_json::from_slice(&text).ok()
}

/// The node's stamp, if it finished from `key` and its outputs are all there.
pub fn fresh(plan: &Plan, node: &Node, key: &Value) -> Option<Stamp> {
    read_stamp(plan, node).filter(|s| s.key == *key && node.outputs.iter().all(|o| o.exists()))
}

/// Runs `node` with `program` (the `carla-gs` binary) unless it is fresh; its dependencies must
/// have finished.
pub fn exec(plan: &Plan, node: &Node, program: &Path) -> Result<Outcome, BatchError> {
    for dep in &node.deps {
        let d = find(plan, Some(dep), None)?;
        if read_stamp(plan, d).is_none_or(|s| s.exit_code != 0) {
            return Err(BatchError::Node {
                node: node.id.clone(),
                message: format!("its dependency {dep} has not finished (no stamp with exit code 0)"),
            });
        }
    }
    let key = key(node)?;
    if let Some(s) = fresh(plan, node, &key) {
        return Ok(Outcome::Skipped(s));
    }
    let stamp_file = stamp_path(plan, node);
    let _ = std::fs::remove_file(&stamp_file);
    let start = Instant::now();
    let status = std::process::Command::new(program)
        .args(&node.args)
        .envs(&node.env)
        .status()
        .map_err(|e| BatchError::Node { node: node.id.clone(), message: format!("{}: {e}", program.display()) })?;
    let seconds = start.elapsed().as_secs_f64();
    // A signal leaves no code: reported as -1, never stamped.
    let exit_code = status.code().unwrap_or(-1);
    let done = exit_code == 0 && node.outputs.iter().all(|o| o.exists());
    if exit_code == 0 && !done {
        return Err(BatchError::Node {
            node: node.id.clone(),
            message: "the command exited 0 without writing its outputs".into(),
        });
    }
    if done || exit_code == 3 {
        let stamp = Stamp { key, exit_code, seconds };
        let text = serde_json::to_vec_pretty(&stamp).map_err(|e| BatchError::invalid(&stamp_file, e.to_string()))?;
        scene::write_file_atomic(&stamp_file, &text)?;
    }
    Ok(Outcome::Ran { exit_code, seconds })
}
