//! Drawing an inserted adversary ([`scene::inserted`]): the trained model has no Gaussians for a
//! road user the log never saw, so one is added to the model as an actor in its box frame, from
//! the asset library where the run has one (the demo's `auto` choice: the nearest real asset
//! harvested from logs, else a synthetic one; [`crate::auto_replace::Swapper::swap`]), else the
//! synthetic sedan ([`with_sedan`]), aligned to the inserted box like any replacement.
//! `run` draws it from `--asset-library` where that holds a library ([`from_library`]).

use crate::synth_asset::{vehicle_asset, vehicle_of_kind, DEFAULT_VOXEL_M};
use crate::PipelineError;
use recon::model::Actor;
use recon::SceneModel;
use render::asset::align::AlignOptions;
use render::asset::auto::{AutoChoice, AUTO};
use render::asset::library::UpAxis;
use render::asset::replace::{replace_actor, replace_specs};
use scene::inserted::Inserted;
use std::path::Path;

/// Body colour of the fallback sedan (linear RGB): a mid grey, the commonest car colour.
const SEDAN_GREY: [f32; 3] = [0.35, 0.36, 0.38];

/// `model` with an empty actor `track` of the inserted box's size (for a replacement to fill).
pub fn with_empty_actor(model: &SceneModel, track: &str, ins: &Inserted) -> SceneModel {
    let mut m = model.clone();
    m.actors.retain(|a| a.track_id != track);
    let gaussians = splat::Gaussians::empty(m.background.sh_degree);
    m.actors.push(Actor { track_id: track.into(), size_lwh: ins.size_lwh, gaussians });
    m
}

/// `model` with the inserted adversary `track` drawn as the synthetic sedan fitted to its box.
pub fn with_sedan(model: &SceneModel, track: &str, ins: &Inserted) -> Result<SceneModel, PipelineError> {
    let mut m = with_empty_actor(model, track, ins);
    let asset = vehicle_asset(&vehicle_of_kind("sedan", SEDAN_GREY)?, DEFAULT_VOXEL_M)?;
    replace_actor(&mut m, track, "synth-sedan", &asset, &AlignOptions::default())?;
    Ok(m)
}

/// `model` with the inserted adversary `track` drawn from the asset `library` (its `auto`
/// choice for the inserted box: the nearest real asset of the class, else a synthetic one),
/// aligned to the box; the choice. `scene_dir` and `model_dir` are the run's.
pub fn from_library(
    model: &SceneModel,
    track: &str,
    ins: &Inserted,
    dirs: (&Path, &Path),
    library: &Path,
) -> Result<(SceneModel, Option<AutoChoice>), PipelineError> {
    let mut m = with_empty_actor(model, track, ins);
    let pairs = [(track.to_string(), AUTO.to_string())];
    let (scene_dir, model_dir) = dirs;
    let done = replace_specs(&mut m, scene_dir, Some(model_dir), &pairs, library, UpAxis::Z, &AlignOptions::default())?;
    Ok((m, done.into_iter().next().and_then(|r| r.auto)))
}
