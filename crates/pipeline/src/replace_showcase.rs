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

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Showcase {
    pub track_id: String,
    pub asset: String,
    pub frame: usize,
    pub chosen: render::asset::align::Candidate,
    pub candidates: Vec<render::asset::align::Candidate>,
    pub before: ViewScore,
    pub after: ViewScore,
}

/// Makes the showcase of `track` into `dir` (pictures and `replacement.json`).
pub fn showcase<B: Backend>(
    backend: &B,
    model: &SceneModel,
    scene: &Scene,
    synth_cfg: &synth::SynthConfig,
    track: &str,
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
    let s = Showcase {
        track_id: track.to_string(),
        asset: name,
        frame,
        chosen: rep.alignment.chosen().clone(),
        candidates: rep.alignment.candidates.clone(),
        before,
        after,
    };
    scene::format::write_json_pretty(&dir.join(SHOWCASE_FILE), &s)?;
    Ok(s)
}
