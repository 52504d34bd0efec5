//! `carla-gs asset harvest`: a library of real vehicles from a trained model of a log.
//!
//! For every vehicle actor of the model, the scene tells how well the log saw it, over the
//! images the model learned from (the training split: frames with `frame % held_out_every != 0`;
//! every frame without a split), each through `observe` at the camera's stored size, with the box
//! where training placed it (the track's pose at the frame's time):
//!
//! * closest approach: the least camera-to-box distance (nearest box point) over the images
//!   that have the box in view;
//! * the sides seen: the azimuth sectors (30 degrees) of the camera around the box, and the
//!   smallest arc holding every azimuth;
//! * pixels: the largest and the total projected hull area, and the number of views;
//! * colour: the median body colour of the opaque Gaussians (`library::body_colour`);
//! * size and class: the track's (median box size, `vehicle`).
//!
//! A vehicle is kept when it was seen close (`max_closest_m`), from enough sides
//! (`min_azimuth_bins`), large enough (`min_hull_px`) and has Gaussians enough to align
//! ([`MIN_ASSET_GAUSSIANS`]); every other vehicle is listed with each criterion it failed. Kept
//! vehicles are stored in the library (z up, box frame) as the union of their Gaussians and
//! their mirror images (`mirror`), unless model.json says training already mirrored the actor
//! (`"mirrored": true` in its actor entry; absent means false), named
//! `<scene name>-<short track id>`. A harvest replaces its own earlier entries (the same model's
//! harvested tracks) and refuses to overwrite any other asset of the same name unless forced.
//! See docs/render.md for the defaults and what they rest on.

pub use super::library::HarvestRecord;
use super::library::{without_transparent, AssetEntry, AssetSource, Library, NewAsset, UpAxis, MIN_GEOMETRY_OPACITY};
use super::mirror::with_mirror;
pub use super::observe::Observed;
use super::observe::{observe, AZIMUTH_BINS};
use crate::RenderError;
use recon::pose::box_pose_at;
use scene::{ObjectClass, Scene, Track};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// The model directory's record (`recon::model_io`), read here for the actors' `mirrored` flag.
pub const MODEL_JSON: &str = "model.json";
/// Fewer Gaussians that count for geometry than this: nothing to align (`replace`).
pub const MIN_ASSET_GAUSSIANS: usize = super::replace::MIN_ACTOR_POINTS;

/// What makes a vehicle well seen (defaults: docs/render.md).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Thresholds {
    /// The log's closest view of it at most this far (m).
    pub max_closest_m: f64,
    /// Seen from at least this many 30-degree azimuth sectors.
    pub min_azimuth_bins: usize,
    /// Its largest view at least this many pixels (at the camera's stored size).
    pub min_hull_px: f64,
}

impl Default for Thresholds {
    fn default() -> Self {
        Thresholds { max_closest_m: 15.0, min_azimuth_bins: 3, min_hull_px: 4000.0 }
    }
}

impl Thresholds {
    pub fn check(&self) -> Result<(), RenderError> {
        let bad = |what: &str, detail: String| Err(RenderError::Settings { what: what.into(), detail });
        if !(self.max_closest_m.is_finite() && self.max_closest_m >= 0.0) {
            return bad("--max-closest-m", format!("must be a finite distance >= 0 m, got {}", self.max_closest_m));
        }
        if self.min_azimuth_bins > AZIMUTH_BINS {
            return bad("--min-azimuth-bins", format!("must be 0 to {AZIMUTH_BINS}, got {}", self.min_azimuth_bins));
        }
        if !(self.min_hull_px.is_finite() && self.min_hull_px >= 0.0) {
            return bad("--min-hull-px", format!("must be a finite pixel count >= 0, got {}", self.min_hull_px));
        }
        Ok(())
    }
}

/// One vehicle actor's outcome.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VehicleOutcome {
    pub track_id: String,
    pub size_lwh: [f64; 3],
    pub observed: Observed,
    pub colour: Option<[f64; 3]>,
    /// Its Gaussians that count for geometry (opacity at least 0.1).
    pub geometry_gaussians: usize,
    pub kept: bool,
    /// Each criterion it failed (empty when kept).
    pub why_not: Vec<String>,
    /// The library asset it became.
    pub asset: Option<String>,
    pub mirrored_in_model: bool,
}

/// What a harvest did (`--json`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HarvestReport {
    pub scene: String,
    pub model_dir: PathBuf,
    pub library: PathBuf,
    pub thresholds: Thresholds,
    pub held_out_every: usize,
    /// Every vehicle actor of the model, kept or not.
    pub vehicles: Vec<VehicleOutcome>,
    /// Actors of other classes, not harvested.
    pub other_actors: usize,
    /// Assets of an earlier harvest of this model that this one no longer keeps (dropped).
    pub removed: Vec<String>,
}

impl HarvestReport {
    pub fn vehicle(&self, track_id: &str) -> Option<&VehicleOutcome> {
        self.vehicles.iter().find(|v| v.track_id == track_id)
    }
}

/// How the training images saw `track` (a box of `size_lwh`) in `scene` under the
/// every-`held_out_every`-th split.
pub fn observe_track(
    scene: &Scene,
    track: &Track,
    size_lwh: [f64; 3],
    held_out_every: usize,
) -> Result<Observed, RenderError> {
    let mut views = Vec::new();
    for f in scene.frames.iter().filter(|f| !recon::data::is_held_out(f.index, held_out_every)) {
        let Some(pose) = box_pose_at(scene, track, f.timestamp_s) else { continue };
        for im in &f.images {
            let Some(cam) = scene.camera(&im.camera) else { continue };
            let sc = recon::camera::splat_camera(cam, &scene.world_from_ego_of_image(f, im), 1.0)?;
            views.extend(observe(&sc, &pose, size_lwh));
        }
    }
    Ok(Observed::of(&views))
}

/// Each criterion of `t` that `o` (with `gaussians` geometry Gaussians) fails, in words.
pub fn why_not(o: &Observed, gaussians: usize, t: &Thresholds) -> Vec<String> {
    let mut why = Vec::new();
    match o.closest_m {
        None => why.push("never in view of a training image".to_string()),
        Some(d) if d > t.max_closest_m => why.push(format!("closest {d:.1} m > {:.1} m", t.max_closest_m)),
        Some(_) => {}
    }
    if o.closest_m.is_some() && o.azimuth_sectors.len() < t.min_azimuth_bins {
        why.push(format!("{} azimuth sector(s) < {}", o.azimuth_sectors.len(), t.min_azimuth_bins));
    }
    if o.closest_m.is_some() && o.max_hull_px < t.min_hull_px {
        why.push(format!("largest view {:.0} px < {:.0} px", o.max_hull_px, t.min_hull_px));
    }
    if gaussians < MIN_ASSET_GAUSSIANS {
        why.push(format!("{gaussians} Gaussian(s) to align < {MIN_ASSET_GAUSSIANS}"));
    }
    why
}

/// The `"mirrored"` flag of each actor entry of `<model_dir>/model.json` (absent: false).
pub fn mirrored_actors(model_dir: &Path) -> Result<HashMap<String, bool>, RenderError> {
    let file = model_dir.join(MODEL_JSON);
    let v: serde_json::Value = scene::format::read_json(&file)?;
    let mut out = HashMap::new();
    for (i, a) in v["actors"].as_array().map(Vec::as_slice).unwrap_or_default().iter().enumerate() {
        let Some(id) = a["track_id"].as_str() else { continue };
        let mirrored = match &a["mirrored"] {
            serde_json::Value::Null => false,
            serde_json::Value::Bool(b) => *b,
            other => {
                return Err(RenderError::io(
                    &file,
                    format!("actors[{i}].mirrored: expected true or false, got {other}"),
                ))
            }
        };
        out.insert(id.to_string(), mirrored);
    }
    Ok(out)
}

/// How many of `g` count for geometry (opacity at least `library::MIN_GEOMETRY_OPACITY`).
pub fn geometry_count(g: &splat::Gaussians) -> usize {
    g.opacity_logits.iter().filter(|&&o| splat::gaussians::sigmoid(o) >= MIN_GEOMETRY_OPACITY).count()
}

/// `s` with every character but letters, digits, `-` and `_` made `_`.
fn clean(s: &str) -> String {
    s.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect()
}

/// Asset names `<scene>-<short id>` for `ids`: the first 8 characters of each id, the whole id
/// where two would share them.
pub fn asset_names(scene: &str, ids: &[&str]) -> Vec<String> {
    let short = |id: &str| clean(id).chars().take(8).collect::<String>();
    let scene = clean(scene).trim_start_matches(['-', '_']).to_string();
    let scene = if scene.is_empty() { "scene".to_string() } else { scene };
    ids.iter()
        .map(|id| {
            let s = short(id);
            let shared = ids.iter().filter(|o| short(o) == s).count() > 1;
            format!("{scene}-{}", if shared { clean(id) } else { s })
        })
        .collect()
}

/// Whether `e` was harvested from the model in `model_dir`.
fn harvested_from(e: &AssetEntry, model_dir: &Path) -> bool {
    let AssetSource::Model { model_dir: m, .. } = &e.source else { return false };
    let same = match (m.canonicalize(), model_dir.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => m == model_dir,
    };
    same && e.harvest.is_some()
}

/// Harvests the vehicles of the model in `model_dir` (trained on the scene in `scene_dir`) into
/// the library at `library` (see the module notes). `force` lets it overwrite assets of the same
/// name that are not its own.
pub fn harvest(
    scene_dir: &Path,
    model_dir: &Path,
    library: &Path,
    thresholds: &Thresholds,
    force: bool,
) -> Result<HarvestReport, RenderError> {
    thresholds.check()?;
    let scene = scene::load_scene(scene_dir)?;
    let (model, record) = recon::model_io::load_model_for_scene(model_dir, scene_dir, &scene)?;
    let mirrored = mirrored_actors(model_dir)?;
    let vehicles: Vec<(&recon::model::Actor, &Track)> = model
        .actors
        .iter()
        .filter_map(|a| scene.track(&a.track_id).filter(|t| t.class == ObjectClass::Vehicle).map(|t| (a, t)))
        .collect();
    let ids: Vec<&str> = vehicles.iter().map(|(a, _)| a.track_id.as_str()).collect();
    let names = asset_names(&scene.name, &ids);
    let mut outcomes = Vec::with_capacity(vehicles.len());
    let mut new = Vec::new();
    for ((actor, track), name) in vehicles.iter().zip(names) {
        let size = track.median_size_lwh();
        let observed = observe_track(&scene, track, size, record.held_out_every)?;
        let gaussians = geometry_count(&actor.gaussians);
        let why = why_not(&observed, gaussians, thresholds);
        let in_model = mirrored.get(&actor.track_id).copied().unwrap_or(false);
        let kept = why.is_empty();
        if kept {
            let g = without_transparent(&actor.gaussians);
            new.push(NewAsset {
                name: name.clone(),
                class: ObjectClass::Vehicle,
                source: AssetSource::Model { model_dir: model_dir.to_path_buf(), track_id: actor.track_id.clone() },
                up: UpAxis::Z,
                gaussians: if in_model { g } else { with_mirror(&g) },
                harvest: Some(HarvestRecord {
                    scene: scene.name.clone(),
                    track_size_lwh: size,
                    observed: observed.clone(),
                    mirrored_in_model: in_model,
                }),
            });
        }
        outcomes.push(VehicleOutcome {
            track_id: actor.track_id.clone(),
            size_lwh: size,
            observed,
            colour: super::library::body_colour(&actor.gaussians),
            geometry_gaussians: gaussians,
            kept,
            why_not: why,
            asset: kept.then_some(name),
            mirrored_in_model: in_model,
        });
    }
    let before: Vec<String> = Library::load(library)?
        .assets
        .iter()
        .filter(|e| harvested_from(e, model_dir) && new.iter().all(|n| n.name != e.name))
        .map(|e| e.name.clone())
        .collect();
    let own = |e: &AssetEntry| force || harvested_from(e, model_dir);
    Library::store(library, new, &own, &|e| harvested_from(e, model_dir))?;
    Ok(HarvestReport {
        scene: scene.name.clone(),
        model_dir: model_dir.to_path_buf(),
        library: library.to_path_buf(),
        thresholds: *thresholds,
        held_out_every: record.held_out_every,
        other_actors: model.actors.len() - vehicles.len(),
        vehicles: outcomes,
        removed: before,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_short_unless_two_would_share_one() {
        let n = asset_names("pandaset-002", &["5efc9139-933d-4339", "0d238564-0ebe", "0d238564-ffff", "lead 1"]);
        assert_eq!(
            n,
            [
                "pandaset-002-5efc9139",
                "pandaset-002-0d238564-0ebe",
                "pandaset-002-0d238564-ffff",
                "pandaset-002-lead_1"
            ]
        );
        assert_eq!(asset_names(".", &["a"]), ["scene-a"]);
    }

    #[test]
    fn every_failed_criterion_is_named() {
        let t = Thresholds::default();
        let o = Observed {
            views: 4,
            closest_m: Some(18.0),
            azimuth_sectors: vec![5, 6],
            azimuth_span_deg: 20.0,
            max_hull_px: 3000.0,
            total_hull_px: 9000.0,
        };
        let why = why_not(&o, 10, &t);
        assert_eq!(why.len(), 4, "{why:?}");
        assert!(why[0].contains("closest 18.0 m > 15.0 m") && why[1].contains("2 azimuth sector(s) < 3"), "{why:?}");
        assert!(why[2].contains("3000 px < 4000 px") && why[3].contains("10 Gaussian(s)"), "{why:?}");
        let good = Observed { closest_m: Some(5.0), azimuth_sectors: vec![1, 2, 3], max_hull_px: 5000.0, ..o };
        assert!(why_not(&good, 500, &t).is_empty());
        assert_eq!(why_not(&Observed::default(), 500, &t), ["never in view of a training image"]);
        assert!(Thresholds { min_azimuth_bins: 13, ..t }.check().is_err());
        assert!(Thresholds { max_closest_m: f64::NAN, ..t }.check().is_err());
    }

    #[test]
    fn the_mirrored_flag_is_read_leniently_and_checked() {
        let d = tempfile::tempdir().unwrap();
        let write = |text: &str| std::fs::write(d.path().join(MODEL_JSON), text).unwrap();
        write(
            r#"{"actors": [{"track_id": "a"}, {"track_id": "b", "mirrored": true}, {"track_id": "c", "mirrored": false}]}"#,
        );
        let m = mirrored_actors(d.path()).unwrap();
        assert_eq!((m["a"], m["b"], m["c"]), (false, true, false));
        write(r#"{"actors": [{"track_id": "a", "mirrored": "yes"}]}"#);
        let e = mirrored_actors(d.path()).unwrap_err().to_string();
        assert!(e.contains("actors[0].mirrored") && e.contains("expected true or false"), "{e}");
    }
}
