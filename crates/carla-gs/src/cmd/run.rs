//! `carla-gs run` (one corner case end to end) and `carla-gs video` (re-render an executed case):
//! argument parsing around the `pipeline` and `render` crates.

use super::progress::count_bar;
use super::recon::{open_cuda, Device};
use anyhow::Context;
use cases::spec::{AgentName, T0Spec};
use cases::window::Horizon;
use pipeline::case::{CaseRequest, T0Choice};
use pipeline::run::{RenderSettings, RunInputs};
use recon::backend::{Cpu, CpuF32};
use std::path::PathBuf;

/// Video settings shared by `run`, `video` and `demo`.
#[derive(clap::Args, Clone, Debug)]
pub struct VideoArgs {
    /// Comma-separated layouts: single:<CAMERA>, front3, compare:<CAMERA>. A camera FRONT the
    /// scene does not have by that name is its front camera (PandaSet front_camera, KITTI LEFT).
    #[arg(long, default_value = "compare:FRONT,front3")]
    pub layouts: String,
    /// Video frame rate (poses are interpolated between the log's frames).
    #[arg(long, default_value_t = 24.0)]
    pub fps: f64,
    /// Fraction of the cameras' image size to render at.
    #[arg(long, default_value_t = 1.0)]
    pub scale: f64,
    /// Seconds of log shown before the corner case starts.
    #[arg(long, default_value_t = 1.5)]
    pub lead_in: f64,
    /// Write PNG frames instead of MP4 even when ffmpeg is installed.
    #[arg(long)]
    pub png: bool,
    /// Where the rasterizer runs.
    #[arg(long, value_enum, default_value = "cpu")]
    pub device: Device,
    /// OpenSCENARIO version of `scenario.xosc`: 1.2, or 1.0 for CARLA's ScenarioRunner.
    #[arg(long, default_value = "1.2")]
    pub xosc_version: export::XoscVersion,
}

impl VideoArgs {
    pub fn settings(&self) -> RenderSettings {
        RenderSettings {
            layouts: self.layouts.split(',').map(|s| s.trim().to_string()).filter(|s| !s.is_empty()).collect(),
            fps: self.fps,
            lead_in_s: self.lead_in,
            scale: self.scale,
            png_only: self.png,
            xosc_version: self.xosc_version,
            ..RenderSettings::default()
        }
    }
}

#[derive(clap::Args)]
pub struct RunArgs {
    /// The scene directory.
    scene: PathBuf,
    /// The trained model directory (`carla-gs train`).
    #[arg(long)]
    model: PathBuf,
    /// The dangerous behaviour (required unless --describe gives one).
    #[arg(long)]
    behavior: Option<String>,
    /// planner, local, openai, rule or random.
    #[arg(long, default_value = "planner")]
    agent: String,
    #[command(flatten)]
    constraints: super::constraints::ConstraintArgs,
    #[command(flatten)]
    describe: super::describe::DescribeArgs,
    /// Analysis time (s from the first frame); default: search every 0.5 s for the first
    /// physically valid, successful case.
    #[arg(long)]
    t0: Option<f64>,
    #[arg(long)]
    out: PathBuf,
    #[arg(long, default_value_t = 0)]
    seed: u64,
    #[arg(long, default_value_t = 3)]
    refine_rounds: usize,
    /// Seeds tried at each t0 (seed, seed+1, ...) before moving on.
    #[arg(long, default_value_t = 3)]
    seeds_per_t0: usize,
    /// The window measured and rendered: `plan` (the plan's own end) or seconds from t0 (clipped
    /// at the log's end), as `eval-cases --horizon`; `--horizon 5` shows the case the tables count.
    /// Default: the plan's own end, and only if no attempt succeeds there, 5 s (as `demo`).
    #[arg(long)]
    horizon: Option<String>,
    /// Between the plan's end and the horizon: `stop` (brake to rest at 4 m/s^2) or `hold`.
    #[arg(long, default_value = "stop")]
    after_plan: String,
    #[command(flatten)]
    video: VideoArgs,
    #[command(flatten)]
    llm: super::llm::LlmArgs,
    #[command(flatten)]
    physics: super::backend::BackendArgs,
    #[command(flatten)]
    replace: super::asset::ReplaceFlags,
}

pub fn run(a: RunArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        (1..=pipeline::case::MAX_SEEDS_PER_T0).contains(&a.seeds_per_t0),
        "--seeds-per-t0 {}: expected 1 to {}",
        a.seeds_per_t0,
        pipeline::case::MAX_SEEDS_PER_T0
    );
    anyhow::ensure!(
        a.refine_rounds <= cases::runner::MAX_REFINE_ROUNDS,
        "--refine-rounds {}: expected 0 to {}",
        a.refine_rounds,
        cases::runner::MAX_REFINE_ROUNDS
    );
    super::out_dir::check_not_inside(&a.out, &[&a.scene, &a.model])?;
    let scene = scene::load_scene(&a.scene)?;
    let (mut model, _) = recon::model_io::load_model_for_scene(&a.model, &a.scene, &scene)?;
    a.replace.apply(&mut model, &a.scene, &a.model)?;
    let agent: AgentName = a.agent.parse().map_err(anyhow::Error::msg)?;
    let behavior =
        a.behavior.as_deref().map(|b| b.parse().map_err(|e: String| anyhow::anyhow!("--behavior: {e}"))).transpose()?;
    let t0 = match a.t0 {
        Some(t) => T0Choice::At(t),
        None => T0Choice::Search(T0Spec::Every(0.5)),
    };
    let log_s = scene.frames[scene.frames.len() - 1].timestamp_s - scene.frames[0].timestamp_s;
    if let Some(t) = a.t0 {
        anyhow::ensure!(
            t.is_finite() && (0.0..=log_s).contains(&t),
            "--t0: must be from 0 to {log_s:.2} s (the log's length), got {t:?}"
        );
    }
    let mut flags = a.constraints.apply(reason::ReasonOptions { behavior, seed: a.seed, ..Default::default() })?;
    // An explicit --ttc past the log's end at every t0 tried is no case, as `reason` says (exit 3).
    if let Some(ttc) = flags.ttc_s {
        let first_t0 = match &t0 {
            T0Choice::At(t) => Some(*t),
            T0Choice::Search(spec) => spec.times(&scene).first().copied(),
        };
        if let Some(t) = first_t0.filter(|t| t + ttc > log_s + 1e-9) {
            return Err(super::NoCase(format!(
                "no feasible adversary at t0 = {t:.2} s: --ttc {ttc} s is past the end of the log ({:.2} s after t0 = \
                 {t:.2} s), where the ego's motion is unknown; nothing written",
                log_s - t
            ))
            .into());
        }
    }
    if let Some(text) = &a.describe.describe {
        let mut reader = a.describe.backend(&a.llm, agent == AgentName::Openai)?;
        let (intent, summary, t) =
            pipeline::case::describe(&scene, &t0, &flags, text, reader.as_mut()).map_err(anyhow::Error::msg)?;
        super::describe::show(text, &reader.name(), &format!(" at t0 = {t:.1} s"), &intent, &summary);
        flags = intent.fill(&flags);
    }
    let horizon: Option<Horizon> =
        a.horizon.as_deref().map(str::parse).transpose().map_err(|e: String| anyhow::anyhow!("--horizon: {e}"))?;
    let after_plan = a.after_plan.parse().map_err(|e: String| anyhow::anyhow!("--after-plan: {e}"))?;
    let req = CaseRequest {
        behavior: flags.behavior.ok_or_else(|| anyhow::anyhow!("--behavior is required (or --describe)"))?,
        agent,
        adversary: flags.adversary,
        zone: flags.zone,
        ttc_s: flags.ttc_s,
        insert: flags.insert,
        seed: a.seed,
        seeds_per_t0: a.seeds_per_t0,
        refine_rounds: a.refine_rounds,
        window: cases::window::Window { horizon: horizon.unwrap_or(Horizon::Plan), after_plan },
        // Without --horizon, the tables' window when nothing succeeds over the plan's own end.
        fallback_window: horizon.is_none().then_some(cases::window::Window { after_plan, ..Default::default() }),
    };
    let mut llm = match agent {
        AgentName::Local => Some(a.llm.local()?),
        AgentName::Openai => Some(a.llm.openai()?),
        _ => None,
    };
    let settings = a.video.settings();
    let pb = count_bar("frames");
    let llm = llm.as_mut().map(|b| b.as_mut() as &mut dyn reason::backend::Backend);
    let simulate = a.physics.simulate_fn()?;
    // An inserted adversary is drawn from --asset-library (else the synthetic sedan).
    let library = pipeline::run_library::RunLibrary {
        scene: &scene,
        scene_dir: &a.scene,
        model: &model,
        model_dir: &a.model,
        library: &a.replace.asset_library,
        fps: settings.fps,
    };
    let swap = |e: &scene::Executed| library.swap(e);
    let swap = Some(&swap as &pipeline::run::AdversarySwap);
    let s = match a.video.device {
        Device::Cpu => {
            let inputs = RunInputs { scene: &scene, model: &model, backend: &CpuF32, render: &settings, out: &a.out };
            pipeline::run::run_with_swap(&inputs, &req, &t0, llm, &pb, simulate, swap)
        }
        Device::CpuF64 => {
            let inputs = RunInputs { scene: &scene, model: &model, backend: &Cpu, render: &settings, out: &a.out };
            pipeline::run::run_with_swap(&inputs, &req, &t0, llm, &pb, simulate, swap)
        }
        Device::Cuda => {
            let backend = open_cuda()?;
            let inputs = RunInputs { scene: &scene, model: &model, backend: &backend, render: &settings, out: &a.out };
            pipeline::run::run_with_swap(&inputs, &req, &t0, llm, &pb, simulate, swap)
        }
    }
    .with_context(|| format!("run of {} failed", a.scene.display()))?;
    pb.finish_and_clear();
    print_run(&s, &a.out);
    if s.result.is_none() {
        return Err(super::NoCase(format!(
            "{}; {} lists the attempts",
            s.no_case.as_deref().unwrap_or("no attempt produced a case"),
            a.out.join("run.json").display()
        ))
        .into());
    }
    Ok(())
}

/// What a run did, for the terminal.
pub fn print_run(s: &pipeline::run::RunSummary, out: &std::path::Path) {
    let tried: Vec<String> = s
        .attempts
        .iter()
        .map(|a| {
            format!(
                "t0={:.1}s seed {} {}{}",
                a.t0_s,
                a.seed,
                a.status,
                if a.valid && a.success { " (valid, success)" } else { "" }
            )
        })
        .collect();
    println!("attempts: {}", tried.join("; "));
    let (Some(r), Some(m)) = (&s.result, &s.metrics) else {
        println!("no corner case: no attempt produced one (reasons in {}/run.json)", out.display());
        return;
    };
    let plan = &r.best().expect("chosen case has rounds").plan;
    println!(
        "case: {} at t0={:.1}s, adversary {} -> {} zone; {}; zone hit {}, success {}, MinTTC {:.2} s",
        plan.behavior.as_str(),
        r.spec.t0_s,
        plan.adversary_track,
        plan.target_zone.as_str(),
        if m.validity.valid { "physically valid" } else { "INVALID" },
        m.zone_hit,
        m.success_center,
        m.min_ttc_center_s
    );
    for p in &s.placement {
        println!(
            "placement t={:.2}s {}: IoU {:.3}, vehicle profile IoU {:.3} ({} box px, {:.1} m from the logged box)",
            p.t,
            p.camera,
            p.iou,
            p.profile_iou.unwrap_or(f64::NAN),
            p.box_pixels,
            p.offset_from_log_m.unwrap_or(f64::NAN)
        );
    }
    for v in &s.videos {
        println!("video {}: {} ({} frames)", v.layout, v.output.path.display(), v.output.frames);
    }
    for t in &s.timings {
        println!("time {:<28} {:>8.1} s", t.stage, t.seconds);
    }
    println!("wrote {} ({})", out.display(), s.files.join(", "));
}

#[derive(clap::Args)]
pub struct VideoCmdArgs {
    /// The executed case (`executed.json`).
    executed: PathBuf,
    #[arg(long)]
    scene: PathBuf,
    #[arg(long)]
    model: PathBuf,
    /// Output `.mp4` (a `<stem>_frames/` PNG directory without ffmpeg); one layout.
    #[arg(long)]
    out: PathBuf,
    /// Replace an existing --out file that is not an MP4 (a frames directory holding anything
    /// but our frames is never replaced).
    #[arg(long)]
    force: bool,
    #[command(flatten)]
    video: VideoArgs,
}

pub fn video(a: VideoCmdArgs) -> anyhow::Result<()> {
    let inputs = [a.executed.as_path(), a.scene.as_path(), a.model.as_path()];
    super::out_file::check_not_input(&a.out, &inputs)?;
    super::out_file::check_not_input(&render::encode::png_dir(&a.out), &inputs)?;
    let png = a.video.png || render::encode::find_ffmpeg().is_none();
    render::clip_out::check_clip_out(&a.out, png, a.force)?;
    let scene = scene::load_scene(&a.scene)?;
    let (model, _) = recon::model_io::load_model_for_scene(&a.model, &a.scene, &scene)?;
    let executed = scene::executed::load_executed(&a.executed)?;
    let settings = a.video.settings();
    let layouts = settings.resolved_layouts(&scene)?;
    let [layout] = layouts.as_slice() else {
        anyhow::bail!("--layouts: `video` writes one layout, got {}", layouts.len())
    };
    let spec = render::video::VideoSpec {
        layout: layout.clone(),
        fps: settings.fps,
        lead_in_s: settings.lead_in_s,
        scale: settings.scale,
        png_only: settings.png_only,
        force: a.force,
        ..Default::default()
    };
    render::video::check_spec(&scene, &spec)?;
    let pb = count_bar("frames");
    let out = match a.video.device {
        Device::Cpu => {
            render::video::CaseView::new(&CpuF32, &model, &scene, &executed)?.render_video(&spec, &a.out, &pb)?
        }
        Device::CpuF64 => {
            render::video::CaseView::new(&Cpu, &model, &scene, &executed)?.render_video(&spec, &a.out, &pb)?
        }
        Device::Cuda => {
            let backend = open_cuda()?;
            render::video::CaseView::new(&backend, &model, &scene, &executed)?.render_video(&spec, &a.out, &pb)?
        }
    };
    pb.finish_and_clear();
    println!("wrote {} ({} frames, {}x{} at {} fps)", out.path.display(), out.frames, out.width, out.height, out.fps);
    if let render::encode::VideoKind::PngSequence { why } = &out.kind {
        println!("note: PNG frames, not MP4: {why}");
    }
    Ok(())
}
