//! Replacing an actor of a trained model with an aligned asset, in memory and as a new model
//! directory (`carla-gs replace`, `--replace` of `run` and `demo`).
//!
//! The actor's frame is its tracked box (centre at the origin, yaw 0, extents = the box size);
//! its points are the means of its Gaussians that are not nearly transparent, or, for an actor
//! with almost none (never well seen), points on its box's faces, where the Chamfer term cannot
//! tell front from back and the tie goes to `d`. The asset is moved by the chosen alignment
//! (`covariance::transform`), its SH degree made the model's, and it takes the actor's place;
//! the box size, track and everything else stay. The output directory gets every model file
//! (no `checkpoint.bin`: the training state no longer matches) and `replacements.json`, the
//! alignment report of each replacement (all four candidates with both terms).

use super::align::{align, AlignOptions, Alignment, Frame};
use super::auto::{resolve, AutoChoice, AutoQuery};
use super::covariance::{transform, with_sh_degree};
use super::library::{body_colour, geometry_points, UpAxis};
use crate::RenderError;
use recon::SceneModel;
use scene::ObjectClass;
use serde::{Deserialize, Serialize};
use splat::Gaussians;
use std::path::Path;

pub const REPLACEMENTS_FILE: &str = "replacements.json";
/// Fewer geometry points than this: the box's faces stand in for the actor.
pub const MIN_ACTOR_POINTS: usize = 20;

/// What one replacement did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Replacement {
    pub track_id: String,
    /// The asset's name or file.
    pub asset: String,
    pub gaussians_before: usize,
    pub gaussians_after: usize,
    /// Whether the actor's own Gaussians were too few and the box's faces were used.
    pub box_points: bool,
    pub alignment: Alignment,
    /// Why `auto` chose the asset (`None` for an asset named by the user).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub auto: Option<AutoChoice>,
}

/// Points on the faces of a box of `size` centred at the origin, about 0.1 m apart.
fn box_points(size: [f64; 3]) -> Vec<[f64; 3]> {
    let n: [usize; 3] = std::array::from_fn(|k| (size[k] / 0.1).ceil().clamp(1.0, 200.0) as usize);
    let at = |k: usize, i: usize| size[k] * (i as f64 / n[k] as f64 - 0.5);
    let mut out = Vec::new();
    for ax in 0..3 {
        let (u, v) = ((ax + 1) % 3, (ax + 2) % 3);
        for side in [-0.5, 0.5] {
            for i in 0..=n[u] {
                for j in 0..=n[v] {
                    let mut p = [0.0; 3];
                    p[ax] = side * size[ax];
                    p[u] = at(u, i);
                    p[v] = at(v, j);
                    out.push(p);
                }
            }
        }
    }
    out
}

/// Replaces actor `track` of `model` with `asset` (z up, any frame), aligned to it.
pub fn replace_actor(
    model: &mut SceneModel,
    track: &str,
    asset_name: &str,
    asset: &Gaussians,
    opts: &AlignOptions,
) -> Result<Replacement, RenderError> {
    let degree = model.background.sh_degree;
    let Some(idx) = model.actors.iter().position(|a| a.track_id == track) else {
        return Err(RenderError::no_actor(model, track));
    };
    let actor = &model.actors[idx];
    let size = actor.size_lwh;
    if size.iter().any(|v| !(*v > 0.0 && v.is_finite())) {
        return Err(RenderError::Settings {
            what: format!("actor `{track}`"),
            detail: format!("box size {size:?} is not positive: nothing to align to"),
        });
    }
    let mut points = geometry_points(&actor.gaussians);
    let use_box = points.len() < MIN_ACTOR_POINTS;
    if use_box {
        points = box_points(size);
    }
    let frame = Frame { centre: [0.0; 3], yaw: 0.0, extents: size };
    let a = align(&geometry_points(asset), &points, Some(frame), opts).map_err(|e| RenderError::Settings {
        what: format!("aligning asset `{asset_name}` to actor `{track}`"),
        detail: e.to_string(),
    })?;
    let moved = transform(asset, &a.linear, a.translation, &a.rotation);
    let moved = with_sh_degree(&moved, degree);
    let before = model.actors[idx].gaussians.len();
    model.actors[idx].gaussians = moved;
    Ok(Replacement {
        track_id: track.to_string(),
        asset: asset_name.to_string(),
        gaussians_before: before,
        gaussians_after: asset.len(),
        box_points: use_box,
        alignment: a,
        auto: None,
    })
}

/// Parses `--replace <track>=<spec>` (spec: `auto`, a PLY file or a library name).
pub fn parse_replace_arg(arg: &str) -> Result<(String, String), RenderError> {
    match arg.split_once('=') {
        Some((t, s)) if !t.is_empty() && !s.is_empty() => Ok((t.to_string(), s.to_string())),
        _ => Err(RenderError::Settings {
            what: format!("--replace `{arg}`"),
            detail: "expected <track>=<ply file|asset name|auto>".into(),
        }),
    }
}

/// Replaces each `(track, asset spec)` of `model` in memory (`auto::resolve`). For `auto`, the
/// track's class comes from the scene in `scene_dir`, its colour from its actor, and the track's
/// own asset from this scene or from `model_dir` (the model's directory, where it has one) is
/// never chosen.
pub fn replace_specs(
    model: &mut SceneModel,
    scene_dir: &Path,
    model_dir: Option<&Path>,
    replacements: &[(String, String)],
    library_dir: &Path,
    up: UpAxis,
    opts: &AlignOptions,
) -> Result<Vec<Replacement>, RenderError> {
    let mut done = Vec::with_capacity(replacements.len());
    let mut scene: Option<scene::Scene> = None;
    for (track, spec) in replacements {
        if spec == super::auto::AUTO && scene.is_none() {
            scene = Some(scene::load_scene(scene_dir)?);
        }
        let class = scene.as_ref().and_then(|s| s.track(track)).map_or(ObjectClass::Vehicle, |t| t.class);
        let actor = model.actors.iter().find(|a| &a.track_id == track);
        let q = AutoQuery {
            track_id: track,
            class,
            size_lwh: actor.map_or([0.0; 3], |a| a.size_lwh),
            colour: actor.and_then(|a| body_colour(&a.gaussians)),
            scene: scene.as_ref().map(|s| s.name.as_str()),
            model_dir,
        };
        let r = resolve(spec, library_dir, up, &q)?;
        let mut rep = replace_actor(model, track, &r.name, &r.gaussians, opts)?;
        rep.auto = r.auto;
        done.push(rep);
    }
    Ok(done)
}

/// Loads the model in `model_dir`, replaces each `(track, asset spec)` (`auto::resolve`:
/// `auto`, a PLY file or a library name) and writes the result to `out_dir` (not `model_dir`).
/// The track's class (for `auto`) comes from the scene the model was trained on.
pub fn replace_in_dir(
    model_dir: &Path,
    out_dir: &Path,
    replacements: &[(String, String)],
    library_dir: &Path,
    up: UpAxis,
    opts: &AlignOptions,
) -> Result<Vec<Replacement>, RenderError> {
    let same = match (model_dir.canonicalize(), out_dir.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if same {
        return Err(RenderError::Settings {
            what: format!("--out {}", out_dir.display()),
            detail: "is the input model directory; write the replaced model elsewhere".into(),
        });
    }
    let (mut model, mut record) = recon::model_io::load_model(model_dir)?;
    let cfg = recon::model_io::load_config(model_dir)?;
    let scene_dir = record.scene_dir.clone();
    let done = replace_specs(&mut model, &scene_dir, Some(model_dir), replacements, library_dir, up, opts)?;
    recon::model_io::write_model(out_dir, &model, &mut record, &cfg, None)?;
    scene::format::write_json_pretty(&out_dir.join(REPLACEMENTS_FILE), &done)?;
    Ok(done)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn replace_arguments_parse_or_name_the_fault() {
        assert_eq!(parse_replace_arg("lead-1=auto").unwrap(), ("lead-1".into(), "auto".into()));
        assert_eq!(parse_replace_arg("a=b=c.ply").unwrap(), ("a".into(), "b=c.ply".into()));
        for bad in ["lead-1", "=auto", "lead-1="] {
            assert!(parse_replace_arg(bad).unwrap_err().to_string().contains(bad), "{bad}");
        }
    }

    #[test]
    fn box_points_span_the_box() {
        let p = box_points([4.0, 2.0, 1.5]);
        let f = super::super::align::frame_of(&p).unwrap();
        for (a, b) in f.extents.iter().zip([4.0, 2.0, 1.5]) {
            assert!((a - b).abs() < 1e-9);
        }
        assert!(f.centre.iter().all(|c| c.abs() < 1e-9));
    }
}
