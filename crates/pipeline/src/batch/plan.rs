//! The batch plan: an engine-neutral JSON graph of plain `carla-gs` commands, made from a
//! manifest. Nodes come in dependency order (every node after the nodes it needs), each with
//! absolute paths (a cluster's workers see the same shared file system), its inputs (what its
//! stamp fingerprints), outputs, dependencies and resources. Stages and their nodes:
//!
//! | stage | nodes | command | needs |
//! |---|---|---|---|
//! | `ingest` | one per log with `input` | `ingest <input>... --out <out>/scenes/<log> --force` | - |
//! | `priors` | one per log | `priors <scene> --force` | its ingest |
//! | `train` | one per log | `train <scene> --out <out>/models/<log> --force --device ...` | its ingest, priors |
//! | `eval_cases` | one per shard | `eval-cases <every scene> --shard I/N --out <out>/eval/shard-I-of-N --force` | every ingest |
//! | `tables` | one | `tables <every shard dir> --out <out>/tables` | every shard |
//! | `run` | one per log and behaviour | `run <scene> --model <model> --behavior B --out <out>/runs/<log>/<B>` | its train |
//!
//! CPU nodes get `RAYON_NUM_THREADS` = their cores, so packed workers do not oversubscribe.
//! The node count, each node and the plan's size are held to `super::budget` as the plan is made.

use super::budget::{argv_bytes, Sizer};
use super::manifest::{Manifest, Resources as Asked};
pub use super::plan_node::{Node, Resources};
use super::BatchError;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

pub const PLAN_FORMAT: &str = "carla-gs-batch-plan";
pub const PLAN_VERSION: u32 = 1;
pub const PLAN_FILE: &str = "plan.json";
/// A command line longer than this may not start (Linux allows 2 MiB of arguments and
/// environment together).
pub const MAX_ARGV_BYTES: usize = 1 << 20;

impl Resources {
    fn from(asked: &Asked, cpus: u32, gpus: u32, memory_gb: f64) -> Self {
        Resources {
            cpus: asked.cpus.unwrap_or(cpus),
            gpus: asked.gpus.unwrap_or(gpus),
            memory_gb: asked.memory_gb.unwrap_or(memory_gb),
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Plan {
    pub format: String,
    pub version: u32,
    pub manifest: PathBuf,
    pub out: PathBuf,
    /// Stage names in dependency order (each stage's nodes need only earlier stages).
    pub stages: Vec<String>,
    pub nodes: Vec<Node>,
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

fn cpu_env(r: &Resources) -> BTreeMap<String, String> {
    BTreeMap::from([("RAYON_NUM_THREADS".to_string(), r.cpus.to_string())])
}

/// The plan of `manifest` (read from `manifest_file`), writing under `out`.
pub fn build(manifest: &Manifest, manifest_file: &Path, out: &Path) -> Result<Plan, BatchError> {
    let abs = |p: &Path| std::path::absolute(p).map_err(|e| BatchError::from(scene::SceneError::io(p, e)));
    let manifest_file = abs(manifest_file)?;
    let base = manifest_file.parent().unwrap_or(Path::new("/")).to_path_buf();
    let out = abs(out)?;
    let mut sizer = Sizer::new(&manifest_file, node_count(manifest))?;
    let mut nodes: Vec<Node> = Vec::new();
    let mut stages = Vec::new();
    // Each log's scene directory and the node (if any) that makes it.
    let mut scenes: Vec<(String, PathBuf, Option<String>)> = Vec::new();
    let mut ingest = Vec::new();
    for l in &manifest.logs {
        match &l.scene {
            Some(dir) => scenes.push((l.name.clone(), Manifest::resolve(&base, dir), None)),
            None => {
                let dir = out.join("scenes").join(&l.name);
                let inputs: Vec<PathBuf> = l.inputs().iter().map(|p| Manifest::resolve(&base, p)).collect();
                let mut args = vec!["ingest".to_string()];
                args.extend(inputs.iter().map(|p| s(p)));
                args.extend(["--out".into(), s(&dir), "--force".into()]);
                if let Some(f) = &l.format {
                    args.extend(["--format".into(), f.clone()]);
                }
                let r = Resources { cpus: 1, gpus: 0, memory_gb: 4.0 };
                let id = format!("ingest/{}", l.name);
                let index = ingest.len();
                sizer.push(
                    &mut ingest,
                    Node {
                        id: id.clone(),
                        stage: "ingest".into(),
                        index,
                        args,
                        env: cpu_env(&r),
                        inputs,
                        outputs: vec![dir.clone()],
                        deps: vec![],
                        resources: r,
                    },
                )?;
                scenes.push((l.name.clone(), dir, Some(id)));
            }
        }
    }
    let mut push_stage = |name: &str, v: Vec<Node>, nodes: &mut Vec<Node>| {
        if !v.is_empty() {
            stages.push(name.to_string());
            nodes.extend(v);
        }
    };
    push_stage("ingest", ingest, &mut nodes);
    // Per log: the node whose output the next stage of that log needs.
    let mut last: Vec<Vec<String>> = scenes.iter().map(|(_, _, id)| id.iter().cloned().collect()).collect();
    if let Some(p) = &manifest.priors {
        let mut v = Vec::new();
        for (k, (name, dir, _)) in scenes.iter().enumerate() {
            let r = Resources::from(&p.resources, 2, 0, 8.0);
            let mut args = vec!["priors".to_string(), s(dir), "--force".into()];
            args.extend(p.args.iter().cloned());
            let id = format!("priors/{name}");
            sizer.push(
                &mut v,
                Node {
                    id: id.clone(),
                    stage: "priors".into(),
                    index: k,
                    args,
                    env: cpu_env(&r),
                    inputs: vec![dir.join(scene::format::SCENE_FILE)],
                    outputs: vec![dir.join("priors")],
                    deps: last[k].clone(),
                    resources: r,
                },
            )?;
            last[k] = vec![id];
        }
        push_stage("priors", v, &mut nodes);
    }
    let mut models = Vec::new();
    if let Some(t) = &manifest.train {
        let mut v = Vec::new();
        let device = t.device.clone().unwrap_or_else(|| "cpu".into());
        for (k, (name, dir, _)) in scenes.iter().enumerate() {
            let model = out.join("models").join(name);
            let gpu = device == "cuda";
            let r = Resources::from(&t.resources, if gpu { 4 } else { 2 }, u32::from(gpu), 16.0);
            let mut args = vec!["train".to_string(), s(dir), "--out".into(), s(&model), "--force".into()];
            args.extend(["--device".into(), device.clone()]);
            if let Some(c) = &t.config {
                args.extend(["--config".into(), s(&Manifest::resolve(&base, c))]);
            }
            if let Some(i) = t.iters {
                args.extend(["--iters".into(), i.to_string()]);
            }
            if let Some(x) = t.scale {
                args.extend(["--scale".into(), x.to_string()]);
            }
            if let Some(x) = t.seed {
                args.extend(["--seed".into(), x.to_string()]);
            }
            args.extend(t.args.iter().cloned());
            let mut inputs = vec![dir.clone()];
            inputs.extend(t.config.iter().map(|c| Manifest::resolve(&base, c)));
            let id = format!("train/{name}");
            sizer.push(
                &mut v,
                Node {
                    id: id.clone(),
                    stage: "train".into(),
                    index: k,
                    args,
                    env: if gpu { BTreeMap::new() } else { cpu_env(&r) },
                    inputs,
                    outputs: vec![model.clone()],
                    deps: last[k].clone(),
                    resources: r,
                },
            )?;
            models.push((model, id));
        }
        push_stage("train", v, &mut nodes);
    }
    if let Some(e) = &manifest.eval_cases {
        let n = e.shards.unwrap_or(1);
        let all_deps: Vec<String> = scenes.iter().filter_map(|(_, _, id)| id.clone()).collect();
        let mut v = Vec::new();
        let mut dirs = Vec::new();
        for i in 0..n {
            let dir = out.join("eval").join(format!("shard-{i}-of-{n}"));
            let r = Resources::from(&e.resources, 1, 0, 4.0);
            let mut args = vec!["eval-cases".to_string()];
            args.extend(scenes.iter().map(|(_, d, _)| s(d)));
            // A node that runs again (changed inputs) replaces its own earlier shard output.
            args.extend(["--shard".into(), format!("{i}/{n}"), "--out".into(), s(&dir), "--force".into()]);
            for (flag, val) in
                [("--agents", &e.agents), ("--behaviors", &e.behaviors), ("--t0", &e.t0), ("--horizon", &e.horizon)]
            {
                if let Some(x) = val {
                    args.extend([flag.to_string(), x.clone()]);
                }
            }
            if let Some(x) = e.seed {
                args.extend(["--seed".into(), x.to_string()]);
            }
            args.extend(e.args.iter().cloned());
            sizer.push(
                &mut v,
                Node {
                    id: format!("eval_cases/{i}-of-{n}"),
                    stage: "eval_cases".into(),
                    index: i,
                    args,
                    env: cpu_env(&r),
                    inputs: scenes.iter().map(|(_, d, _)| d.join(scene::format::SCENE_FILE)).collect(),
                    outputs: vec![dir.join(format!("shard-{i}-of-{n}.json"))],
                    deps: all_deps.clone(),
                    resources: r,
                },
            )?;
            dirs.push(dir);
        }
        let argv: usize = v.first().map_or(0, |x| argv_bytes(&x.args));
        if argv > MAX_ARGV_BYTES {
            return Err(BatchError::invalid(
                &manifest_file,
                format!(
                    "[eval_cases]: one sweep's command line would be {argv} bytes (every scene is an argument); \
                     at most {MAX_ARGV_BYTES} fit: split the logs into several manifests"
                ),
            ));
        }
        let shard_ids: Vec<String> = v.iter().map(|x| x.id.clone()).collect();
        push_stage("eval_cases", v, &mut nodes);
        let tables = out.join("tables");
        let mut args = vec!["tables".to_string()];
        args.extend(dirs.iter().map(|d| s(d)));
        args.extend(["--out".into(), s(&tables)]);
        if argv_bytes(&args) > MAX_ARGV_BYTES {
            return Err(BatchError::invalid(
                &manifest_file,
                format!(
                    "[eval_cases]: the tables command line would be {} bytes (every shard directory is an argument); \
                     at most {MAX_ARGV_BYTES} fit: ask for fewer shards or a shorter --out",
                    argv_bytes(&args)
                ),
            ));
        }
        let r = Resources { cpus: 1, gpus: 0, memory_gb: 4.0 };
        let node = Node {
            id: "tables".into(),
            stage: "tables".into(),
            index: 0,
            args,
            env: cpu_env(&r),
            inputs: dirs.iter().enumerate().map(|(i, d)| d.join(format!("shard-{i}-of-{n}.json"))).collect(),
            outputs: vec![tables.join("table1.md")],
            deps: shard_ids,
            resources: r,
        };
        let mut t = Vec::new();
        sizer.push(&mut t, node)?;
        push_stage("tables", t, &mut nodes);
    }
    if let Some(run) = &manifest.run {
        let mut v = Vec::new();
        for (k, (name, dir, _)) in scenes.iter().enumerate() {
            for b in &run.behaviors {
                let (model, train_id) = &models[k];
                let case = out.join("runs").join(name).join(b);
                let r = Resources::from(&run.resources, 2, 0, 8.0);
                let mut args =
                    vec!["run".to_string(), s(dir), "--model".into(), s(model), "--behavior".into(), b.clone()];
                args.extend(["--out".into(), s(&case)]);
                if let Some(a) = &run.agent {
                    args.extend(["--agent".into(), a.clone()]);
                }
                if let Some(x) = run.seed {
                    args.extend(["--seed".into(), x.to_string()]);
                }
                args.extend(run.args.iter().cloned());
                let index = v.len();
                sizer.push(
                    &mut v,
                    Node {
                        id: format!("run/{name}/{b}"),
                        stage: "run".into(),
                        index,
                        args,
                        env: if r.gpus > 0 { BTreeMap::new() } else { cpu_env(&r) },
                        inputs: vec![dir.join(scene::format::SCENE_FILE), model.clone()],
                        outputs: vec![case],
                        deps: vec![train_id.clone()],
                        resources: r,
                    },
                )?;
            }
        }
        push_stage("run", v, &mut nodes);
    }
    Ok(Plan { format: PLAN_FORMAT.into(), version: PLAN_VERSION, manifest: manifest_file, out, stages, nodes })
}

/// The nodes `manifest` makes, counted before any is: ingest, priors and train per log, the
/// shards and their tables node, a run per log and behaviour.
fn node_count(m: &Manifest) -> usize {
    let logs = m.logs.len();
    let ingest = m.logs.iter().filter(|l| l.scene.is_none()).count();
    let per_log = usize::from(m.priors.is_some()) + usize::from(m.train.is_some());
    let shards = m.eval_cases.as_ref().map_or(0, |e| e.shards.unwrap_or(1).saturating_add(1));
    let runs = m.run.as_ref().map_or(0, |r| logs.saturating_mul(r.behaviors.len()));
    ingest.saturating_add(logs.saturating_mul(per_log)).saturating_add(shards).saturating_add(runs)
}
