//! `carla-gs run`: one corner case end to end, from a scene directory and a trained model to the
//! files a person opens: `scenario.json` (the plan), `executed.json`, `metrics.json` (Table I/II
//! metrics, the t0 attempts, the placement checks of the video), `scenario.xosc` (OpenSCENARIO
//! 1.2), `bev.png` and `tracking.png`, and one video per layout under `videos/`. `run.json`
//! summarises all of it (written last). When no attempt produced a case, `run.json` says why for
//! each t0 and nothing else is written.

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

pub const RUN_FORMAT: &str = "carla-gs-run/1";

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
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Video {
    pub layout: String,
    #[serde(flatten)]
    pub output: VideoOutput,
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
    pub placement: Vec<Placement>,
    pub videos: Vec<Video>,
    /// File names under the run directory.
    pub files: Vec<String>,
    pub timings: Vec<Timing>,
}

/// Everything `run` needs besides the request.
pub struct RunInputs<'a, B: Backend> {
    pub scene: &'a Scene,
    pub model: &'a recon::SceneModel,
    pub backend: &'a B,
    pub render: &'a RenderSettings,
    pub out: &'a Path,
}

/// Every file and directory a run writes, removed before a new run so a directory never mixes two.
const OUTPUTS: [&str; 10] = [
    "run.json",
    "scenario.json",
    "executed.json",
    "metrics.json",
    "scenario.xosc",
    "scenario.xodr",
    "bev.png",
    "tracking.png",
    "placement",
    "videos",
];

fn clear_outputs(out: &Path) -> Result<(), PipelineError> {
    for name in OUTPUTS {
        let p = out.join(name);
        let r = if p.is_dir() { std::fs::remove_dir_all(&p) } else { std::fs::remove_file(&p) };
        match r {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(PipelineError::Scene(scene::SceneError::io(&p, e)))
            }
            _ => {}
        }
    }
    Ok(())
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
    let out = inputs.out;
    // A layout the scene cannot show is refused before anything is planned or removed.
    let layouts = inputs.render.resolved_layouts(inputs.scene)?;
    std::fs::create_dir_all(out).map_err(PipelineError::io(out))?;
    clear_outputs(out)?;
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
        placement: vec![],
        videos: vec![],
        files: vec![],
        timings,
    };
    let Some((result, executed)) = selection.chosen else {
        write_json_pretty(&out.join("run.json"), &summary)?;
        return Ok(summary);
    };
    let best = result.best().expect("a chosen case has rounds").clone();
    let mut files = vec!["scenario.json".to_string(), "executed.json".into(), "metrics.json".into()];
    write_json_pretty(&out.join("scenario.json"), &best.plan)?;
    write_json_pretty(&out.join("executed.json"), &executed)?;

    let clock = Instant::now();
    let view = CaseView::new(inputs.backend, inputs.model, inputs.scene, &executed)?;
    let mut placement = Vec::new();
    for t in check_times(inputs.scene, &view.adversary, best.plan.start_time_s, inputs.render.placement_checks) {
        if let Some((p, picture)) =
            check_best_camera(inputs.backend, inputs.model, inputs.scene, &view.adversary, t, inputs.render.scale)?
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
    crate::outputs::write_xosc(inputs.scene, &executed, out, inputs.render.xosc_version)?;
    files.extend(["scenario.xodr".into(), "scenario.xosc".into()]);
    files.extend(crate::outputs::plots(inputs.scene, &best.plan, &executed, &best.metrics, out));
    summary.timings.push(Timing { stage: "export + checks".into(), seconds: clock.elapsed().as_secs_f64() });

    let clock = Instant::now();
    let videos_dir = out.join("videos");
    std::fs::create_dir_all(&videos_dir).map_err(PipelineError::io(&videos_dir))?;
    let mut videos = Vec::new();
    for layout in layouts {
        let spec = VideoSpec {
            layout: layout.clone(),
            fps: inputs.render.fps,
            lead_in_s: inputs.render.lead_in_s,
            scale: inputs.render.scale,
            png_only: inputs.render.png_only,
            ..VideoSpec::default()
        };
        progress.set_message(format!("video {}", layout.slug()));
        let output = view.render_video(&spec, &videos_dir.join(format!("{}.mp4", layout.slug())), progress)?;
        videos.push(Video { layout: layout.slug(), output });
    }
    summary.timings.push(Timing { stage: "render videos".into(), seconds: clock.elapsed().as_secs_f64() });
    summary.result = Some(result);
    summary.metrics = Some(best.metrics);
    summary.placement = placement;
    summary.videos = videos;
    summary.files = files;
    write_json_pretty(&out.join("run.json"), &summary)?;
    Ok(summary)
}
