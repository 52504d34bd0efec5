//! `carla-gs batch plan <manifest.toml> --out <dir>` writes the engine-neutral plan of a batch
//! (`pipeline::batch::plan`); `carla-gs batch exec <plan.json> <node>` runs one node of it,
//! skipping it when it already finished from the same inputs and settings
//! (`pipeline::batch::node`). `tools/batch_ray.py` runs a plan on Ray or writes a Slurm script.
use pipeline::batch::{manifest::Manifest, node, plan};
use std::path::PathBuf;

#[derive(clap::Subcommand)]
pub enum Command {
    /// Turn a manifest (logs, stages) into <out>/plan.json: a graph of plain carla-gs commands.
    Plan(PlanArgs),
    /// Run one node of a plan (by id, or by --stage and --index), unless it already finished.
    Exec(ExecArgs),
}

#[derive(clap::Args)]
pub struct PlanArgs {
    manifest: PathBuf,
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing <out>/plan.json (only one of ours: a batch plan).
    #[arg(long)]
    force: bool,
}

#[derive(clap::Args)]
pub struct ExecArgs {
    plan: PathBuf,
    /// The node's id (`ingest/<log>`, `eval_cases/0-of-4`, `tables`, ...).
    #[arg(required_unless_present = "stage", conflicts_with = "stage")]
    node: Option<String>,
    /// The node's stage (with --index: a Slurm array task's node).
    #[arg(long, requires = "index")]
    stage: Option<String>,
    #[arg(long)]
    index: Option<usize>,
}

pub fn run(c: Command) -> anyhow::Result<()> {
    match c {
        Command::Plan(a) => {
            let file = a.out.join(plan::PLAN_FILE);
            let ours = scene::has_format_marker(&a.out, plan::PLAN_FILE, plan::PLAN_FORMAT);
            super::out_dir::check_out_file_in(&file, a.force, "a batch plan", ours)?;
            let m = Manifest::read(&a.manifest)?;
            pipeline::batch::checks::inputs_exist(&m, &a.manifest)?;
            let p = plan::build(&m, &a.manifest, &a.out)?;
            scene::format::write_json_pretty(&file, &p)?;
            let mut per_stage = String::new();
            for s in &p.stages {
                per_stage += &format!(" {s} {}", p.nodes.iter().filter(|n| &n.stage == s).count());
            }
            println!("wrote {} ({} nodes:{per_stage})", file.display(), p.nodes.len());
            Ok(())
        }
        Command::Exec(a) => {
            let p = node::read_plan(&a.plan)?;
            let n = node::find(&p, a.node.as_deref(), a.stage.as_deref().zip(a.index))?;
            node::check_command(n)?;
            let me = std::env::current_exe()?;
            match node::exec(&p, n, &me)? {
                node::Outcome::Skipped(s) => {
                    println!("skip {}: finished before from the same inputs and settings (exit {})", n.id, s.exit_code);
                    exit_with(s.exit_code, &n.id)
                }
                node::Outcome::Ran { exit_code, seconds } => {
                    println!("ran {} in {seconds:.1} s: exit {exit_code}", n.id);
                    exit_with(exit_code, &n.id)
                }
            }
        }
    }
}

/// The node's own exit code becomes ours: 3 (no case) stays 3, a failure is an error.
fn exit_with(code: i32, id: &str) -> anyhow::Result<()> {
    match code {
        0 => Ok(()),
        3 => Err(super::NoCase(format!("{id}: no case possible (stamped; not retried)")).into()),
        c => anyhow::bail!("{id}: the command failed (exit {c})"),
    }
}
