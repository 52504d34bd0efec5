//! The size budgets of a batch plan, checked before anything is written (and, for the plan's
//! nodes, before each is kept): a manifest of a few lines asked for a million `[eval_cases]`
//! shards and got a 906 MB `plan.json` (every shard node lists every scene, and the `tables` node
//! every shard). The limits sit far above real use and say how to split the work instead:
//!
//! * [`MAX_SHARDS_PER_LOG`]: a log's sweep is a few hundred to a few thousand attempts (agents x
//!   behaviours x t0 x seeds), so more than 1,000 shards per log are nodes with nothing to do;
//! * [`MAX_PLAN_SHARDS`]: 10,000 shard nodes in one plan (Slurm's default `MaxArraySize` is
//!   1,001; the `tables` node names every shard directory on one command line);
//! * [`MAX_PLAN_NODES`]: a million nodes (100,000 logs through ingest, priors, train and several
//!   behaviours; counted from the manifest before any node is made);
//! * [`MAX_PLAN_BYTES`]: 256 MiB of plan JSON (a 1,000-log plan is a few MB), counted node by node
//!   as the plan is built, so a huge `args` list repeated on every node is refused too.

use super::plan_node::Node;
use super::BatchError;
use std::path::{Path, PathBuf};

/// Most `[eval_cases] shards` per log.
pub const MAX_SHARDS_PER_LOG: usize = 1_000;
/// Most `[eval_cases] shards` in one plan.
pub const MAX_PLAN_SHARDS: usize = 10_000;
/// Most nodes in one plan.
pub const MAX_PLAN_NODES: usize = 1_000_000;
/// Largest plan (JSON bytes, as written pretty-printed, approximately).
pub const MAX_PLAN_BYTES: u64 = 256 << 20;

/// The largest shard count a manifest of `logs` logs may ask for.
pub fn max_shards(logs: usize) -> usize {
    MAX_PLAN_SHARDS.min(MAX_SHARDS_PER_LOG.saturating_mul(logs.max(1)))
}

/// Counts a plan's nodes and bytes as they are made, refusing past the budget; errors name the
/// manifest.
pub struct Sizer {
    file: PathBuf,
    bytes: u64,
    max_bytes: u64,
}

/// A `Write` that only counts.
struct Count(u64);

impl std::io::Write for Count {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0 += buf.len() as u64;
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl Sizer {
    /// A plan of `nodes` nodes for the manifest `file` (refused past [`MAX_PLAN_NODES`]).
    pub fn new(file: &Path, nodes: usize) -> Result<Sizer, BatchError> {
        if nodes > MAX_PLAN_NODES {
            return Err(BatchError::invalid(
                file,
                format!("the plan would have {nodes} nodes; at most {MAX_PLAN_NODES} fit in one plan: split the logs into several manifests"),
            ));
        }
        Ok(Sizer { file: file.to_path_buf(), bytes: 0, max_bytes: MAX_PLAN_BYTES })
    }

    /// The same with another byte budget (tests).
    pub fn with_max_bytes(mut self, max_bytes: u64) -> Sizer {
        self.max_bytes = max_bytes;
        self
    }

    /// Keeps `node` in `v` if the plan stays within [`MAX_PLAN_BYTES`].
    pub fn push(&mut self, v: &mut Vec<Node>, node: Node) -> Result<(), BatchError> {
        let mut c = Count(0);
        serde_json::to_writer_pretty(&mut c, &node)
            .map_err(|e| BatchError::invalid(&self.file, format!("node {}: {e}", node.id)))?;
        // Pretty-printed inside `nodes`, each line is indented by four more spaces.
        let lines = node.args.len() + node.inputs.len() + node.outputs.len() + node.deps.len() + node.env.len() + 20;
        self.bytes += c.0 + 4 * lines as u64;
        if self.bytes > self.max_bytes {
            return Err(BatchError::invalid(
                &self.file,
                format!(
                    "the plan would be more than {} bytes of JSON (at node {}, {} nodes in); \
                     split the logs into several manifests or ask for fewer shards, behaviours or arguments",
                    self.max_bytes,
                    node.id,
                    v.len()
                ),
            ));
        }
        v.push(node);
        Ok(())
    }
}

/// The bytes `args` take on a command line (each with its terminating NUL).
pub fn argv_bytes(args: &[String]) -> usize {
    args.iter().map(|a| a.len() + 1).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::batch::manifest::Manifest;

    fn read(dir: &Path, text: &str) -> Result<Manifest, String> {
        let f = dir.join("m.toml");
        std::fs::write(&f, text).unwrap();
        Manifest::read(&f).map_err(|e| e.to_string())
    }

    fn logs(n: usize) -> String {
        (0..n).map(|i| format!("[[log]]\nname = \"l{i}\"\nscene = \"s{i}\"\n")).collect()
    }

    #[test]
    fn a_million_shards_per_log_is_refused_before_any_plan_is_made() {
        let d = tempfile::tempdir().unwrap();
        for (n_logs, shards, said) in [
            (1, 1_000_000, "shards = 1000000: expected 1 to 1000 for 1 log(s)"),
            (1, 1_001, "shards = 1001: expected 1 to 1000 for 1 log(s)"),
            (3, 3_001, "expected 1 to 3000 for 3 log(s)"),
            (20, 10_001, "expected 1 to 10000 for 20 log(s)"),
        ] {
            let e = read(d.path(), &format!("{}[eval_cases]\nshards = {shards}\n", logs(n_logs))).unwrap_err();
            assert!(e.contains("m.toml") && e.contains(said), "{e}");
        }
        let m = read(d.path(), &format!("{}[eval_cases]\nshards = 1000\n", logs(1))).unwrap();
        let p = crate::batch::plan::build(&m, &d.path().join("m.toml"), &d.path().join("out")).unwrap();
        assert_eq!(p.nodes.len(), 1001);
    }

    #[test]
    fn too_many_nodes_or_bytes_are_refused_naming_the_manifest() {
        let f = Path::new("/x/m.toml");
        let e = Sizer::new(f, MAX_PLAN_NODES + 1).err().unwrap().to_string();
        assert!(e.contains("/x/m.toml") && e.contains("1000001 nodes"), "{e}");
        let mut s = Sizer::new(f, 10).unwrap().with_max_bytes(4_000);
        let node = |i: usize| Node {
            id: format!("run/{i}"),
            stage: "run".into(),
            index: i,
            args: vec!["x".repeat(1_000)],
            env: Default::default(),
            inputs: vec![],
            outputs: vec![],
            deps: vec![],
            resources: super::super::plan::Resources { cpus: 1, gpus: 0, memory_gb: 1.0 },
        };
        let mut v = Vec::new();
        let mut refused = None;
        for i in 0..10 {
            if let Err(e) = s.push(&mut v, node(i)) {
                refused = Some(e.to_string());
                break;
            }
        }
        let e = refused.expect("the byte budget was never hit");
        assert!(e.contains("more than 4000 bytes") && e.contains("/x/m.toml"), "{e}");
        assert!(v.len() >= 2 && v.len() < 4, "{} nodes kept", v.len());
    }

    #[test]
    fn the_tables_command_line_is_bounded() {
        let d = tempfile::tempdir().unwrap();
        let m = read(d.path(), &format!("{}[eval_cases]\nshards = 10000\n", logs(10))).unwrap();
        let long = d.path().join("o".repeat(200));
        let e = crate::batch::plan::build(&m, &d.path().join("m.toml"), &long).err().unwrap().to_string();
        assert!(e.contains("tables command line") && e.contains("m.toml"), "{e}");
    }
}
