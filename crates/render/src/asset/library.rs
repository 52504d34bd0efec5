//! The asset library: a directory of standard 3DGS PLY files and `index.json` naming each one's
//! class, nominal size and source.
//!
//! ```text
//! <lib>/index.json     {"format": "carla-gs-assets/1", "assets": [{name, class, size_lwh, source,
//!                       file, up, gaussians, sh_degree, colour?, harvest?}, ...]}
//! <lib>/<name>.ply     the asset, z up (converted from its declared up axis when added)
//! ```
//!
//! Sources: a user's PLY (from SAM-3D or any other tool; any SH degree; its up axis declared,
//! `z` by default: a `y`-up export is turned so +y becomes +z), an actor extracted from a trained
//! model (already in its box frame: x forward, z up), or a synthetic vehicle (`pipeline`). The
//! nominal size is the canonical frame's extents (`align::frame_of`) of the Gaussians that are
//! not nearly transparent, and the colour the median body colour of the opaque ones, so `auto`
//! (`auto`) can pick the nearest asset of a class. Assets harvested from a log (`harvest`) also
//! carry how well the log saw the vehicle. Both fields are optional, so indices written before
//! them still load. Every change is staged: the PLY files are written beside their destination
//! and renamed into place, then the index is replaced whole.

use super::align::frame_of;
use super::covariance::{transform, Mat3};
use super::observe::Observed;
use crate::RenderError;
use scene::ObjectClass;
use serde::{Deserialize, Serialize};
use splat::Gaussians;
use std::path::{Path, PathBuf};

pub const LIBRARY_FORMAT: &str = "carla-gs-assets/1";
pub const INDEX_FILE: &str = "index.json";
/// Gaussians below this opacity do not count for an asset's geometry (size, alignment).
pub const MIN_GEOMETRY_OPACITY: f64 = 0.1;
/// Gaussians at least this opaque make an asset's body colour ([`body_colour`]).
pub const MIN_COLOUR_OPACITY: f64 = 0.5;

/// The axis of a PLY that points up.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
pub enum UpAxis {
    #[default]
    #[serde(rename = "z")]
    Z,
    #[serde(rename = "-z")]
    NegZ,
    #[serde(rename = "y")]
    Y,
    #[serde(rename = "-y")]
    NegY,
    #[serde(rename = "x")]
    X,
    #[serde(rename = "-x")]
    NegX,
}

impl UpAxis {
    pub fn parse(s: &str) -> Result<UpAxis, RenderError> {
        serde_json::from_value(serde_json::Value::String(s.to_string())).map_err(|_| RenderError::Settings {
            what: format!("up axis `{s}`"),
            detail: "expected one of z, -z, y, -y, x, -x".into(),
        })
    }

    /// The rotation taking this axis to +z (`z_up_from_asset`).
    pub fn z_up_from_asset(self) -> Mat3 {
        match self {
            UpAxis::Z => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            UpAxis::NegZ => [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]],
            UpAxis::Y => [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
            UpAxis::NegY => [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]],
            UpAxis::X => [[0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]],
            UpAxis::NegX => [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]],
        }
    }
}

/// Where an asset came from.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum AssetSource {
    /// A PLY from elsewhere (SAM-3D or any 3DGS tool), as given.
    User { path: PathBuf },
    /// An actor of a trained model.
    Model { model_dir: PathBuf, track_id: String },
    /// A synthetic vehicle of `synth`, made by `pipeline::synth_asset` (how: `method`).
    Synth { vehicle: String, method: String },
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AssetEntry {
    pub name: String,
    pub class: ObjectClass,
    pub size_lwh: [f64; 3],
    pub source: AssetSource,
    /// The PLY, relative to the library directory (stored z up).
    pub file: String,
    /// The up axis the source declared (the stored file is already turned to z up).
    pub up: UpAxis,
    pub gaussians: usize,
    pub sh_degree: usize,
    /// The median body colour (r, g, b in [0, 1], [`body_colour`]); absent in indices written
    /// before it was recorded (`auto` then reads it from the PLY).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub colour: Option<[f64; 3]>,
    /// How well the log saw the vehicle, for an asset harvested from a log (`harvest`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub harvest: Option<HarvestRecord>,
}

impl AssetEntry {
    /// Whether the asset is a real vehicle: an actor of a model trained on a log.
    pub fn is_real(&self) -> bool {
        matches!(self.source, AssetSource::Model { .. })
    }
}

/// An asset to store ([`Library::store`]).
pub struct NewAsset {
    pub name: String,
    pub class: ObjectClass,
    pub source: AssetSource,
    pub up: UpAxis,
    /// Already z up.
    pub gaussians: Gaussians,
    pub harvest: Option<HarvestRecord>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Library {
    pub format: String,
    pub assets: Vec<AssetEntry>,
}

impl Default for Library {
    fn default() -> Self {
        Library { format: LIBRARY_FORMAT.into(), assets: vec![] }
    }
}

/// The PLY reader's error already names the file: kept as it is, not prefixed again.
fn ply_err(_file: &Path) -> impl Fn(splat::ply::PlyError) -> RenderError {
    RenderError::Ply
}

/// A Gaussian larger than this many times the asset's whole extent (its means' bounding box) is
/// no part of an object.
const MAX_SCALE_RATIO: f64 = 10.0;

/// Values an asset can be drawn with, whatever its unit (alignment scales it to the box):
/// means within [`scene::executed_check::MAX_COORD_M`], each Gaussian's scales at most
/// [`MAX_SCALE_RATIO`] times the asset's extent, and a rotation quaternion that is not zero. An asset breaking them (log-scales of 87, an all-zero quaternion) was drawn as
/// nothing and its case reported as valid; it is refused, naming the vertex and property.
fn check_asset_values(path: &Path, g: &Gaussians) -> Result<(), RenderError> {
    let bad = |i: usize, property: String, message: String| {
        RenderError::io(path, format!("vertex {i}: property `{property}`: {message}"))
    };
    let max = scene::executed_check::MAX_COORD_M;
    let (mut lo, mut hi) = ([f64::MAX; 3], [f64::MIN; 3]);
    for (i, m) in g.means.iter().enumerate() {
        for k in 0..3 {
            if m[k].is_nan() || m[k].abs() > max {
                return Err(bad(i, ["x", "y", "z"][k].into(), format!("{:e}; expected at most {max:e} in size", m[k])));
            }
            lo[k] = lo[k].min(m[k]);
            hi[k] = hi[k].max(m[k]);
        }
    }
    let extent = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max).max(1e-6);
    let largest = MAX_SCALE_RATIO * extent;
    for (i, (s, q)) in g.log_scales.iter().zip(&g.rotations).enumerate() {
        for (k, v) in s.iter().enumerate() {
            let scale = v.exp();
            if scale.is_nan() || scale > largest {
                return Err(bad(
                    i,
                    format!("scale_{k}"),
                    format!(
                        "log-scale {v} is a Gaussian of {scale:.3e}; the asset spans {extent:.3e}, so expected at most {largest:.3e}"
                    ),
                ));
            }
        }
        let norm2: f64 = q.iter().map(|c| c * c).sum();
        if norm2.is_nan() || norm2 <= 1e-12 {
            return Err(bad(i, "rot_0..rot_3".into(), "the rotation quaternion is zero".into()));
        }
    }
    Ok(())
}

/// Reads a 3DGS PLY and turns it so z is up.
pub fn read_asset_ply(path: &Path, up: UpAxis) -> Result<Gaussians, RenderError> {
    let g = splat::ply::read_ply(path).map_err(ply_err(path))?;
    if g.is_empty() {
        return Err(RenderError::io(path, "the PLY has no Gaussians"));
    }
    check_asset_values(path, &g)?;
    if up == UpAxis::Z {
        return Ok(g);
    }
    let r = up.z_up_from_asset();
    Ok(transform(&g, &r, [0.0; 3], &r))
}

/// The means of the Gaussians that count for geometry (opacity at least
/// [`MIN_GEOMETRY_OPACITY`]; all of them when none does).
pub fn geometry_points(g: &Gaussians) -> Vec<[f64; 3]> {
    let keep: Vec<[f64; 3]> = (0..g.len())
        .filter(|&i| splat::gaussians::sigmoid(g.opacity_logits[i]) >= MIN_GEOMETRY_OPACITY)
        .map(|i| g.means[i])
        .collect();
    if keep.is_empty() {
        g.means.clone()
    } else {
        keep
    }
}

/// Nominal (length, width, height) of a z-up asset.
pub fn nominal_size(g: &Gaussians) -> [f64; 3] {
    frame_of(&geometry_points(g)).map_or([0.0; 3], |f| f.extents)
}

/// The body colour of a vehicle's Gaussians: per channel, the median over the Gaussians at least
/// [`MIN_COLOUR_OPACITY`] opaque of their view-independent colour `0.5 + C0 * dc` (clamped to
/// [0, 1]). The median, not the mean: windows, tyres and lights are a minority of a car's
/// Gaussians. `None` when no Gaussian is that opaque.
pub fn body_colour(g: &Gaussians) -> Option<[f64; 3]> {
    let k = g.coeffs() * 3;
    let opaque: Vec<usize> =
        (0..g.len()).filter(|&i| splat::gaussians::sigmoid(g.opacity_logits[i]) >= MIN_COLOUR_OPACITY).collect();
    if opaque.is_empty() {
        return None;
    }
    Some(std::array::from_fn(|ch| {
        let mut v: Vec<f64> =
            opaque.iter().map(|&i| (0.5 + splat::sh::C0 * g.sh[i * k + ch]).clamp(0.0, 1.0)).collect();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n % 2 == 1 {
            v[n / 2]
        } else {
            (v[n / 2 - 1] + v[n / 2]) / 2.0
        }
    }))
}

/// Refuses a name that is not a plain file stem.
fn check_name(name: &str) -> Result<(), RenderError> {
    if name.is_empty() || !name.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c)) || name.starts_with('.')
    {
        return Err(RenderError::Settings {
            what: format!("asset name `{name}`"),
            detail: "use letters, digits, `-`, `_` and `.` (not first)".into(),
        });
    }
    Ok(())
}

impl Library {
    /// Reads `<dir>/index.json`; an absent index is an empty library.
    pub fn load(dir: &Path) -> Result<Library, RenderError> {
        let file = dir.join(INDEX_FILE);
        if !file.exists() {
            return Ok(Library::default());
        }
        let lib: Library = scene::format::read_json(&file)?;
        if lib.format != LIBRARY_FORMAT {
            return Err(RenderError::io(&file, format!("format {:?}, expected {LIBRARY_FORMAT:?}", lib.format)));
        }
        Ok(lib)
    }

    pub fn get(&self, name: &str) -> Option<&AssetEntry> {
        self.assets.iter().find(|a| a.name == name)
    }

    /// Loads an asset's Gaussians (z up).
    pub fn read(&self, dir: &Path, entry: &AssetEntry) -> Result<Gaussians, RenderError> {
        read_asset_ply(&dir.join(&entry.file), UpAxis::Z)
    }

    /// Adds `g` (already z up) as `name`, writing `<dir>/<name>.ply` and the index. A name
    /// already in the library is refused unless `replace`.
    pub fn add(
        dir: &Path,
        name: &str,
        class: ObjectClass,
        source: AssetSource,
        up: UpAxis,
        g: &Gaussians,
        replace: bool,
    ) -> Result<AssetEntry, RenderError> {
        let new = NewAsset { name: name.to_string(), class, source, up, gaussians: g.clone(), harvest: None };
        let mut stored = Library::store(dir, vec![new], &|_| replace, &|_| false)?;
        Ok(stored.pop().expect("one asset stored"))
    }

    /// Stores `new` in the library at `dir` in one change: each PLY is written beside its
    /// destination and renamed into place, then the index is replaced whole (an interrupted
    /// store leaves the old index). An asset of the same name is replaced only where
    /// `replaceable` says so (otherwise nothing is written); entries for which `remove` holds are
    /// dropped from the index and their PLY files deleted. Returns the new entries.
    pub fn store(
        dir: &Path,
        new: Vec<NewAsset>,
        replaceable: &dyn Fn(&AssetEntry) -> bool,
        remove: &dyn Fn(&AssetEntry) -> bool,
    ) -> Result<Vec<AssetEntry>, RenderError> {
        for (i, a) in new.iter().enumerate() {
            check_name(&a.name)?;
            if new[..i].iter().any(|b| b.name == a.name) {
                return Err(RenderError::Settings {
                    what: format!("asset `{}`", a.name),
                    detail: "is named twice in one change".into(),
                });
            }
        }
        let mut lib = Library::load(dir)?;
        for a in &new {
            if let Some(old) = lib.get(&a.name).filter(|old| !replaceable(old)) {
                return Err(RenderError::Settings {
                    what: format!("asset `{}`", old.name),
                    detail: format!("is already in {} (replace it explicitly)", dir.join(INDEX_FILE).display()),
                });
            }
        }
        std::fs::create_dir_all(dir).map_err(|e| RenderError::io(dir, e))?;
        let mut staged: Vec<(PathBuf, PathBuf)> = Vec::with_capacity(new.len());
        let mut entries = Vec::with_capacity(new.len());
        for a in &new {
            let file = format!("{}.ply", a.name);
            let tmp = dir.join(format!(".{file}.{}.tmp", std::process::id()));
            if let Err(e) = splat::ply::write_ply(&tmp, &a.gaussians).map_err(ply_err(&tmp)) {
                let _ = std::fs::remove_file(&tmp);
                staged.iter().for_each(|(t, _)| drop(std::fs::remove_file(t)));
                return Err(e);
            }
            staged.push((tmp, dir.join(&file)));
            entries.push(AssetEntry {
                name: a.name.clone(),
                class: a.class,
                size_lwh: nominal_size(&a.gaussians),
                source: a.source.clone(),
                file,
                up: a.up,
                gaussians: a.gaussians.len(),
                sh_degree: a.gaussians.sh_degree,
                colour: body_colour(&a.gaussians),
                harvest: a.harvest.clone(),
            });
        }
        for (i, (tmp, path)) in staged.iter().enumerate() {
            if let Err(e) = std::fs::rename(tmp, path) {
                staged[i..].iter().for_each(|(t, _)| drop(std::fs::remove_file(t)));
                return Err(RenderError::io(path, e));
            }
        }
        let dropped: Vec<AssetEntry> =
            lib.assets.iter().filter(|a| remove(a) && new.iter().all(|n| n.name != a.name)).cloned().collect();
        lib.assets.retain(|a| new.iter().all(|n| n.name != a.name) && !dropped.contains(a));
        lib.assets.extend(entries.iter().cloned());
        scene::format::write_json_pretty(&dir.join(INDEX_FILE), &lib)?;
        for d in dropped.iter().filter(|d| lib.assets.iter().all(|a| a.file != d.file)) {
            let _ = std::fs::remove_file(dir.join(&d.file));
        }
        Ok(entries)
    }
}

/// Gaussians below this opacity are left out of an asset taken from a model: they draw nothing.
pub const MIN_ASSET_OPACITY: f64 = 0.02;

/// `g` without its nearly transparent Gaussians (opacity below [`MIN_ASSET_OPACITY`]).
pub fn without_transparent(g: &Gaussians) -> Gaussians {
    let mut g = g.clone();
    let keep: Vec<bool> = g.opacity_logits.iter().map(|&o| splat::gaussians::sigmoid(o) >= MIN_ASSET_OPACITY).collect();
    recon::model::retain(&mut g, &keep);
    g
}

/// The Gaussians of actor `track` of the model in `model_dir` (its box frame: x forward, z up),
/// with its box size. Nearly transparent Gaussians are left out.
pub fn extract_actor(model_dir: &Path, track: &str) -> Result<(Gaussians, [f64; 3]), RenderError> {
    let (model, _) = recon::model_io::load_model(model_dir)?;
    let actor =
        model.actors.iter().find(|a| a.track_id == track).ok_or_else(|| RenderError::no_actor(&model, track))?;
    let g = without_transparent(&actor.gaussians);
    if g.is_empty() {
        return Err(RenderError::Settings {
            what: format!("{}: actor `{track}`", model_dir.display()),
            detail: "has no Gaussian that is not transparent".into(),
        });
    }
    Ok((g, actor.size_lwh))
}

/// What the library records of a harvested vehicle (`AssetEntry::harvest`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct HarvestRecord {
    /// The scene the model was trained on (its name).
    pub scene: String,
    /// The track's median box size (m).
    pub track_size_lwh: [f64; 3],
    #[serde(flatten)]
    pub observed: Observed,
    /// Whether training had already mirrored the actor (model.json), so the harvest did not.
    pub mirrored_in_model: bool,
}

#[cfg(test)]
mod tests;
