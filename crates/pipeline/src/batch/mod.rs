//! Batch runs over many logs on an existing cluster engine (Ray, Slurm): the Rust side only
//! turns a manifest into an engine-neutral plan and runs one node of it, idempotently.
//! * [`budget`]: how many shards and nodes, and how large, a plan may be;
//! * [`manifest`]: the TOML a user writes (logs to ingest, which stages to run and how);
//! * [`plan`]: the JSON graph of plain `carla-gs` commands with their inputs, outputs,
//!   dependencies and resources (CPU cores, GPUs, memory) that `tools/batch_ray.py` (one Ray
//!   task per node) or its `--slurm` script (one `sbatch --array` per stage) schedules;
//! * [`node`]: `carla-gs batch exec`: runs a node unless its stamp says it already finished
//!   from the same inputs and settings.
//!
//! No scheduler lives here: order, placement and retries are the engine's.

pub mod budget;
pub mod checks;
pub mod manifest;
pub mod node;
pub mod plan;
pub mod plan_node;

/// What can go wrong reading a manifest or a plan, or running a node.
#[derive(Debug, thiserror::Error)]
pub enum BatchError {
    #[error("{file}: {message}")]
    Invalid { file: std::path::PathBuf, message: String },
    #[error(transparent)]
    Scene(#[from] scene::SceneError),
    #[error("{node}: {message}")]
    Node { node: String, message: String },
}

impl BatchError {
    pub fn invalid(file: &std::path::Path, message: impl Into<String>) -> Self {
        BatchError::Invalid { file: file.to_path_buf(), message: message.into() }
    }
}
