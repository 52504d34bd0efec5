//! `carla-gs demo [--out demo-out] [--input <log>]`: the whole pipeline on embedded defaults
//! (`pipeline::demo`), on the synthetic street or on a real log (`pipeline::real_log`, whose
//! adversaries are replaced by the log's own well-seen vehicles where a case needs it,
//! `pipeline::auto_replace`).
//!
//! `--out` is new, empty, or a demo's own (`demo.json` of our format, written as the demo
//! starts): anything else is refused, with or without `--force`, and never inside, equal to or
//! holding `--input`. An earlier demo's `--out` is continued from its cache; with `--force` a
//! fresh demo is built beside it and swapped in whole at the end.

use super::recon::{open_cuda, Device};
use indicatif::{ProgressBar, ProgressStyle};
use pipeline::demo::{run_demo_on, DemoConfig, DemoProgress};
use recon::backend::{Cpu, CpuF32};
use std::path::{Path, PathBuf};

#[derive(clap::Args)]
pub struct Args {
    /// Where everything goes (reused by the next run: finished stages are cached).
    #[arg(long, default_value = "demo-out")]
    out: PathBuf,
    /// Training iterations (default: the demo's 1500).
    #[arg(long)]
    iters: Option<usize>,
    /// The agent that makes the corner cases: planner, rule or random (LLM agents: use `run`).
    #[arg(long, default_value = "planner")]
    agent: String,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Where the rasterizer runs (training, evaluation, videos).
    #[arg(long, value_enum, default_value = "cpu")]
    device: Device,
    /// Replace an actor with an aligned asset before the cases: <track>=<PLY file, asset name of
    /// <out>/assets (synth-sedan, synth-van, synth-truck), or auto>. Repeatable.
    #[arg(long = "replace")]
    replace: Vec<String>,
    /// A real log instead of the synthetic street: a PandaSet sequence (or any folder `ingest`
    /// reads) or a scene directory. Trained at a quarter of the cameras' size on the CPU, at full
    /// size with configs/real-street-gpu.toml on `--device cuda`.
    #[arg(long)]
    input: Option<PathBuf>,
    /// On a real log, draw every adversary as reconstructed: no harvest of the log's vehicles
    /// into <out>/assets and no automatic replacement (--replace still applies).
    #[arg(long)]
    no_auto_replace: bool,
    /// Rebuild an earlier demo's --out from scratch (only one of ours: demo.json of format
    /// carla-gs-demo/1); the old one stays until the new one is complete.
    #[arg(long)]
    force: bool,
}

/// A demo's output: `demo.json` of our format (or a whole earlier result).
const DEMO_OUT: super::out_dir::Kind =
    super::out_dir::Kind { what: "a demo output", marker: "demo.json of format carla-gs-demo/1", ours: is_demo_out };

fn is_demo_out(dir: &Path) -> bool {
    scene::has_format_marker(dir, "demo.json", pipeline::demo::DEMO_FORMAT)
        || scene::format::read_json::<pipeline::demo::DemoResult>(&dir.join("demo.json")).is_ok()
}

struct Terminal;

impl DemoProgress for Terminal {
    fn stage(&self, name: &str) {
        eprintln!("demo: {name}");
    }

    fn bar(&self) -> ProgressBar {
        let pb = ProgressBar::new(0);
        pb.set_style(
            ProgressStyle::with_template("  [{bar:30}] {pos}/{len} ({eta}) {msg}")
                .expect("valid template")
                .progress_chars("=> "),
        );
        pb
    }
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let inputs: Vec<&Path> = a.input.iter().map(|p| p.as_path()).collect();
    // Ours is continued (or, with --force, rebuilt); anything else is refused.
    super::out_dir::check_replaceable(&a.out, &inputs, true, &DEMO_OUT)?;
    let mut cfg = match &a.input {
        None => DemoConfig::default(),
        Some(input) => {
            anyhow::ensure!(
                input.is_dir(),
                "--input {}: not a folder (a PandaSet sequence or a scene)",
                input.display()
            );
            pipeline::real_log::config(input, matches!(a.device, Device::Cuda))?
        }
    };
    if let Some(n) = a.iters {
        // Checked before any stage runs (training would refuse it only after ingest and priors).
        let max = recon::budget::MAX_ITERATIONS;
        anyhow::ensure!((1..=max).contains(&n), "--iters {n}: expected 1 to {max} training iterations");
        cfg.train.iterations = n;
    }
    cfg.agent = a.agent.parse().map_err(anyhow::Error::msg)?;
    anyhow::ensure!(
        !cfg.agent.is_llm(),
        "--agent {}: the demo runs planner, rule or random; LLM agents run with `carla-gs run`",
        cfg.agent.as_str()
    );
    cfg.seed = a.seed;
    cfg.replace = a.replace.clone();
    if a.no_auto_replace {
        cfg.auto_replace = None;
    }
    let staged = match a.force {
        true => Some(super::out_dir::stage(&a.out, &inputs, true, &DEMO_OUT)?),
        false => None,
    };
    let out = staged.as_ref().map_or(a.out.as_path(), |s| s.path());
    let mut r = match a.device {
        Device::Cpu => run_demo_on(&CpuF32, &cfg, out, &Terminal)?,
        Device::CpuF64 => run_demo_on(&Cpu, &cfg, out, &Terminal)?,
        Device::Cuda => run_demo_on(&open_cuda()?, &cfg, out, &Terminal)?,
    };
    if let Some(staged) = staged {
        // demo.json names the directory it will be in.
        r.out = a.out.clone();
        scene::format::write_json_pretty(&staged.path().join("demo.json"), &r)?;
        staged.commit()?;
    }
    println!("stage                          seconds");
    for t in &r.timings {
        println!("{:<30} {:>8.1}{}", t.stage, t.seconds, if t.cached { "  (cached)" } else { "" });
    }
    println!("total this run                 {:>8.1}", r.total_seconds);
    for (b, s) in &r.cases {
        match &s.metrics {
            Some(m) => println!(
                "{:<22} {} zone hit {}, success {}, MinTTC {:.2} s",
                b.as_str(),
                if m.validity.valid { "valid," } else { "INVALID," },
                m.zone_hit,
                m.success_center,
                m.min_ttc_center_s
            ),
            None => println!("{:<22} no corner case ({} attempts)", b.as_str(), s.attempts.len()),
        }
        if let Some(adv) = &s.adversary {
            match (&adv.auto, adv.replaced) {
                (Some(c), true) => {
                    println!("{:<22} adversary {} replaced by `{}`: {}", "", adv.track_id, c.asset, adv.why)
                }
                _ => println!("{:<22} adversary {} as reconstructed: {}", "", adv.track_id, adv.why),
            }
        }
    }
    if let Some(h) = &r.harvest {
        let kept = h.vehicles.iter().filter(|v| v.kept).count();
        println!(
            "asset library: {kept} of {} vehicles of the log harvested -> {}",
            h.vehicles.len(),
            h.library.join(render::asset::library::INDEX_FILE).display()
        );
    }
    let report = a.out.join(pipeline::report::REPORT_FILE);
    let shown = std::fs::canonicalize(&report).unwrap_or(report);
    println!("report: {}", shown.display());
    Ok(())
}
