//! `carla-gs run`: one corner case end to end, from a scene directory and a trained model to the
//! files a person opens: `scenario.json` (the plan), `executed.json`, `metrics.json` (Table I/II
//! metrics, the t0 attempts, the placement checks of the video), `scenario.xosc` (OpenSCENARIO
//! 1.2), `bev.png` and `tracking.png`, and one video per layout under `videos/`. `run.json`
//! summarises all of it (written last). When no attempt produced a case, `run.json` says why for
//! each t0 and nothing else is written. Every setting (layouts, rate, scale, lead-in, cameras, the
//! model's actor for an `--adversary`, t0) and `--out` itself are checked before any work; the
//! files are built in a staging directory and moved in at the end (`run_out`), so a failed run
//! leaves `--out` as it was.

use crate::case::{select_case_with, Attempt, CaseRequest, T0Choice};
use crate::PipelineError;
use cases::runner::CaseResult;
use indicatif::ProgressBar;
use metrics::CaseMetrics;
use recon::backend::Backend;
use render::encode::VideoOutput;
use render::layout::Layout;
use render::placement::{check_best_camera, check_times, Placement};
use render::video::{CaseView, VideoSpec};
use scene::format::write_json_pretty;
use scene::Scene;
use serde::{Deserialize, Serialize};
use std::path::Path;
use std::time::Instant;

pub use crate::run_out::RUN_FORMAT;

/// How to render the videos of a case.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RenderSettings {
    /// Layouts as `single:<CAMERA>`, `front3`, `compare:<CAMERA>`.
    pub layouts: Vec<String>,
    pub fps: f64,
    pub lead_in_s: f64,
    pub scale: f64,
    pub png_only: bool,
    /// Placement checks spread over the case (plus the farthest-from-log instant).
    pub placement_checks: usize,
    /// The OpenSCENARIO version of `scenario.xosc` (`1.0` for CARLA's ScenarioRunner).
    #[serde(default, with = "xosc_version_text")]
    pub xosc_version: export::XoscVersion,
}

/// `XoscVersion` as its text (`"1.0"`, `"1.2"`) in run and demo records.
mod xosc_version_text {
    use export::XoscVersion;
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &XoscVersion, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(match v {
            XoscVersion::V1_0 => "1.0",
            XoscVersion::V1_2 => "1.2",
        })
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<XoscVersion, D::Error> {
        String::deserialize(d)?.parse().map_err(serde::de::Error::custom)
    }
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            layouts: vec!["compare:FRONT".into(), "front3".into()],
            fps: 24.0,
            lead_in_s: 1.5,
            scale: 1.0,
            png_only: false,
            placement_checks: 4,
            xosc_version: export::XoscVersion::default(),
        }
    }
}

impl RenderSettings {
    pub fn parsed_layouts(&self) -> Result<Vec<Layout>, PipelineError> {
        self.layouts.iter().map(|l| l.parse().map_err(|e| PipelineError::stage("render settings", e))).collect()
    }

    /// The layouts with their cameras as `scene` names them (`Layout::resolve`: `FRONT` is the
    /// scene's front camera), or the first camera it lacks.
    pub fn resolved_layouts(&self, scene: &Scene) -> Result<Vec<Layout>, PipelineError> {
        self.parsed_layouts()?.iter().map(|l| Ok(l.resolve(scene)?)).collect()
    }

    /// The video spec of one layout.
    pub fn spec(&self, layout: &Layout) -> VideoSpec {
        VideoSpec {
            layout: layout.clone(),
            fps: self.fps,
            lead_in_s: self.lead_in_s,
            scale: self.scale,
            png_only: self.png_only,
            ..VideoSpec::default()
        }
    }

    /// The resolved layouts, with every setting checked against `scene` before any work
    /// (`render::video::check_spec`: rate, lead-in, scale and the cameras of each layout).
    pub fn checked_layouts(&self, scene: &Scene) -> Result<Vec<Layout>, PipelineError> {
        let layouts = self.resolved_layouts(scene)?;
        for l in &layouts {
            render::video::check_spec(scene, &self.spec(l))?;
        }
        Ok(layouts)
    }
}

/// Everything of a run that can be checked before it plans anything: the render settings, every
/// camera the placement check may draw, the model's actor of an `--adversary` the scene has, t0.
fn check_before_work<B: Backend>(
    inputs: &RunInputs<B>,
    req: &CaseRequest,
    t0: &T0Choice,
) -> Result<Vec<Layout>, PipelineError> {
    let layouts = inputs.render.checked_layouts(inputs.scene)?;
    let first = inputs.scene.frames[0].timestamp_s;
    for cam in &inputs.scene.cameras {
        render::video::camera_at(inputs.scene, &cam.name, first, inputs.render.scale)?;
    }
    if let Some(track) = &req.adversary {
        if inputs.scene.track(track).is_some() {
            render::video::actor_index(inputs.model, track)?;
        }
    }
    if let T0Choice::At(t) = t0 {
        let (start, end) = (first, inputs.scene.frames[inputs.scene.frames.len() - 1].timestamp_s);
        if !(t.is_finite() && *t >= 0.0 && start + t <= end) {
            return Err(PipelineError::stage(
                "--t0",
                format!("must be from 0 to {:.2} s (the log's length), got {t:?}", end - start),
            ));
        }
    }
    Ok(layouts)
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Video {
    pub layout: String,
    #[serde(flatten)]
    pub output: VideoOutput,
    /// The still of the frame nearest to MinTTC (the case's climax), a PNG beside the video.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub climax: Option<Climax>,
}

/// The video frame a viewer should look at first: where the adversary is closest in time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Climax {
    /// The still's file, relative to the run directory.
    pub file: String,
    /// The frame's index in the video and its log time (s); MinTTC's time.
    pub frame: usize,
    pub t: f64,
    pub t_min_ttc: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Timing {
    pub stage: String,
    pub seconds: f64,
}

/// `metrics.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MetricsFile {
    pub metrics: CaseMetrics,
    /// Where the adversary was drawn vs its box (IoU), at the checked instants.
    pub placement: Vec<Placement>,
    pub attempts: Vec<Attempt>,
}

/// `run.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct RunSummary {
    pub format: String,
    pub scene: String,
    pub request: CaseRequest,
    pub attempts: Vec<Attempt>,
    /// The chosen case (every round of refinement), if any attempt produced one.
    pub result: Option<CaseResult>,
    pub metrics: Option<CaseMetrics>,
    /// The window the chosen case was executed, measured and rendered over.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub window: Option<cases::window::Window>,
    /// Why there is no case, when there is none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub no_case: Option<String>,
    pub placement: Vec<Placement>,
    pub videos: Vec<Video>,
    /// File names under the run directory.
    pub files: Vec<String>,
    pub timings: Vec<Timing>,
    /// The demo's decision on drawing the adversary from a real asset (`auto_replace`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub adversary: Option<crate::auto_replace::AdversaryCheck>,
}

/// Decides, once the case is executed and before anything is drawn, whether its adversary is
/// drawn from another model (`Some`: the model to draw with) and records why.
/// (`None` check: nothing to record.)
pub type AdversarySwap<'a> = dyn Fn(
        &scene::Executed,
    ) -> Result<(Option<recon::SceneModel>, Option<crate::auto_replace::AdversaryCheck>), PipelineError>
    + 'a;

/// Everything `run` needs besides the request.
pub struct RunInputs<'a, B: Backend> {
    pub scene: &'a Scene,
    pub model: &'a recon::SceneModel,
    pub backend: &'a B,
    pub render: &'a RenderSettings,
    pub out: &'a Path,
}

/// Runs one case and writes its files under `inputs.out`, with the built-in physics.
pub fn run<B: Backend>(
    inputs: &RunInputs<B>,
    req: &CaseRequest,
    t0: &T0Choice,
    llm: Option<&mut dyn reason::backend::Backend>,
    progress: &ProgressBar,
) -> Result<RunSummary, PipelineError> {
    run_with(inputs, req, t0, llm, progress, Box::new(sim::simulate))
}

/// [`run`] with another physics backend (`sim::carla::simulate` with its options).
pub fn run_with<B: Backend>(
    inputs: &RunInputs<B>,
    req: &CaseRequest,
    t0: &T0Choice,
    llm: Option<&mut dyn reason::backend::Backend>,
    progress: &ProgressBar,
    simulate: Box<cases::runner::SimulateFn>,
) -> Result<RunSummary, PipelineError> {
    run_with_swap(inputs, req, t0, llm, progress, simulate, None)
}

/// [`run`] with the adversary's model decided by `swap` after the case is executed (the demo's
/// automatic replacement, `auto_replace`); the decision is recorded in `run.json`.
pub fn run_swapping<B: Backend>(
    inputs: &RunInputs<B>,
    req: &CaseRequest,
    t0: &T0Choice,
    progress: &ProgressBar,
    swap: &AdversarySwap,
) -> Result<RunSummary, PipelineError> {
    run_with_swap(inputs, req, t0, None, progress, Box::new(sim::simulate), Some(swap))
}

/// [`run_with`] and, where `swap` is given, [`run_swapping`]'s decision on the adversary's model.
pub fn run_with_swap<B: Backend>(
    inputs: &RunInputs<B>,
    req: &CaseRequest,
    t0: &T0Choice,
    llm: Option<&mut dyn reason::backend::Backend>,
    progress: &ProgressBar,
    simulate: Box<cases::runner::SimulateFn>,
    swap: Option<&AdversarySwap>,
) -> Result<RunSummary, PipelineError> {
    // Settings the scene or model cannot honour, and an --out that is not ours, are refused
    // before anything is planned or written.
    let layouts = check_before_work(inputs, req, t0)?;
    let staged = crate::run_out::StagedRun::new(inputs.out)?;
    let out = staged.path().to_path_buf();
    let out = out.as_path();
    let mut timings = Vec::new();
    let clock = Instant::now();
    let selection = select_case_with(inputs.scene, req, t0, llm, simulate);
    timings.push(Timing { stage: "reason + simulate + measure".into(), seconds: clock.elapsed().as_secs_f64() });
    let mut summary = RunSummary {
        format: RUN_FORMAT.into(),
        scene: inputs.scene.name.clone(),
        request: req.clone(),
        attempts: selection.attempts,
        result: None,
        metrics: None,
        window: None,
        no_case: None,
        placement: vec![],
        videos: vec![],
        files: vec![],
        timings,
        adversary: None,
    };
    let Some((result, executed, window)) = selection.chosen else {
        summary.no_case = Some(if summary.attempts.is_empty() {
            format!(
                "no t0 to try: the log is {:.2} s long and every t0 searched needs {} s of log after it",
                inputs.scene.duration_s(),
                cases::spec::MIN_HORIZON_S
            )
        } else {
            "no attempt produced a case: each attempt's status and detail say why".into()
        });
        write_json_pretty(&out.join("run.json"), &summary)?;
        staged.commit()?;
        return Ok(summary);
    };
    let best = result.best().expect("a chosen case has rounds").clone();
    let mut files = vec!["scenario.json".to_string(), "executed.json".into(), "metrics.json".into()];
    write_json_pretty(&out.join("scenario.json"), &best.plan)?;
    write_json_pretty(&out.join("executed.json"), &executed)?;

    let clock = Instant::now();
    let swapped = match swap {
        Some(swap) => {
            let (model, check) = swap(&executed)?;
            summary.adversary = check;
            model
        }
        None => None,
    };
    // An inserted adversary joins the scene as a track, and the model as an asset from the
    // library (the swap, where there is one) or the synthetic sedan.
    let scene_with = crate::inserted::scene_with(inputs.scene, &best.plan)?;
    let scene = &*scene_with;
    let inserted_model = match (&best.plan.inserted, &swapped) {
        (Some(ins), None) => Some(crate::inserted::with_sedan(inputs.model, &best.plan.adversary_track, ins)?),
        _ => None,
    };
    let model = swapped.as_ref().or(inserted_model.as_ref()).unwrap_or(inputs.model);
    let view = CaseView::new(inputs.backend, model, scene, &executed)?;
    let mut placement = Vec::new();
    for t in check_times(scene, &view.adversary, best.plan.start_time_s, inputs.render.placement_checks) {
        if let Some((p, picture)) =
            check_best_camera(inputs.backend, model, scene, &view.adversary, t, inputs.render.scale)?
        {
            let name = format!("placement/t{:.2}_{}.png", p.t, p.camera);
            std::fs::create_dir_all(out.join("placement")).map_err(PipelineError::io(out))?;
            picture.save_png(&out.join(&name))?;
            files.push(name);
            placement.push(p);
        }
    }
    let metrics_file =
        MetricsFile { metrics: best.metrics.clone(), placement: placement.clone(), attempts: summary.attempts.clone() };
    write_json_pretty(&out.join("metrics.json"), &metrics_file)?;
    crate::outputs::write_xosc(scene, &executed, out, inputs.render.xosc_version)?;
    files.extend(["scenario.xodr".into(), "scenario.xosc".into()]);
    files.extend(crate::outputs::plots(scene, &best.plan, &executed, &best.metrics, out));
    summary.timings.push(Timing { stage: "export + checks".into(), seconds: clock.elapsed().as_secs_f64() });

    let clock = Instant::now();
    let videos_dir = out.join("videos");
    std::fs::create_dir_all(&videos_dir).map_err(PipelineError::io(&videos_dir))?;
    let mut videos = Vec::new();
    for layout in layouts {
        let spec = inputs.render.spec(&layout);
        progress.set_message(format!("video {}", layout.slug()));
        let mut output = view.render_video(&spec, &videos_dir.join(format!("{}.mp4", layout.slug())), progress)?;
        output.path = staged.final_path(inputs.out, &output.path);
        let t_min = best.metrics.t_min_ttc_center_s;
        let climax = match t_min.is_finite() {
            true => {
                let (frame, t, still) = view.frame_near(&spec, t_min)?;
                let file = format!("videos/{}-minttc.png", layout.slug());
                still.save_png(&out.join(&file))?;
                files.push(file.clone());
                Some(Climax { file, frame, t, t_min_ttc: t_min })
            }
            false => None,
        };
        videos.push(Video { layout: layout.slug(), output, climax });
    }
    summary.timings.push(Timing { stage: "render videos".into(), seconds: clock.elapsed().as_secs_f64() });
    summary.result = Some(result);
    summary.metrics = Some(best.metrics);
    summary.window = Some(window);
    summary.placement = placement;
    summary.videos = videos;
    summary.files = files;
    write_json_pretty(&out.join("run.json"), &summary)?;
    staged.commit()?;
    Ok(summary)
}
