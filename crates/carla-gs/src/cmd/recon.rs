//! `carla-gs train`, `eval-recon` and `render`: argument parsing around the `recon` crate.

use super::progress::count_bar;
use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use recon::backend::{Backend, Cpu, CpuF32};
use recon::backend_cuda::Cuda;
use recon::compose::Layers;
use recon::data::PriorLoader;
use recon::TrainConfig;
use std::path::{Path, PathBuf};

/// Where the rasterizer runs.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum Device {
    /// The CPU in f32 (SIMD tile kernels; held to the f64 reference by parity tests).
    Cpu,
    /// The f64 CPU reference (slower; the definition the other paths are tested against).
    CpuF64,
    /// The CUDA rasterizer on GPU 0 (needs the NVIDIA driver and NVRTC).
    Cuda,
}

/// Opens the CUDA backend, or says why this machine cannot run it.
pub fn open_cuda() -> anyhow::Result<Cuda> {
    let c = Cuda::new().map_err(|e| anyhow::anyhow!("--device cuda: {e}"))?;
    eprintln!("device: {}", c.describe());
    Ok(c)
}

#[derive(clap::Args)]
pub struct TrainArgs {
    scene: PathBuf,
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    settings: Settings,
    /// Continue from <out>/checkpoint.bin (same scene and settings required; a finished run is
    /// reported as finished and left untouched, exit 0).
    #[arg(long)]
    resume: bool,
    /// Replace an existing model directory at --out (only one of ours: model.json or
    /// checkpoint.bin); the old model stays until the new one is complete.
    #[arg(long, conflicts_with = "resume")]
    force: bool,
    #[arg(long, value_enum, default_value = "cpu")]
    device: Device,
    /// Stop after this iteration (with a checkpoint), to continue later with --resume.
    #[arg(long)]
    stop_after: Option<usize>,
}

/// The training settings: a TOML file and the flags that override it.
#[derive(clap::Args)]
pub struct Settings {
    /// TOML training config (docs/recon.md); the flags below override it.
    #[arg(long)]
    config: Option<PathBuf>,
    #[arg(long)]
    iters: Option<usize>,
    /// Train at this fraction of the image size.
    #[arg(long)]
    scale: Option<f64>,
    #[arg(long)]
    seed: Option<u64>,
}

impl Settings {
    pub fn config(&self) -> anyhow::Result<TrainConfig> {
        let mut cfg = match &self.config {
            Some(p) => {
                let text = std::fs::read_to_string(p).with_context(|| format!("{}: cannot read", p.display()))?;
                TrainConfig::from_toml(&text).map_err(|e| anyhow::anyhow!("{}: {e}", p.display()))?
            }
            None => TrainConfig::default(),
        };
        cfg.iterations = self.iters.unwrap_or(cfg.iterations);
        cfg.scale = self.scale.unwrap_or(cfg.scale);
        cfg.seed = self.seed.unwrap_or(cfg.seed);
        cfg.validate().map_err(|e| anyhow::anyhow!("settings: {e}"))?;
        Ok(cfg)
    }
}

/// The scene's priors as training targets (none until `carla-gs priors` has run).
pub fn priors_of(scene_dir: &Path) -> anyhow::Result<Box<PriorLoader<'static>>> {
    let loader = recon::targets::prior_loader(scene_dir)?;
    if !scene_dir.join("priors").is_dir() {
        eprintln!(
            "note: {} has no priors/ (run `carla-gs priors` first): depth, normal and geometry losses are off",
            scene_dir.display()
        );
    }
    Ok(loader)
}

pub fn train(a: TrainArgs) -> anyhow::Result<()> {
    super::out_dir::check_not_inside(&a.out, &[&a.scene])?;
    match a.device {
        Device::Cpu => train_on(a, CpuF32),
        Device::CpuF64 => train_on(a, Cpu),
        Device::Cuda => {
            let c = open_cuda()?;
            train_on(a, c)
        }
    }
}

fn train_on<B: Backend>(a: TrainArgs, backend: B) -> anyhow::Result<()> {
    let cfg = a.settings.config()?;
    let priors = priors_of(&a.scene)?;
    let pb = ProgressBar::new(cfg.iterations as u64);
    pb.set_style(
        ProgressStyle::with_template("train [{bar:30}] {pos}/{len} {per_sec} ({eta}) {msg}").expect("valid template"),
    );
    let req = recon::session::TrainRequest {
        scene_dir: &a.scene,
        out_dir: &a.out,
        cfg,
        resume: a.resume,
        force: if a.force { recon::out_dir::ForceMode::Replace } else { recon::out_dir::ForceMode::Refuse },
        stop_after: a.stop_after,
        priors: priors.as_ref(),
    };
    let s = recon::session::train(req, backend, &pb)?;
    pb.finish_and_clear();
    if s.already_finished {
        println!(
            "{}: already finished ({} of {} iterations); nothing to resume, nothing rewritten",
            a.out.display(),
            s.iterations_done,
            s.iterations_done
        );
        return Ok(());
    }
    println!(
        "trained {} iterations ({} train / {} held-out views) in {:.1} s ({:.2} it/s): {} Gaussians, loss {:.4}, recent train PSNR {:.2} dB -> {}",
        s.iterations_done,
        s.views_train,
        s.views_held_out,
        s.seconds,
        s.iterations_per_second,
        s.gaussians,
        s.last_loss.total,
        s.recent_psnr,
        a.out.display()
    );
    Ok(())
}

#[derive(clap::Args)]
pub struct EvalArgs {
    model: PathBuf,
    scene: PathBuf,
    /// Print the report as JSON (per view included).
    #[arg(long)]
    json: bool,
    #[arg(long, value_enum, default_value = "cpu")]
    device: Device,
    /// Also draw each moving-vehicle pair (held-out image beside its render and box profile,
    /// every pixel classed) into this new directory, with `pairs.csv` (docs/pandaset.md).
    #[arg(long)]
    pair_masks: Option<PathBuf>,
    /// The moving-vehicle masks the appearance scores use (docs/recon.md, "Moving vehicles on the
    /// log's pixels"): read from this directory when it exists, else computed and written there,
    /// so another tool (tools/bench/gsplat_train.py) scores the same pixels.
    #[arg(long)]
    vehicle_masks: Option<PathBuf>,
}

/// The report of `a` on `backend`, and the pair pictures if asked for.
fn eval_on<B: recon::backend::Backend>(
    backend: &B,
    a: &EvalArgs,
    priors: &recon::data::PriorLoader,
) -> anyhow::Result<recon::eval::EvalReport> {
    let (r, from) =
        recon::eval::evaluate_model_dir_with(backend, &a.model, &a.scene, priors, a.vehicle_masks.as_deref())?;
    if let Some(dir) = &a.vehicle_masks {
        let verb = if from == recon::eval::MasksFrom::Read { "read" } else { "wrote" };
        eprintln!("{verb} the moving-vehicle masks {} {}", if verb == "read" { "from" } else { "->" }, dir.display());
    }
    if let Some(dir) = &a.pair_masks {
        let n = recon::eval_pair_png::write_pair_masks(backend, &a.model, &a.scene, priors, dir)?;
        eprintln!("wrote {n} pair pictures and pairs.csv -> {}", dir.display());
    }
    Ok(r)
}

pub fn eval(a: EvalArgs) -> anyhow::Result<()> {
    if let Some(dir) = a.pair_masks.as_ref().filter(|d| d.exists()) {
        anyhow::bail!("{}: already exists (--pair-masks writes a new directory)", dir.display());
    }
    let priors = priors_of(&a.scene)?;
    let r = match a.device {
        Device::Cpu => eval_on(&CpuF32, &a, priors.as_ref())?,
        Device::CpuF64 => eval_on(&Cpu, &a, priors.as_ref())?,
        Device::Cuda => eval_on(&open_cuda()?, &a, priors.as_ref())?,
    };
    if a.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
        return Ok(());
    }
    // Means over views, or over (view, actor) / (view, moving vehicle) pairs.
    let over = |name: &str, unit: &str, m: &Option<recon::eval::Mean>| match m {
        Some(m) => println!("{name:<28} {:>9.4}  ({} {unit})", m.mean, m.count),
        None => println!("{name:<28} {:>9}", "n/a"),
    };
    let show = |name: &str, m: &Option<recon::eval::Mean>| over(name, "views", m);
    let pairs = |name: &str, m: &Option<recon::eval::Mean>| over(name, "pairs", m);
    println!("held-out views: {}", r.views);
    show("PSNR (dB)", &r.psnr);
    show("SSIM", &r.ssim);
    show("Normal L1 MAE vs prior (M)", &r.normal_prior_l1);
    show("Normal Cos MAE vs prior (M)", &r.normal_prior_cos);
    show("Normal L1 MAE vs GT (M)", &r.normal_gt_masked_l1);
    show("Normal Cos MAE vs GT (M)", &r.normal_gt_masked_cos);
    show("Normal L1 MAE vs GT (all)", &r.normal_gt_all_l1);
    show("Normal Cos MAE vs GT (all)", &r.normal_gt_all_cos);
    show("actor mask IoU", &r.actor_iou);
    pairs("per-actor mask IoU", &r.per_actor_iou);
    pairs("moving-vehicle IoU, box hull", &r.moving_vehicle_box_iou);
    pairs("moving-vehicle IoU, profile", &r.moving_vehicle_profile_iou);
    pairs("moving-vehicle IoU, LiDAR", &r.moving_vehicle_lidar_iou);
    pairs("  clear pairs: box hull", &r.moving_vehicle_clear_box_iou);
    pairs("  clear pairs: profile", &r.moving_vehicle_clear_profile_iou);
    pairs("  clear pairs: LiDAR", &r.moving_vehicle_clear_lidar_iou);
    pairs("  profile precision", &r.moving_vehicle_profile_precision);
    pairs("  profile recall", &r.moving_vehicle_profile_recall);
    if r.moving_vehicle_box_iou.is_some() || r.moving_vehicle_too_small > 0 {
        let min = recon::eval_boxes::MIN_PIXELS;
        println!(
            "{:<28} {:>9}  (pairs under {min} px at this scale)",
            "  not scored: too small", r.moving_vehicle_too_small
        );
    }
    if let Some(app) = &r.moving_vehicle_appearance {
        for (name, m) in [("hull", &app.hull), ("rect", &app.rect)] {
            let db = |x: Option<f64>| x.map_or("n/a".to_string(), |v| format!("{v:.2} dB"));
            println!(
                "moving vehicles, {name:<4}: PSNR per image {} ({} of {} images), pooled {}, SSIM {} ({} pairs, {} px)",
                db(m.image_mean_psnr),
                m.images,
                m.images_scored,
                db(m.pooled_psnr),
                m.ssim.map_or("n/a".to_string(), |v| format!("{v:.4}")),
                m.pairs,
                m.pixels
            );
        }
    }
    println!("{:<28} {:>9}  (needs network weights that cannot be fetched here)", "LPIPS", "n/a");
    Ok(())
}

#[derive(clap::Args)]
pub struct RenderArgs {
    model: PathBuf,
    #[arg(long)]
    scene: PathBuf,
    #[arg(long)]
    camera: String,
    #[arg(long)]
    frame: usize,
    #[arg(long)]
    out: PathBuf,
    /// Move the camera sideways by this many metres (positive: to the ego's left).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    shift_m: f64,
    /// Image scale (default: the model's training scale): positive, and the image at most
    /// `render::budget::MAX_PIXELS`.
    #[arg(long)]
    scale: Option<f64>,
    /// Draw only the tracked actors (over black).
    #[arg(long)]
    actors_only: bool,
    /// Replace an existing --out that is not what this command writes.
    #[arg(long)]
    force: bool,
    #[arg(long, value_enum, default_value = "cpu")]
    device: Device,
}

pub fn render(a: RenderArgs) -> anyhow::Result<()> {
    anyhow::ensure!(a.shift_m.is_finite(), "--shift-m must be a finite number of metres, got {}", a.shift_m);
    super::out_file::check_out_file(&a.out, &[&a.model, &a.scene], a.force, "a PNG image", super::out_file::is_png)?;
    if let Some(s) = a.scale {
        render::budget::check_scale("--scale", s)?;
    }
    let scene = scene::load_scene(&a.scene)?;
    let (model, record) = recon::model_io::load_model_for_scene(&a.model, &a.scene, &scene)?;
    let scale = a.scale.unwrap_or(record.scale);
    render::budget::check_scale(&format!("{}: scale", a.model.join("model.json").display()), scale)?;
    let frame = scene
        .frames
        .get(a.frame)
        .with_context(|| format!("--frame {}: the scene has {} frames", a.frame, scene.frames.len()))?;
    let cam = scene.camera(&a.camera).with_context(|| {
        let names: Vec<&str> = scene.cameras.iter().map(|c| c.name.as_str()).collect();
        format!("--camera {}: not in the scene (cameras: {})", a.camera, names.join(", "))
    })?;
    let ego_from_shifted = scene::Transform3::from_yaw_translation(0.0, scene::glam::DVec3::new(0.0, a.shift_m, 0.0));
    let world_from_ego = frame.world_from_ego * ego_from_shifted;
    let sc = recon::camera::splat_camera(cam, &world_from_ego, scale)?;
    let what = format!("--camera {} at scale {scale}", a.camera);
    render::budget::check_size(&what, sc.width as u64, sc.height as u64)?;
    let layers = if a.actors_only { Layers::ActorsOnly } else { Layers::All };
    let bar = count_bar("render");
    let d = match a.device {
        Device::Cpu => recon::view::draw(&CpuF32, &model, &scene, &sc, frame.timestamp_s, layers, &|_| None),
        Device::CpuF64 => recon::view::draw(&Cpu, &model, &scene, &sc, frame.timestamp_s, layers, &|_| None),
        Device::Cuda => recon::view::draw(&open_cuda()?, &model, &scene, &sc, frame.timestamp_s, layers, &|_| None),
    };
    bar.finish_and_clear();
    recon::view::save_png(&a.out, d.width, d.height, &d.rgb)?;
    println!(
        "rendered {} frame {} (shift {:+.2} m) at {}x{} -> {}",
        a.camera,
        a.frame,
        a.shift_m,
        d.width,
        d.height,
        a.out.display()
    );
    Ok(())
}

#[derive(clap::Args)]
pub struct AblateArgs {
    scene: PathBuf,
    #[arg(long)]
    out: PathBuf,
    /// Replace an earlier ablation at --out (table3.json there), whole; a folder of anything
    /// else is refused.
    #[arg(long)]
    force: bool,
    #[command(flatten)]
    settings: Settings,
    #[arg(long, value_enum, default_value = "cpu")]
    device: Device,
}

/// An ablation's output: `table3.json`, a list of rows.
const ABLATE_OUT: super::out_dir::Kind =
    super::out_dir::Kind { what: "an ablation output", marker: "table3.json", ours: is_ablate_out };

fn is_ablate_out(dir: &Path) -> bool {
    scene::format::read_json::<Vec<serde_json::Value>>(&dir.join("table3.json"))
        .is_ok_and(|rows| rows.iter().all(|r| r.get("train_seconds").is_some() && r.get("eval").is_some()))
}

pub fn ablate(a: AblateArgs) -> anyhow::Result<()> {
    let cfg = a.settings.config()?;
    // Built whole beside --out and swapped in at the end (`out_dir`).
    let staged = super::out_dir::stage(&a.out, &[&a.scene], a.force, &ABLATE_OUT)?;
    let out = staged.path().to_path_buf();
    let priors = priors_of(&a.scene)?;
    let bar = |name: &str| {
        let pb = ProgressBar::new(0);
        pb.set_style(
            ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len} ({eta}) {msg}").expect("valid template"),
        );
        pb.set_prefix(name.to_string());
        pb
    };
    let rows = match a.device {
        Device::Cpu => recon::ablate::ablate(&CpuF32, &a.scene, &out, &cfg, priors.as_ref(), &bar)?,
        Device::CpuF64 => recon::ablate::ablate(&Cpu, &a.scene, &out, &cfg, priors.as_ref(), &bar)?,
        Device::Cuda => recon::ablate::ablate(&open_cuda()?, &a.scene, &out, &cfg, priors.as_ref(), &bar)?,
    };
    let md = recon::ablate::markdown(&rows, cfg.iterations);
    scene::write_file_atomic(&out.join("table3.md"), md.as_bytes())?;
    scene::format::write_json_pretty(&out.join("table3.json"), &rows)?;
    staged.commit()?;
    print!("{md}");
    println!("-> {}", a.out.join("table3.md").display());
    Ok(())
}
