//! `carla-gs`: command-line entry point. Parses arguments and calls the crates; no logic here.
//! Exit codes: 0 done, 2 bad input, refused or failed (the message says which file and field),
//! 3 no case possible for a well-formed request ([`cmd::NoCase`]; nothing written).

mod cmd;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "carla-gs", version, about = "Photorealistic, physically valid corner cases from real driving logs")]
struct Cli {
    /// More log output (-v info, -vv debug, -vvv trace).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Convert Waymo Frame or WOMD Scenario TFRecords into a scene directory.
    Ingest(cmd::ingest::Args),
    /// Summarise a scene directory or a TFRecord file.
    Inspect(cmd::inspect::Args),
    /// Choose an adversary, zone and trajectory for a dangerous behaviour (writes scenario.json).
    Reason(cmd::reason::Args),
    /// Execute a corner-case plan with vehicle dynamics (or a CARLA server) and the CARLA PID tracker.
    Simulate(cmd::simulate::Args),
    /// Write the scene's road network (lanes, road edges; a flat road without a map) as OpenDRIVE.
    ExportXodr(cmd::export_xodr::Args),
    /// Reason -> simulate -> measure over scenes x behaviours x t0 x agents; Tables I and II, plots.
    EvalCases(cmd::eval_cases::Args),
    /// The stress corpus (WOMD, PandaSet, KITTI paths and perturbed copies): the table per behaviour.
    BenchCases(cmd::bench_cases::Args),
    /// Merge `eval-cases --shard I/N` outputs into the tables of one run over all attempts.
    Tables(cmd::tables::Args),
    /// Batch runs over many logs: `plan` a manifest into a graph of commands, `exec` one node.
    #[command(subcommand)]
    Batch(cmd::batch::Command),
    /// Render a 3DGS PLY from a camera (JSON) to a PNG.
    RenderPly(cmd::splat::RenderArgs),
    /// Time the CPU rasterizer's forward and forward+backward passes; writes JSON.
    BenchSplat(cmd::splat::BenchArgs),
    /// Generate a synthetic driving sequence with exact ground truth (a scene directory).
    Synth(cmd::synth::Args),
    /// Measure an executed corner case (TTC, Success, Zone Hit, comfort).
    Metrics(cmd::metrics::Args),
    /// Train a Street-Gaussians model of a scene (background, actors, sky) with geometry losses.
    Train(cmd::recon::TrainArgs),
    /// Score a trained model on the held-out views (PSNR, SSIM, normal errors, actor mask IoU).
    EvalRecon(cmd::recon::EvalArgs),
    /// Render one camera of a trained model at a frame (optionally moved sideways).
    Render(cmd::recon::RenderArgs),
    /// Table III: train the four geometry-loss settings with one seed and split, score each.
    Ablate(cmd::recon::AblateArgs),
    /// Geometry priors per image (depth, normals, ground/object masks) under <scene>/priors/.
    Priors(cmd::priors::Args),
    /// One corner case end to end: reason -> simulate -> metrics -> OpenSCENARIO -> videos.
    Run(cmd::run::RunArgs),
    /// Everything on embedded defaults: synthesise, train, one case per showcased behaviour, videos, report.
    Demo(cmd::demo::Args),
    /// Closed loop: drive a policy through a corner case (cameras at the simulated pose, NCAP score).
    Drive(cmd::drive::DriveArgs),
    /// Drive many cases with many policies; the table per behaviour and policy (shards with --shard).
    EvalDrive(cmd::drive::EvalArgs),
    /// Merge `eval-drive --shard I/N` outputs into the table of one run.
    DriveTables(cmd::drive::TablesArgs),
    /// Render an executed corner case as video (one layout).
    Video(cmd::run::VideoCmdArgs),
    /// Add a Gaussian asset (a 3DGS PLY, a trained actor, a synthetic vehicle) to an asset library.
    Asset(cmd::asset::AssetArgs),
    /// Replace an actor of a trained model with an aligned Gaussian asset (writes a new model).
    Replace(cmd::asset::ReplaceArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let level = match cli.verbose {
        0 => "warn",
        1 => "info",
        2 => "debug",
        _ => "trace",
    };
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| level.into()))
        .with_writer(std::io::stderr)
        .init();
    let result = match cli.command {
        Command::Ingest(a) => cmd::ingest::run(a),
        Command::Inspect(a) => cmd::inspect::run(a),
        Command::Reason(a) => cmd::reason::run(a),
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::Metrics(a) => cmd::metrics::run(a),
        Command::EvalCases(a) => cmd::eval_cases::run(a),
        Command::BenchCases(a) => cmd::bench_cases::run(a),
        Command::Tables(a) => cmd::tables::run(a),
        Command::Batch(c) => cmd::batch::run(c),
        Command::ExportXodr(a) => cmd::export_xodr::run(a),
        Command::RenderPly(a) => cmd::splat::render(a),
        Command::BenchSplat(a) => cmd::splat::bench(a),
        Command::Synth(a) => cmd::synth::run(a),
        Command::Train(a) => cmd::recon::train(a),
        Command::EvalRecon(a) => cmd::recon::eval(a),
        Command::Render(a) => cmd::recon::render(a),
        Command::Ablate(a) => cmd::recon::ablate(a),
        Command::Priors(a) => cmd::priors::run(a),
        Command::Run(a) => cmd::run::run(a),
        Command::Demo(a) => cmd::demo::run(a),
        Command::Video(a) => cmd::run::video(a),
        Command::Drive(a) => cmd::drive::run(a),
        Command::EvalDrive(a) => cmd::drive::eval(a),
        Command::DriveTables(a) => cmd::drive::tables(a),
        Command::Asset(a) => cmd::asset::add(a),
        Command::Replace(a) => cmd::asset::replace(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.downcast_ref::<cmd::NoCase>().is_some() => {
            eprintln!("no case: {}", cmd::message::message(&e));
            ExitCode::from(3)
        }
        Err(e) => {
            eprintln!("error: {}", cmd::message::message(&e));
            ExitCode::from(2)
        }
    }
}
