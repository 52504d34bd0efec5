//! `drive` (one closed-loop episode of a corner case), `eval-drive` (many cases x policies, the
//! table per behaviour and policy, shards) and `drive-tables` (merge shards). Argument parsing
//! only; the `drive` crate does the work (docs/drive.md). `drive-tables --out` is new, empty or
//! an earlier output of ours (replaced whole with `--force`), never one of its shards.

use super::recon::{open_cuda, Device};
use anyhow::Context;
use drive::eval_run::{Case, EvalRequest, PolicySpec};
use drive::{EpisodeSettings, Request};
use recon::backend::{Backend, Cpu, CpuF32};
use std::path::{Path, PathBuf};

#[derive(clap::Args, Clone, Debug)]
pub struct LoopArgs {
    /// The scene directory the cases were made on.
    #[arg(long)]
    scene: PathBuf,
    /// Tick period (s of log time; 0.1 = 10 Hz).
    #[arg(long, default_value_t = 0.1)]
    dt: f64,
    /// Seconds driven before the plan starts (within the log and the executed run).
    #[arg(long, default_value_t = 1.0)]
    lead_in: f64,
    /// Seconds driven after the plan ends (within the log; the adversary keeps its last velocity).
    #[arg(long, default_value_t = 1.0)]
    tail: f64,
    /// Cameras drawn each tick: `front3` or names separated by commas (`FRONT`: the front camera).
    #[arg(long, default_value = "front3")]
    cameras: String,
    /// Fraction of the cameras' image size (0.25: 960x540 drawn at 240x135).
    #[arg(long, default_value_t = 0.25)]
    scale: f64,
    /// Where the cameras are drawn.
    #[arg(long, value_enum, default_value = "cpu")]
    device: Device,
    /// Seconds a subprocess policy may take to answer a tick.
    #[arg(long, default_value_t = 10.0)]
    policy_timeout: f64,
    /// PNG frames instead of an MP4 even when ffmpeg is there.
    #[arg(long)]
    png: bool,
    /// Replace an existing --out of ours.
    #[arg(long)]
    force: bool,
}

#[derive(clap::Args)]
pub struct DriveArgs {
    /// A run directory (`carla-gs run` or the demo's `cases/<behaviour>`): its `executed.json`.
    run_dir: PathBuf,
    /// The trained model of the scene.
    #[arg(long)]
    model: PathBuf,
    /// `log`, `constant`, `idm-aeb`, or `exec` (the command after `--`, as a subprocess).
    #[arg(long)]
    policy: String,
    /// The episode directory.
    #[arg(long)]
    out: PathBuf,
    /// No video (built-in policies then draw nothing).
    #[arg(long)]
    no_video: bool,
    #[command(flatten)]
    common: LoopArgs,
    /// With `--policy exec`: the policy's program and arguments.
    #[arg(last = true)]
    command: Vec<String>,
}

#[derive(clap::Args)]
pub struct EvalArgs {
    /// Run directories (one case each) of the scene.
    #[arg(required = true)]
    run_dirs: Vec<PathBuf>,
    /// The trained model (needed for --video and subprocess policies).
    #[arg(long)]
    model: Option<PathBuf>,
    /// Policies separated by commas: `log`, `constant`, `idm-aeb`, and `exec` (the command after `--`).
    #[arg(long, default_value = "log,constant,idm-aeb")]
    policies: String,
    /// Write every episode's video.
    #[arg(long)]
    video: bool,
    /// One deterministic part of the attempts, `I/N`.
    #[arg(long)]
    shard: Option<String>,
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    common: LoopArgs,
    #[arg(last = true)]
    command: Vec<String>,
}

#[derive(clap::Args)]
pub struct TablesArgs {
    /// `eval-drive --shard` output directories.
    #[arg(required = true)]
    shards: Vec<PathBuf>,
    /// New, empty, or an earlier drive-tables or eval-drive output (replaced whole with --force);
    /// never one of the shards.
    #[arg(long)]
    out: PathBuf,
    /// Replace an earlier output of ours at --out whole.
    #[arg(long)]
    force: bool,
}

/// What drive-tables and eval-drive write: `drive-eval.json` of our format.
const DRIVE_EVAL_OUT: super::out_dir::Kind = super::out_dir::Kind {
    what: "a drive-tables output",
    marker: "drive-eval.json of format carla-gs-drive-eval/1",
    ours: drive::eval_run::is_eval_dir,
};

fn settings(a: &LoopArgs, scene: &scene::Scene) -> anyhow::Result<EpisodeSettings> {
    render::budget::check_scale("--scale", a.scale)?;
    Ok(EpisodeSettings {
        tick_dt_s: a.dt,
        lead_in_s: a.lead_in,
        tail_s: a.tail,
        cameras: drive::cameras::resolve(scene, &a.cameras)?,
        scale: a.scale,
        rollout: sim::RolloutConfig::default(),
    })
}

fn policy_spec(name: &str, command: &[String], timeout_s: f64) -> anyhow::Result<PolicySpec> {
    match name {
        "exec" => {
            let (program, args) =
                command.split_first().context("--policy exec: give the policy's command after `--`")?;
            Ok(PolicySpec::Command { name: "exec".into(), program: program.clone(), args: args.to_vec(), timeout_s })
        }
        n if drive::builtin::BUILTINS.contains(&n) => Ok(PolicySpec::Builtin(n.into())),
        n => anyhow::bail!("--policy: `{n}` is not one of {}, exec", drive::builtin::BUILTINS.join(", ")),
    }
}

fn load_case(run_dir: &Path) -> anyhow::Result<Case> {
    let executed = scene::executed::load_executed(&run_dir.join("executed.json"))?;
    let name = run_dir.file_name().map_or("case".into(), |n| n.to_string_lossy().into_owned());
    Ok(Case { name, run_dir: run_dir.to_path_buf(), executed })
}

/// What runs with the cameras' drawer and the rasterizer's name (`None`: nothing is drawn).
type WithDraw<'f, T> = dyn FnMut(Option<(&dyn drive::episode::Draw, String)>) -> anyhow::Result<T> + 'f;

/// Runs `f` with the cameras' drawer on the chosen device (or none without a model).
fn with_draw<T>(
    device: Device,
    model: Option<&recon::SceneModel>,
    scene: &scene::Scene,
    s: &EpisodeSettings,
    f: &mut WithDraw<T>,
) -> anyhow::Result<T> {
    fn go<B: Backend, T>(
        b: &B,
        model: &recon::SceneModel,
        scene: &scene::Scene,
        s: &EpisodeSettings,
        f: &mut WithDraw<T>,
    ) -> anyhow::Result<T> {
        let cams = drive::cameras::Cameras::new(b, model, scene, &s.cameras, s.scale)?;
        f(Some((&cams, b.name().to_string())))
    }
    let Some(model) = model else { return f(None) };
    match device {
        Device::Cpu => go(&CpuF32, model, scene, s, f),
        Device::CpuF64 => go(&Cpu, model, scene, s, f),
        Device::Cuda => go(&open_cuda()?, model, scene, s, f),
    }
}

pub fn run(a: DriveArgs) -> anyhow::Result<()> {
    super::out_dir::check_not_inside(&a.out, &[&a.run_dir, &a.common.scene, &a.model])?;
    let spec = policy_spec(&a.policy, &a.command, a.common.policy_timeout)?;
    drive::output::check_out(&a.out, a.common.force)?;
    let scene = scene::load_scene(&a.common.scene)?;
    let settings = settings(&a.common, &scene)?;
    let case = load_case(&a.run_dir)?;
    drive::episode::span(&scene, &case.executed, &settings)?;
    let (model, _) = recon::model_io::load_model_for_scene(&a.model, &a.common.scene, &scene)?;
    let file = with_draw(a.common.device, Some(&model), &scene, &settings, &mut |draw| {
        let (mut policy, command) = spec.open()?;
        let req = Request {
            scene: &scene,
            executed: &case.executed,
            settings: &settings,
            case: drive::output::case_info(&case.executed, Some(&case.run_dir)),
            policy_command: command,
            draw,
            video: !a.no_video,
            png_only: a.common.png,
            out: &a.out,
            force: a.common.force,
        };
        Ok(drive::drive(&req, policy.as_mut())?)
    })?;
    let s = &file.scores;
    println!("wrote {} ({} ticks, ended: {})", a.out.display(), file.ticks.len(), file.ended);
    match &s.contact {
        Some(c) => println!(
            "collision with {} ({}) at t = {:.2} s, impact speed {:.2} m/s",
            c.other, c.class, c.t, c.impact_speed
        ),
        None => println!("no collision"),
    }
    let ttc = s.min_ttc_s.map_or("-".into(), |v| format!("{v:.2} s"));
    let gap = s.min_gap_m.map_or("-".into(), |v| format!("{v:.2} m"));
    println!("NCAP score {:.2}, MinTTC {ttc}, min gap {gap}", s.ncap_score);
    let t = &file.timing;
    println!(
        "per tick: render {:.4} s ({} cameras), policy {:.4} s; {:.1} Hz",
        t.render_s_mean,
        t.cameras,
        t.policy_s_mean,
        t.step_hz.unwrap_or(0.0)
    );
    Ok(())
}

pub fn eval(a: EvalArgs) -> anyhow::Result<()> {
    let names: Vec<&str> = a.policies.split(',').map(str::trim).filter(|s| !s.is_empty()).collect();
    anyhow::ensure!(!names.is_empty(), "--policies: give at least one policy");
    let specs = names
        .iter()
        .map(|n| policy_spec(n, &a.command, a.common.policy_timeout))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut inputs: Vec<&std::path::Path> = a.run_dirs.iter().map(|p| p.as_path()).collect();
    inputs.push(&a.common.scene);
    inputs.extend(a.model.as_deref());
    super::out_dir::check_not_inside(&a.out, &inputs)?;
    let shard = a.shard.as_deref().map(drive::eval::parse_shard).transpose()?;
    let scene = scene::load_scene(&a.common.scene)?;
    let settings = settings(&a.common, &scene)?;
    let cases = a.run_dirs.iter().map(|d| load_case(d)).collect::<anyhow::Result<Vec<_>>>()?;
    let needs_model = a.video || specs.iter().any(|s| matches!(s, PolicySpec::Command { .. }));
    let model = match (&a.model, needs_model) {
        (Some(m), _) => Some(recon::model_io::load_model_for_scene(m, &a.common.scene, &scene)?.0),
        (None, true) => anyhow::bail!("--model: needed to draw the cameras (--video or a subprocess policy)"),
        (None, false) => None,
    };
    let (mut all, mut rows) = (Vec::new(), Vec::new());
    with_draw(a.common.device, model.as_ref(), &scene, &settings, &mut |draw| {
        let req = EvalRequest {
            scene: &scene,
            cases: &cases,
            policies: &specs,
            settings: &settings,
            draw,
            video: a.video,
            png_only: a.common.png,
            shard,
            out: &a.out,
            force: a.common.force,
        };
        let (file, r) = drive::eval_run::run_eval(&req)?;
        all = file.records;
        rows = r;
        Ok(())
    })?;
    println!("{}", drive::eval::markdown(&rows));
    let failed = all.iter().filter(|r| r.error.is_some()).count();
    println!("wrote {} ({} episodes, {failed} failed)", a.out.display(), all.len());
    Ok(())
}

pub fn tables(a: TablesArgs) -> anyhow::Result<()> {
    let shards: Vec<&Path> = a.shards.iter().map(|p| p.as_path()).collect();
    super::out_dir::check_replaceable(&a.out, &shards, a.force, &DRIVE_EVAL_OUT)?;
    let merged = drive::eval::merge(&a.shards)?;
    // Built beside --out and swapped in whole: a kill leaves the old tables or the new ones.
    let staged = super::out_dir::stage(&a.out, &shards, a.force, &DRIVE_EVAL_OUT)?;
    let rows = drive::eval::write_tables(staged.path(), &merged)?;
    staged.commit()?;
    println!("{}", drive::eval::markdown(&rows));
    println!("wrote {}", a.out.display());
    Ok(())
}
