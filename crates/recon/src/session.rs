//! A whole training run for `carla-gs train`: load the scene and its priors, make the views,
//! initialise (or resume from the checkpoint), iterate with a progress bar showing loss and PSNR,
//! checkpoint at intervals (crash-safe), and write the model directory: in place for a new or
//! resumed run, or built beside an existing model and swapped in at the end ([`crate::out_dir`]).

use crate::backend::Backend;
use crate::checkpoint::{self, TrainState};
use crate::config::TrainConfig;
use crate::data::{load_views, PriorLoader, View, ViewSet};
use crate::device::DeviceTrainer;
use crate::error::ReconError;
use crate::init::{initialise, scene_extent, InitReport};
use crate::loss::LossParts;
use crate::model_io::{write_model_with, ModelRecord};
use crate::out_dir::{ForceMode, WorkDir};
use crate::resume;
use crate::train::{StepReport, Trainer};
use indicatif::ProgressBar;
use scene::Scene;
use std::path::Path;
use std::time::Instant;

pub struct TrainRequest<'a> {
    pub scene_dir: &'a Path,
    pub out_dir: &'a Path,
    pub cfg: TrainConfig,
    pub resume: bool,
    /// What to do with an existing `out_dir` when not resuming.
    pub force: ForceMode,
    /// Stop (with a checkpoint) after this iteration, as if killed there (tests, budgets).
    pub stop_after: Option<usize>,
    pub priors: &'a PriorLoader<'a>,
}

#[derive(Clone, Debug)]
pub struct TrainSummary {
    pub iterations_done: usize,
    pub seconds: f64,
    pub iterations_per_second: f64,
    pub gaussians: usize,
    pub last_loss: LossParts,
    /// Mean training-view PSNR over the last 100 iterations.
    pub recent_psnr: f64,
    pub views_train: usize,
    pub views_held_out: usize,
    /// `--resume` of a run that had already finished: nothing was trained or rewritten.
    pub already_finished: bool,
}

/// Loads the scene's views at the config's scale, for training.
pub fn prepare(scene_dir: &Path, cfg: &TrainConfig, priors: &PriorLoader) -> Result<(Scene, Vec<View>), ReconError> {
    let (scene, views) = prepare_views(scene_dir, cfg, priors, ViewSet::All)?;
    if views.iter().all(|v| v.held_out) {
        return Err(ReconError::Input(format!("{}: every view is held out; nothing to train on", scene_dir.display())));
    }
    Ok((scene, views))
}

/// Loads the views of `set` at the config's scale, once their memory is checked (`memory`).
pub fn prepare_views(
    scene_dir: &Path,
    cfg: &TrainConfig,
    priors: &PriorLoader,
    set: ViewSet,
) -> Result<(Scene, Vec<View>), ReconError> {
    let scene = scene::load_scene(scene_dir)?;
    let with_priors = scene_dir.join("priors").join("priors.json").is_file();
    let keep = set.keeps(&scene, cfg.held_out_every);
    let training = set == ViewSet::All;
    let available = crate::memory::available_bytes()?;
    if training {
        crate::camera::check_scale(&scene.cameras, cfg.scale)?;
    }
    let left_out = if training && cfg.protocol != crate::protocol::Protocol::None {
        crate::memory::LEFT_OUT_BYTES_PER_PIXEL
    } else {
        0
    };
    let targets = crate::memory::check_views(&scene, cfg.scale, with_priors, left_out, &keep, training, available)?;
    if training {
        crate::memory::check_model(cfg, crate::init::actor_tracks(&scene).len(), targets, available)?;
    }
    let mut views = load_views(scene_dir, &scene, cfg.scale, cfg.held_out_every, set, priors, &ProgressBar::hidden())?;
    cfg.set_actor_clock(&mut views);
    Ok((scene, views))
}

pub fn train<B: Backend>(req: TrainRequest, backend: B, progress: &ProgressBar) -> Result<TrainSummary, ReconError> {
    let cfg = req.cfg.clone();
    cfg.validate().map_err(ReconError::Config)?;
    // model.json records the scene directory as text: a path that is not UTF-8 is refused
    // before anything is trained or written.
    if req.scene_dir.to_str().is_none() {
        return Err(ReconError::Input(format!(
            "{}: the scene path contains invalid UTF-8 (model.json records it as text); rename it",
            req.scene_dir.display()
        )));
    }
    let loaded = scene::load_scene(req.scene_dir)?;
    let run = resume::identity(req.scene_dir, &loaded, &cfg)?;
    // A run killed before its first checkpoint (or an empty directory) has nothing to resume:
    // it starts afresh.
    let resumed = match req.resume && !crate::out_dir::not_started(req.out_dir) {
        true => Some(resume::open(req.out_dir, &cfg, &run, &loaded)?),
        false => None,
    };
    // A finished run is left as it is; one killed between its last checkpoint and its
    // model.json goes on to write the model (no iteration runs).
    let complete = req.out_dir.join("model.json").is_file();
    if let Some(st) = resumed.as_ref().filter(|st| st.next_iteration == cfg.iterations && complete) {
        return Ok(finished(st));
    }
    let work = crate::out_dir::plan(req.out_dir, req.resume, req.force)?;
    let result = run_in(&req, &work, resumed, &run, backend, progress);
    match result {
        Ok(summary) => {
            work.commit()?;
            Ok(summary)
        }
        Err(e) => {
            work.discard();
            Err(e)
        }
    }
}

/// Trains into `work` (the destination or its staging directory).
fn run_in<B: Backend>(
    req: &TrainRequest,
    work: &WorkDir,
    resumed: Option<TrainState>,
    run: &checkpoint::RunIdentity,
    backend: B,
    progress: &ProgressBar,
) -> Result<TrainSummary, ReconError> {
    let cfg = req.cfg.clone();
    let (scene, mut views) = prepare(req.scene_dir, &cfg, req.priors)?;
    let left_out = crate::protocol::apply(cfg.protocol, &scene, &mut views);
    if cfg.protocol != crate::protocol::Protocol::None {
        let vehicles: std::collections::BTreeSet<&str> = left_out.iter().map(|s| s.track.as_str()).collect();
        tracing::info!(
            protocol = cfg.protocol.as_str(),
            pairs = left_out.len(),
            vehicles = vehicles.len(),
            "vehicle pixels left out of training"
        );
    }
    work.create()?;
    let out_dir = work.path();
    let ckpt_path = out_dir.join("checkpoint.bin");
    let extent = scene_extent(&views);
    let (state, init): (TrainState, Option<InitReport>) = if let Some(st) = resumed {
        (st, None)
    } else {
        let (model, report) =
            initialise(req.scene_dir, &scene, &views, &cfg.init, cfg.stored_degree(), cfg.sky_res, cfg.seed)?;
        tracing::info!(?report, "initialised");
        (Trainer::<B>::fresh_state(model), Some(report))
    };
    let mut record = ModelRecord {
        format: String::new(),
        scene_name: scene.name.clone(),
        scene_dir: req.scene_dir.to_path_buf(),
        backend: backend.name().into(),
        iterations: 0,
        held_out_every: cfg.held_out_every,
        scale: cfg.scale,
        extent,
        background_file: String::new(),
        background_gaussians: 0,
        actors: vec![],
        sky_res: cfg.sky_res,
        train_seconds: 0.0,
        iterations_per_second: 0.0,
        init: None,
        last_loss: LossParts::default(),
        antialiased: cfg.antialiased,
    };
    // The config is written before the first step so an interrupted run can be resumed.
    let toml = toml::to_string(&cfg).map_err(|e| ReconError::Config(e.to_string()))?;
    scene::write_file_atomic(&out_dir.join("config.toml"), toml.as_bytes())?;
    let mut trainer = match backend.gpu() {
        Some(gpu) => {
            tracing::info!(device = %gpu.describe(), "training on the device");
            Runner::Device(Box::new(DeviceTrainer::new(&scene, &views, cfg.clone(), gpu, state, extent)?))
        }
        None => Runner::Host(Box::new(Trainer::new(&scene, &views, cfg.clone(), backend, state, extent))),
    };
    let start_it = trainer.next_iteration();
    let end = req.stop_after.map_or(cfg.iterations, |s| s.min(cfg.iterations));
    progress.set_length(cfg.iterations as u64);
    progress.set_position(start_it as u64);
    let t0 = Instant::now();
    let mut last_checkpoint = t0;
    let mut recent = std::collections::VecDeque::new();
    let mut last = LossParts::default();
    while trainer.next_iteration() < end {
        let it = trainer.next_iteration();
        let rep = trainer.step()?;
        check_loss(&rep.loss, it)?;
        last = rep.loss;
        recent.push_back(rep.psnr);
        if recent.len() > 100 {
            recent.pop_front();
        }
        let n = trainer.next_iteration();
        if n.is_multiple_of(10) || n == end {
            progress.set_message(format!(
                "loss {:.4} psnr {:.2} dB  {} gaussians",
                rep.loss.total, rep.psnr, rep.gaussians
            ));
        }
        progress.set_position(n as u64);
        if let Some(c) = rep.densified {
            tracing::debug!(iteration = n, ?c, gaussians = rep.gaussians, "density control");
        }
        if checkpoint_due(&cfg, n, end, last_checkpoint.elapsed().as_secs_f64()) {
            checkpoint::save(&ckpt_path, trainer.state()?, run)?;
            last_checkpoint = Instant::now();
        }
    }
    let seconds = t0.elapsed().as_secs_f64();
    if let Runner::Device(d) = &trainer {
        let (secs, times) = d.density_seconds();
        tracing::info!(seconds = secs, times, "density control on the device");
        tracing::info!(phases = %d.host_phases(), "host seconds per phase of the device iterations");
    }
    let state = trainer.state()?;
    checkpoint::save(&ckpt_path, state, run)?;
    let done = state.next_iteration;
    let ran = done - start_it;
    record.iterations = done;
    record.train_seconds = seconds;
    record.iterations_per_second = ran as f64 / seconds.max(1e-9);
    record.last_loss = last;
    let mirrored = crate::train::mirrored_actors(&scene, state, &cfg);
    let saved = crate::bake::baked(state, &cfg, &mirrored);
    write_model_with(out_dir, &saved, &mut record, &cfg, init.as_ref(), &|ai| mirrored[ai])?;
    Ok(TrainSummary {
        iterations_done: done,
        seconds,
        iterations_per_second: record.iterations_per_second,
        gaussians: state.model.gaussian_count(),
        last_loss: last,
        recent_psnr: recent.iter().sum::<f64>() / recent.len().max(1) as f64,
        views_train: views.iter().filter(|v| !v.held_out).count(),
        views_held_out: views.iter().filter(|v| v.held_out).count(),
        already_finished: false,
    })
}

/// Refuses a loss that is not finite: training on from it would only write NaN Gaussians (a model
/// that cannot be read back). The error names the iteration (1-based) and the first bad term.
fn check_loss(loss: &LossParts, it: usize) -> Result<(), ReconError> {
    let terms = [
        ("l1", loss.l1),
        ("ssim", loss.ssim),
        ("depth", loss.depth),
        ("normal", loss.normal),
        ("geo", loss.geo),
        ("flat", loss.flat),
        ("total", loss.total),
    ];
    match terms.iter().find(|(_, v)| !v.is_finite()) {
        None => Ok(()),
        Some((name, v)) => Err(ReconError::Input(format!(
            "iteration {}: the {name} loss term is {v} (total {}): training stopped and no model was \
             written; check the scene's priors (non-finite or non-unit normals, non-finite depths) and \
             the training settings",
            it + 1,
            loss.total
        ))),
    }
}

/// Whether a periodic checkpoint is written after 1-based iteration `n` of a run ending at `end`
/// (the end always writes one), `since_last` seconds after the last checkpoint or the start.
fn checkpoint_due(cfg: &TrainConfig, n: usize, end: usize, since_last: f64) -> bool {
    cfg.checkpoint_interval > 0
        && n.is_multiple_of(cfg.checkpoint_interval)
        && n < end
        && since_last >= cfg.checkpoint_min_seconds
}

/// The summary of a resumed run that had already finished (nothing trained, nothing written).
fn finished(st: &TrainState) -> TrainSummary {
    TrainSummary {
        iterations_done: st.next_iteration,
        seconds: 0.0,
        iterations_per_second: 0.0,
        gaussians: st.model.gaussian_count(),
        last_loss: LossParts::default(),
        recent_psnr: 0.0,
        views_train: 0,
        views_held_out: 0,
        already_finished: true,
    }
}

/// The loop's trainer: on the host (any backend) or entirely on the GPU.
enum Runner<'s, B: Backend> {
    Host(Box<Trainer<'s, B>>),
    Device(Box<DeviceTrainer<'s>>),
}

impl<B: Backend> Runner<'_, B> {
    fn next_iteration(&self) -> usize {
        match self {
            Runner::Host(t) => t.state.next_iteration,
            Runner::Device(t) => t.next_iteration(),
        }
    }

    fn step(&mut self) -> Result<StepReport, ReconError> {
        match self {
            Runner::Host(t) => Ok(t.step()),
            Runner::Device(t) => t.step(),
        }
    }

    /// The current state on the host (the device trainer copies it back first).
    fn state(&mut self) -> Result<&TrainState, ReconError> {
        match self {
            Runner::Host(t) => Ok(&t.state),
            Runner::Device(t) => t.sync_host(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checkpoints_wait_for_their_interval_and_their_time() {
        let cfg = TrainConfig { checkpoint_interval: 500, checkpoint_min_seconds: 300.0, ..Default::default() };
        assert!(!checkpoint_due(&cfg, 500, 15_000, 120.0), "too soon after the start");
        assert!(checkpoint_due(&cfg, 500, 15_000, 300.0));
        assert!(!checkpoint_due(&cfg, 501, 15_000, 1e6), "not on the interval");
        assert!(!checkpoint_due(&cfg, 15_000, 15_000, 1e6), "the end writes its own");
        let every = TrainConfig { checkpoint_min_seconds: 0.0, ..cfg.clone() };
        assert!(checkpoint_due(&every, 500, 15_000, 0.0));
        let never = TrainConfig { checkpoint_interval: 0, ..every };
        assert!(!checkpoint_due(&never, 500, 15_000, 1e6));
    }

    #[test]
    fn a_non_finite_loss_stops_training_naming_the_iteration_and_term() {
        let ok = LossParts { total: 0.5, l1: 0.4, ssim: 0.1, ..Default::default() };
        assert!(check_loss(&ok, 0).is_ok());
        let bad = LossParts { normal: f64::NAN, total: f64::NAN, ..ok };
        let e = check_loss(&bad, 6).unwrap_err().to_string();
        assert!(e.contains("iteration 7") && e.contains("the normal loss term is NaN"), "{e}");
        let inf = LossParts { total: f64::NEG_INFINITY, ..ok };
        assert!(check_loss(&inf, 0).unwrap_err().to_string().contains("the total loss term is -inf"));
    }
}
