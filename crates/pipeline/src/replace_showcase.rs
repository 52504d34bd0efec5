//! The demo's vehicle-replacement case: one actor of the trained model (the first case's
//! adversary) is replaced by an asset of its synthetic vehicle (`synth_asset`), aligned to it,
//! and both models are drawn from a novel view beside it next to the ground truth
//! (`replace_check`): pictures before / after / truth and their mask IoU and PSNR, for the
//! report.

use crate::replace_check::{beside, score_actor, ViewScore};
use crate::PipelineError;
use recon::backend::Backend;
use recon::SceneModel;
use render::asset::align::AlignOptions;
use scene::Scene;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Distance of the novel view from the actor's side (m).
pub const BESIDE_M: f64 = 7.0;
pub const SHOWCASE_FILE: &str = "replacement.json";
/// The pictures, in `showcase`'s directory.
pub const PICTURES: [&str; 3] = ["before.png", "after.png", "truth.png"];
/// The corner case's last executed instant, drawn with the model as trained and replaced.
pub const CASE_PICTURES: [&str; 2] = ["case-before.png", "case-after.png"];

/// Where the case stills were taken.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CaseStill {
    pub case_dir: String,
    pub t: f64,
    pub camera: String,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Showcase {
    pub track_id: String,
    pub asset: String,
    pub frame: usize,
    pub chosen: render::asset::align::Candidate,
    pub candidates: Vec<render::asset::align::Candidate>,
    pub before: ViewScore,
    pub after: ViewScore,
    #[serde(default)]
    pub case: Option<CaseStill>,
}

/// Draws the executed case in `case_dir` (whose adversary is the replaced track) at its last
/// executed instant, from the camera that sees most of the adversary's box, with both models.
fn case_stills<B: Backend>(
    backend: &B,
    models: [&SceneModel; 2],
    scene: &Scene,
    case_dir: &Path,
    dir: &Path,
) -> Result<Option<CaseStill>, PipelineError> {
    let executed = scene::executed::load_executed(&case_dir.join("executed.json"))?;
    let adversary = render::backproject::Backprojection::new(scene, &executed)?;
    let t = adversary.executed_span().1;
    let Some(pose) = adversary.pose_at(scene, t) else { return Ok(None) };
    let actor = render::video::actor_index(models[0], &adversary.track_id)?;
    let size = models[0].actors[actor].size_lwh;
    let mut best: Option<(usize, String)> = None;
    for c in &scene.cameras {
        let cam = render::video::camera_at(scene, &c.name, t, 1.0)?;
        let n = render::placement::box_mask(&cam, &pose, size).map_or(0, |m| m.iter().filter(|&&b| b).count());
        if n > 0 && best.as_ref().is_none_or(|(m, _)| n > *m) {
            best = Some((n, c.name.clone()));
        }
    }
    let Some((_, camera)) = best else { return Ok(None) };
    let cam = render::video::camera_at(scene, &camera, t, 1.0)?;
    let poses = |i: usize| if i == actor { Some(Some(pose)) } else { None };
    for (m, file) in models.iter().zip(CASE_PICTURES) {
        let d = recon::view::draw(backend, m, scene, &cam, t, recon::compose::Layers::All, &poses);
        recon::view::save_png(&dir.join(file), d.width, d.height, &d.rgb)?;
    }
    Ok(Some(CaseStill { case_dir: case_dir.display().to_string(), t, camera }))
}

/// Makes the showcase of `track` into `dir` (pictures and `replacement.json`); with `case_dir`
/// (an executed case whose adversary is `track`) also stills of that case before and after.
pub fn showcase<B: Backend>(
    backend: &B,
    model: &SceneModel,
    scene: &Scene,
    synth_cfg: &synth::SynthConfig,
    track: &str,
    case_dir: Option<&Path>,
    dir: &Path,
) -> Result<Showcase, PipelineError> {
    let seq = synth::Sequence::new(synth_cfg)?;
    let k =
        seq.vehicles.iter().position(|v| v.track_id == track).ok_or_else(|| {
            PipelineError::stage("replacement", format!("track `{track}` is not a synthetic vehicle"))
        })?;
    let asset = crate::synth_asset::vehicle_asset(&seq.vehicles[k], crate::synth_asset::DEFAULT_VOXEL_M)?;
    let mut replaced = model.clone();
    let name = format!("synth-{}", crate::synth_asset::kind_of(seq.vehicles[k].style));
    let rep = render::asset::replace::replace_actor(&mut replaced, track, &name, &asset, &AlignOptions::default())?;
    let frame = synth_cfg.frames / 2;
    let view = beside(&seq, k, frame, BESIDE_M, synth_cfg.width, synth_cfg.height);
    let (before, img_before) = score_actor(backend, model, scene, &seq, track, &view)?;
    let (after, img_after) = score_actor(backend, &replaced, scene, &seq, track, &view)?;
    std::fs::create_dir_all(dir).map_err(PipelineError::io(dir))?;
    let (w, h) = (img_after.width, img_after.height);
    for (file, rgb) in PICTURES.iter().zip([&img_before.drawn, &img_after.drawn, &img_after.truth]) {
        recon::view::save_png(&dir.join(file), w, h, rgb)?;
    }
    let case = match case_dir {
        Some(c) => case_stills(backend, [model, &replaced], scene, c, dir)?,
        None => None,
    };
    let s = Showcase {
        track_id: track.to_string(),
        asset: name,
        frame,
        chosen: rep.alignment.chosen().clone(),
        candidates: rep.alignment.candidates.clone(),
        before,
        after,
        case,
    };
    scene::format::write_json_pretty(&dir.join(SHOWCASE_FILE), &s)?;
    Ok(s)
}
