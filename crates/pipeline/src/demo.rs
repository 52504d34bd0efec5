//! `carla-gs demo`: everything on embedded defaults, on the CPU, in one command (or on a real log
//! with `--input`, `real_log`). A small synthetic street is generated (its seed is chosen so that each showcased behaviour has a physically
//! valid case), its geometry priors computed, a Street-Gaussians model trained and scored on the
//! held-out views, one corner case made per showcased behaviour (sudden braking, cut-in,
//! opposing drift) with the default agent, simulated, exported and rendered, and
//! `report.html` written with all of it and the stage timings.
//!
//! On a real log the trained model is also harvested into `<out>/assets` (the vehicles the log
//! saw well, beside the synthetic fallbacks), and a case whose adversary the log never saw well,
//! or saw only farther away than the case brings it, is drawn with that adversary replaced by the
//! nearest real asset (`auto_replace`; a user's `--replace` wins).
//!
//! Every stage is cached (`cache`): its directory's marker holds the settings it was built from
//! and the key of the stage before, so a second run with the same settings reuses everything
//! and takes seconds, and a changed setting rebuilds that stage and the ones after it. The first
//! key also holds the input folder's fingerprint and the program's ([`scene_key`]): an edited
//! log or a rebuilt carla-gs rebuilds everything. A training
//! run interrupted half-way resumes from its checkpoint.

use crate::auto_replace::{build_library, Swapper, HARVEST_FILE, SYNTH_KINDS};
use crate::cache::{fresh, invalidate, mark};
use crate::case::{CaseRequest, T0Choice};
pub use crate::demo_config::{DemoConfig, DemoResult, StageTime, DEMO_FORMAT};
use crate::run::{run, run_swapping, RunInputs, RunSummary};
use crate::PipelineError;
use cases::spec::T0Spec;
use indicatif::ProgressBar;
use recon::backend::{Backend, CpuF32};
use render::asset::harvest::HarvestReport;
use scene::Behavior;
use serde_json::{json, Value};
use std::path::Path;
use std::time::Instant;

/// Reports what the demo is doing (a stage starting, a progress bar to show).
pub trait DemoProgress {
    fn stage(&self, name: &str);
    fn bar(&self) -> ProgressBar;
}

struct Stages<'a> {
    timings: Vec<StageTime>,
    progress: &'a dyn DemoProgress,
}

impl Stages<'_> {
    /// Runs `build` unless `dir` already holds `key`'s outputs.
    fn cached(
        &mut self,
        name: &str,
        dir: &Path,
        key: &Value,
        build: impl FnOnce() -> Result<(), PipelineError>,
    ) -> Result<(), PipelineError> {
        if let Some(m) = fresh(dir, key) {
            self.timings.push(StageTime { stage: name.into(), seconds: m.seconds, cached: true });
            return Ok(());
        }
        self.progress.stage(name);
        invalidate(dir);
        let clock = Instant::now();
        build()?;
        let seconds = clock.elapsed().as_secs_f64();
        mark(dir, key, seconds)?;
        self.timings.push(StageTime { stage: name.into(), seconds, cached: false });
        Ok(())
    }
}

/// The first stage's cache key, which every later stage's holds: the synthetic street's settings,
/// or the input folder with its files' fingerprint (the demo's own `out` left out where it lies
/// inside); and the program's (`fingerprint`), so neither an edited log nor a rebuilt carla-gs
/// reuses stages made before.
pub fn scene_key(cfg: &DemoConfig, out: &Path) -> Result<Value, PipelineError> {
    let program = crate::fingerprint::program();
    Ok(match &cfg.input {
        None => json!({"synth": {"frames": cfg.frames, "cameras": cfg.cameras, "width": cfg.width,
            "height": cfg.height, "seed": cfg.scene_seed}, "program": program, "version": 2}),
        Some(input) => {
            let input = std::fs::canonicalize(input).map_err(PipelineError::io(input))?;
            let out = std::fs::canonicalize(out).unwrap_or_else(|_| out.to_path_buf());
            let files = crate::fingerprint::folder(&input, |p| p.starts_with(&out))
                .map_err(|e| PipelineError::stage("ingest the log", e))?;
            json!({"input": input, "files": files, "program": program, "version": 2})
        }
    })
}

/// Runs the demo into `out` (created if needed) and writes `report.html` there.
pub fn run_demo(cfg: &DemoConfig, out: &Path, progress: &dyn DemoProgress) -> Result<DemoResult, PipelineError> {
    run_demo_on(&CpuF32, cfg, out, progress)
}

/// [`run_demo`] with the rasterizer `backend` for training, evaluation and the videos. A backend
/// other than the CPU reference is part of the training stage's cache key (its f32 model differs).
pub fn run_demo_on<B: Backend + Clone>(
    backend: &B,
    cfg: &DemoConfig,
    out: &Path,
    progress: &dyn DemoProgress,
) -> Result<DemoResult, PipelineError> {
    let clock = Instant::now();
    std::fs::create_dir_all(out).map_err(PipelineError::io(out))?;
    // Marked as ours before anything else is written, so that a demo killed part-way is
    // recognised (and continued from its cache) by the next run.
    let marker = out.join("demo.json");
    if std::fs::symlink_metadata(&marker).is_err() {
        scene::write_file_atomic(&marker, json!({"format": DEMO_FORMAT, "complete": false}).to_string().as_bytes())?;
    }
    let mut stages = Stages { timings: vec![], progress };
    let scene_dir = out.join("scene");
    let synth_cfg = synth::SynthConfig {
        frames: cfg.frames,
        cameras: cfg.cameras,
        width: cfg.width,
        height: cfg.height,
        seed: cfg.scene_seed,
        force: true,
        preview: false,
    };

    let scene_key = scene_key(cfg, out)?;
    if let Some(input) = &cfg.input {
        stages.cached("ingest the log", &scene_dir, &scene_key, || {
            let pb = progress.bar();
            crate::real_log::build_scene(input, &scene_dir, &pb)?;
            pb.finish_and_clear();
            Ok(())
        })?;
    } else {
        stages.cached("synthesise scene", &scene_dir, &scene_key, || {
            let pb = progress.bar();
            pb.set_length(cfg.frames as u64);
            synth::synthesize(&synth_cfg, &scene_dir, &mut |done, _| pb.set_position(done as u64))?;
            pb.finish_and_clear();
            Ok(())
        })?;
    }

    let priors_dir = scene_dir.join(recon::priors::PRIORS_DIR);
    let priors_key = json!({"scene": scene_key, "priors": {"seed": cfg.seed}});
    stages.cached("geometry priors", &priors_dir, &priors_key, || {
        let scene = scene::load_scene(&scene_dir)?;
        let opts = recon::priors::PriorOptions { force: true, seed: cfg.seed, ..Default::default() };
        let pb = progress.bar();
        recon::priors::compute_priors(&scene_dir, &scene, &opts, &pb).map_err(|e| PipelineError::stage("priors", e))?;
        pb.finish_and_clear();
        Ok(())
    })?;

    let model_dir = out.join("model");
    let train_key = match backend.name() {
        "cpu" => json!({"priors": priors_key, "train": cfg.train}),
        device => json!({"priors": priors_key, "train": cfg.train, "device": device}),
    };
    let train_stage = format!("train ({})", backend.name().to_uppercase());
    stages.cached(&train_stage, &model_dir, &train_key, || {
        let priors = recon::targets::prior_loader(&scene_dir)?;
        let resume = recon::model_io::load_config(&model_dir).is_ok_and(|c| c == cfg.train)
            && model_dir.join("checkpoint.bin").is_file();
        let pb = progress.bar();
        let req = recon::session::TrainRequest {
            scene_dir: &scene_dir,
            out_dir: &model_dir,
            cfg: cfg.train.clone(),
            resume,
            force: recon::out_dir::ForceMode::Replace,
            stop_after: None,
            priors: priors.as_ref(),
        };
        recon::session::train(req, backend.clone(), &pb)?;
        pb.finish_and_clear();
        Ok(())
    })?;

    let eval_dir = out.join("recon-eval");
    let eval_key = json!({"model": train_key});
    stages.cached("evaluate reconstruction", &eval_dir, &eval_key, || {
        let priors = recon::targets::prior_loader(&scene_dir)?;
        let report = recon::eval::evaluate_model_dir(backend, &model_dir, &scene_dir, priors.as_ref())?;
        std::fs::create_dir_all(&eval_dir).map_err(PipelineError::io(&eval_dir))?;
        scene::format::write_json_pretty(&eval_dir.join("eval.json"), &report)?;
        crate::report::held_out_pictures(backend, &model_dir, &scene_dir, &eval_dir)?;
        Ok(())
    })?;
    let recon: recon::eval::EvalReport = scene::format::read_json(&eval_dir.join("eval.json"))?;

    let scene = scene::load_scene(&scene_dir)?;
    // `compare:FRONT,front3` show the scene's own front cameras (`render::layout`).
    let render_settings = &cfg.render;
    let (mut model, record) = recon::model_io::load_model(&model_dir)?;
    // The replacement showcase compares against the model as trained.
    let trained = if cfg.replace.is_empty() { None } else { Some(model.clone()) };
    // On a real log the library also holds the log's own well-seen vehicles.
    let auto = cfg.auto_replace.filter(|_| cfg.input.is_some());
    let lib = out.join("assets");
    let mut lib_key = json!({"kinds": SYNTH_KINDS, "voxel": crate::synth_asset::DEFAULT_VOXEL_M, "version": 1});
    if let Some(a) = &auto {
        lib_key["harvest"] = json!({"model": train_key, "thresholds": a.thresholds, "version": 1});
    }
    let mut harvest: Option<HarvestReport> = None;
    if !cfg.replace.is_empty() || auto.is_some() {
        let name = if auto.is_some() { "asset library + harvest" } else { "asset library" };
        let thresholds = auto.as_ref().map(|a| a.thresholds);
        stages.cached(name, &lib, &lib_key, || build_library(&lib, &scene_dir, &model_dir, thresholds.as_ref()))?;
        if auto.is_some() {
            harvest = Some(scene::format::read_json(&lib.join(HARVEST_FILE))?);
        }
    }
    if !cfg.replace.is_empty() {
        let pairs =
            cfg.replace.iter().map(|r| render::asset::replace::parse_replace_arg(r)).collect::<Result<Vec<_>, _>>()?;
        let opts = render::asset::align::AlignOptions::default();
        let up = render::asset::library::UpAxis::Z;
        render::asset::replace::replace_specs(&mut model, &scene_dir, Some(&model_dir), &pairs, &lib, up, &opts)?;
    }
    let user_replaced: Vec<String> =
        cfg.replace.iter().filter_map(|r| r.split_once('=')).map(|(t, _)| t.into()).collect();
    let mut cases = Vec::new();
    for &behavior in &cfg.behaviors {
        let case_dir = out.join("cases").join(behavior.as_str());
        let req = CaseRequest {
            behavior,
            agent: cfg.agent,
            adversary: None,
            zone: None,
            ttc_s: None,
            insert: reason::insert::InsertMode::Fallback,
            seed: cfg.seed,
            seeds_per_t0: 3,
            refine_rounds: 3,
            window: crate::case::rendered_window(),
            // The tables' window when no case succeeds over the plan's own end (`case`).
            fallback_window: Some(cases::window::Window::default()),
        };
        let mut key = json!({"model": train_key, "request": req, "t0": "every:0.5s", "render": render_settings});
        if !cfg.replace.is_empty() {
            key["replace"] = json!(cfg.replace);
        }
        if let Some(a) = &auto {
            key["auto_replace"] = json!({"settings": a, "library": lib_key, "version": 1});
        }
        stages.cached(&format!("case {}", behavior.as_str()), &case_dir, &key, || {
            let inputs = RunInputs { scene: &scene, model: &model, backend, render: render_settings, out: &case_dir };
            let pb = progress.bar();
            let t0 = T0Choice::Search(T0Spec::Every(0.5));
            match (&auto, &harvest) {
                (Some(settings), Some(harvest)) => {
                    let swapper = Swapper {
                        scene: &scene,
                        scene_dir: &scene_dir,
                        model: &model,
                        model_dir: &model_dir,
                        library: &lib,
                        harvest,
                        settings: *settings,
                        fps: render_settings.fps,
                        user_replaced: user_replaced.clone(),
                    };
                    run_swapping(&inputs, &req, &t0, &pb, &|e| swapper.swap(e).map(|(m, c)| (m, Some(c))))?
                }
                _ => run(&inputs, &req, &t0, None, &pb)?,
            };
            pb.finish_and_clear();
            Ok(())
        })?;
        cases.push((behavior, scene::format::read_json(&case_dir.join("run.json"))?));
    }

    // Vehicle replacement: the first case's adversary (the lead vehicle without a case).
    let first_case = cases.iter().find_map(|(b, s): &(Behavior, RunSummary)| {
        s.result.as_ref().and_then(|r| r.best()).map(|c| (*b, c.plan.adversary_track.clone()))
    });
    let track = first_case.as_ref().map_or_else(|| "lead-1".to_string(), |(_, t)| t.clone());
    let case_dir = first_case.map(|(b, _)| out.join("cases").join(b.as_str()));
    let replace_dir = out.join("replacement");
    let replace_key = json!({"model": train_key, "track": track, "case": case_dir, "version": 2});
    // The showcase scores the replacement against the synthetic street's exact render of the
    // vehicle: a real log has none, so it runs on the synthetic street only.
    if cfg.input.is_none() {
        stages.cached("vehicle replacement", &replace_dir, &replace_key, || {
            let original = trained.as_ref().unwrap_or(&model);
            let case = case_dir.as_deref();
            crate::replace_showcase::showcase(backend, original, &scene, &synth_cfg, &track, case, &replace_dir)
                .map(|_| ())
        })?;
    }
    let replacement = match cfg.input {
        None => scene::format::read_json(&replace_dir.join(crate::replace_showcase::SHOWCASE_FILE)).ok(),
        Some(_) => None,
    };

    let mut result = DemoResult {
        format: DEMO_FORMAT.into(),
        config: cfg.clone(),
        out: out.to_path_buf(),
        recon,
        model: record,
        cases,
        timings: stages.timings,
        total_seconds: 0.0,
        replacement,
        harvest,
    };
    let clock_report = Instant::now();
    progress.stage("report");
    crate::report::write_report(&result, out)?;
    result.timings.push(StageTime {
        stage: "report".into(),
        seconds: clock_report.elapsed().as_secs_f64(),
        cached: false,
    });
    result.total_seconds = clock.elapsed().as_secs_f64();
    scene::format::write_json_pretty(&out.join("demo.json"), &result)?;
    Ok(result)
}
