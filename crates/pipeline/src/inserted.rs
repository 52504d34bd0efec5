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
use scene::{Plan, Scene};
use std::borrow::Cow;
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

/// The scene `plan` was made for (with its inserted road user as a track, if any); a plan that
/// does not fit the scene is an error naming `scenario.json`'s field.
pub fn scene_with<'a>(scene: &'a Scene, plan: &Plan) -> Result<Cow<'a, Scene>, PipelineError> {
    scene::plan::with_inserted(scene, plan)
        .map_err(|(field, message)| PipelineError::stage("scenario.json", format!("`{field}`: {message}")))
}

/// Replaces actor `track` of `model` by the asset `library`'s `auto` choice for it (the nearest
/// real asset of its class and size, else a synthetic one), aligned to its box; that choice.
/// `dirs` are the run's scene and model directories.
pub fn fill_auto(
    model: &mut SceneModel,
    track: &str,
    dirs: (&Path, &Path),
    library: &Path,
) -> Result<Option<AutoChoice>, PipelineError> {
    let pairs = [(track.to_string(), AUTO.to_string())];
    let (scene_dir, model_dir) = dirs;
    let done = replace_specs(model, scene_dir, Some(model_dir), &pairs, library, UpAxis::Z, &AlignOptions::default())?;
    Ok(done.into_iter().next().and_then(|r| r.auto))
}

/// `model` with the inserted adversary `track` drawn from the asset `library` ([`fill_auto`]
/// on an empty actor of the inserted box); the choice.
pub fn from_library(
    model: &SceneModel,
    track: &str,
    ins: &Inserted,
    dirs: (&Path, &Path),
    library: &Path,
) -> Result<(SceneModel, Option<AutoChoice>), PipelineError> {
    let mut m = with_empty_actor(model, track, ins);
    let auto = fill_auto(&mut m, track, dirs, library)?;
    Ok((m, auto))
}
