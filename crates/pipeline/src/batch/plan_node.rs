//! One node of a batch plan (`plan`): its `carla-gs` command, environment, inputs, outputs,
//! dependencies and the resources it asks for. Below the plan's builder and the budget that
//! sizes it (`budget`).

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Resources {
    pub cpus: u32,
    pub gpus: u32,
    pub memory_gb: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Node {
    /// `stage/name`, unique.
    pub id: String,
    pub stage: String,
    /// Position within its stage (the `SLURM_ARRAY_TASK_ID` of its array job).
    pub index: usize,
    /// The `carla-gs` arguments (without the program name).
    pub args: Vec<String>,
    pub env: BTreeMap<String, String>,
    pub inputs: Vec<PathBuf>,
    pub outputs: Vec<PathBuf>,
    pub deps: Vec<String>,
    pub resources: Resources,
}
