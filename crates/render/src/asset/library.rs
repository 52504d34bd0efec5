//! The asset library: a directory of standard 3DGS PLY files and `index.json` naming each one's
//! class, nominal size and source.
//!
//! ```text
//! <lib>/index.json     {"format": "carla-gs-assets/1", "assets": [{name, class, size_lwh, source,
//!                       file, up, gaussians, sh_degree}, ...]}
//! <lib>/<name>.ply     the asset, z up (converted from its declared up axis when added)
//! ```
//!
//! Sources: a user's PLY (from SAM-3D or any other tool; any SH degree; its up axis declared,
//! `z` by default: a `y`-up export is turned so +y becomes +z), an actor extracted from a trained
//! model (already in its box frame: x forward, z up), or a synthetic vehicle (`pipeline`). The
//! nominal size is the canonical frame's extents (`align::frame_of`) of the Gaussians that are
//! not nearly transparent, so `auto` can pick the nearest-sized asset of a class.

use super::align::frame_of;
use super::covariance::{transform, Mat3};
use crate::RenderError;
use scene::ObjectClass;
use serde::{Deserialize, Serialize};
use splat::Gaussians;
use std::path::{Path, PathBuf};

pub const LIBRARY_FORMAT: &str = "carla-gs-assets/1";
pub const INDEX_FILE: &str = "index.json";
/// Gaussians below this opacity do not count for an asset's geometry (size, alignment).
pub const MIN_GEOMETRY_OPACITY: f64 = 0.1;

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

fn ply_err(file: &Path) -> impl Fn(splat::ply::PlyError) -> RenderError + '_ {
    move |e| RenderError::io(file, e)
}

/// Reads a 3DGS PLY and turns it so z is up.
pub fn read_asset_ply(path: &Path, up: UpAxis) -> Result<Gaussians, RenderError> {
    let g = splat::ply::read_ply(path).map_err(ply_err(path))?;
    if g.is_empty() {
        return Err(RenderError::io(path, "the PLY has no Gaussians"));
    }
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

    /// The asset of `class` whose nominal size is nearest `size_lwh` (sum of |log ratio| over
    /// the three axes; the first listed wins a tie).
    pub fn nearest(&self, class: ObjectClass, size_lwh: [f64; 3]) -> Option<&AssetEntry> {
        let dist = |a: &AssetEntry| -> f64 {
            (0..3).map(|k| (a.size_lwh[k].max(1e-6) / size_lwh[k].max(1e-6)).ln().abs()).sum()
        };
        let mut best: Option<(&AssetEntry, f64)> = None;
        for a in self.assets.iter().filter(|a| a.class == class) {
            let d = dist(a);
            if best.is_none_or(|(_, b)| d < b) {
                best = Some((a, d));
            }
        }
        best.map(|(a, _)| a)
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
        if name.is_empty()
            || !name.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c))
            || name.starts_with('.')
        {
            return Err(RenderError::Settings {
                what: format!("asset name `{name}`"),
                detail: "use letters, digits, `-`, `_` and `.` (not first)".into(),
            });
        }
        let mut lib = Library::load(dir)?;
        if lib.get(name).is_some() && !replace {
            return Err(RenderError::Settings {
                what: format!("asset `{name}`"),
                detail: format!("is already in {} (replace it explicitly)", dir.join(INDEX_FILE).display()),
            });
        }
        std::fs::create_dir_all(dir).map_err(|e| RenderError::io(dir, e))?;
        let file = format!("{name}.ply");
        let path = dir.join(&file);
        splat::ply::write_ply(&path, g).map_err(ply_err(&path))?;
        let entry = AssetEntry {
            name: name.to_string(),
            class,
            size_lwh: nominal_size(g),
            source,
            file,
            up,
            gaussians: g.len(),
            sh_degree: g.sh_degree,
        };
        lib.assets.retain(|a| a.name != name);
        lib.assets.push(entry.clone());
        scene::format::write_json_pretty(&dir.join(INDEX_FILE), &lib)?;
        Ok(entry)
    }
}

/// What `--asset` / `--replace <track>=<spec>` can name.
pub const AUTO: &str = "auto";

/// The asset `spec` names, with a name for reports: `auto` (the library's nearest-sized asset
/// of `class`), a `.ply` file (turned from its declared `up` axis) or an asset of the library.
pub fn resolve(
    spec: &str,
    library_dir: &Path,
    up: UpAxis,
    class: ObjectClass,
    size_lwh: [f64; 3],
) -> Result<(String, Gaussians), RenderError> {
    if spec == AUTO {
        let lib = Library::load(library_dir)?;
        let entry = lib.nearest(class, size_lwh).ok_or_else(|| RenderError::Settings {
            what: format!("asset `auto` for a {} of size {size_lwh:?}", class.as_str()),
            detail: format!("the library {} has no asset of that class", library_dir.join(INDEX_FILE).display()),
        })?;
        return Ok((entry.name.clone(), lib.read(library_dir, entry)?));
    }
    let path = Path::new(spec);
    if spec.to_ascii_lowercase().ends_with(".ply") || path.is_file() {
        return Ok((spec.to_string(), read_asset_ply(path, up)?));
    }
    let lib = Library::load(library_dir)?;
    let entry = lib.get(spec).ok_or_else(|| RenderError::Settings {
        what: format!("asset `{spec}`"),
        detail: format!(
            "is neither a .ply file nor an asset of {} (assets: {})",
            library_dir.join(INDEX_FILE).display(),
            lib.assets.iter().map(|a| a.name.as_str()).collect::<Vec<_>>().join(", ")
        ),
    })?;
    Ok((entry.name.clone(), lib.read(library_dir, entry)?))
}

/// The Gaussians of actor `track` of the model in `model_dir` (its box frame: x forward, z up),
/// with its box size. Nearly transparent Gaussians are left out.
pub fn extract_actor(model_dir: &Path, track: &str) -> Result<(Gaussians, [f64; 3]), RenderError> {
    let (model, _) = recon::model_io::load_model(model_dir)?;
    let actor =
        model.actors.iter().find(|a| a.track_id == track).ok_or_else(|| RenderError::no_actor(&model, track))?;
    let mut g = actor.gaussians.clone();
    let keep: Vec<bool> = g.opacity_logits.iter().map(|&o| splat::gaussians::sigmoid(o) >= 0.02).collect();
    recon::model::retain(&mut g, &keep);
    if g.is_empty() {
        return Err(RenderError::Settings {
            what: format!("{}: actor `{track}`", model_dir.display()),
            detail: "has no Gaussian that is not transparent".into(),
        });
    }
    Ok((g, actor.size_lwh))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(name: &str, class: ObjectClass, size_lwh: [f64; 3]) -> AssetEntry {
        AssetEntry {
            name: name.into(),
            class,
            size_lwh,
            source: AssetSource::Synth { vehicle: name.into(), method: "test".into() },
            file: format!("{name}.ply"),
            up: UpAxis::Z,
            gaussians: 1,
            sh_degree: 0,
        }
    }

    #[test]
    fn auto_picks_the_nearest_size_of_the_class() {
        let lib = Library {
            format: LIBRARY_FORMAT.into(),
            assets: vec![
                entry("sedan", ObjectClass::Vehicle, [4.5, 1.85, 1.48]),
                entry("truck", ObjectClass::Vehicle, [7.5, 2.4, 3.0]),
                entry("person", ObjectClass::Pedestrian, [0.6, 0.6, 1.8]),
            ],
        };
        assert_eq!(lib.nearest(ObjectClass::Vehicle, [4.2, 1.8, 1.5]).unwrap().name, "sedan");
        assert_eq!(lib.nearest(ObjectClass::Vehicle, [8.0, 2.5, 3.2]).unwrap().name, "truck");
        assert_eq!(lib.nearest(ObjectClass::Pedestrian, [8.0, 2.5, 3.2]).unwrap().name, "person");
        assert!(lib.nearest(ObjectClass::Cyclist, [1.8, 0.6, 1.7]).is_none());
    }

    #[test]
    fn up_axes_are_proper_rotations_taking_the_axis_to_z() {
        let axes = [
            (UpAxis::Z, [0.0, 0.0, 1.0]),
            (UpAxis::NegZ, [0.0, 0.0, -1.0]),
            (UpAxis::Y, [0.0, 1.0, 0.0]),
            (UpAxis::NegY, [0.0, -1.0, 0.0]),
            (UpAxis::X, [1.0, 0.0, 0.0]),
            (UpAxis::NegX, [-1.0, 0.0, 0.0]),
        ];
        for (up, v) in axes {
            let r = up.z_up_from_asset();
            assert_eq!(super::super::covariance::mat_vec(&r, v), [0.0, 0.0, 1.0], "{up:?}");
            let d = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
                - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
                + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
            assert_eq!(d, 1.0, "{up:?}");
        }
        assert_eq!(UpAxis::parse("-y").unwrap(), UpAxis::NegY);
        assert!(UpAxis::parse("up").unwrap_err().to_string().contains("up axis `up`"));
    }
}
