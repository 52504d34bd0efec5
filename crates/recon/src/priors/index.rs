//! `priors/priors.json` (format `carla-gs-priors/1`) and reading the maps back for the trainer:
//! [`PriorIndex::load`] parses the index, [`PriorIndex::maps`] decodes one image's files.
//! Every file an entry names must be a plain file name inside `priors/` ([`check_file_name`]): an
//! index is input, and `../x` or `/x` would read files anywhere.

use super::error::PriorError;
use super::ground::Plane;
use super::image_io::{read_gz_f32, read_mask_png};
use serde::{Deserialize, Serialize};
use std::path::Path;

pub const PRIORS_DIR: &str = "priors";
pub const PRIORS_FILE: &str = "priors.json";
pub const PRIORS_FORMAT: &str = "carla-gs-priors/1";

/// Where an image's depth prior came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DepthSource {
    Lidar,
    DepthDir,
    Stereo,
    None,
}

/// Largest `priors.json` read (about 2,000 bytes an image: half a million images).
pub const MAX_INDEX_BYTES: u64 = 1 << 30;
/// Most pixels of one image's priors (a 32k x 32k image).
pub const MAX_PIXELS: usize = 1 << 30;
/// How far a prior normal's length may be from 1 (they are written as unit vectors in f32).
pub const NORMAL_TOLERANCE: f32 = 1e-3;

/// Refuses a depth that is not finite (0 is "none"), naming the file and the pixel.
pub fn check_depth(path: &Path, depth: &[f32]) -> Result<(), PriorError> {
    match depth.iter().position(|d| !d.is_finite()) {
        None => Ok(()),
        Some(i) => Err(PriorError::invalid(
            path,
            format!("pixel {i}: depth {}, expected a finite number (0 = none)", depth[i]),
        )),
    }
}

/// Refuses a normal that is neither `[0, 0, 0]` ("none") nor a unit vector (length within
/// [`NORMAL_TOLERANCE`] of 1), naming the file and the pixel.
pub fn check_normals(path: &Path, normal: &[[f32; 3]]) -> Result<(), PriorError> {
    let bad = |n: &[f32; 3]| {
        let len = n.iter().map(|c| (*c as f64).powi(2)).sum::<f64>().sqrt();
        *n != [0.0; 3] && ((len - 1.0).abs() > NORMAL_TOLERANCE as f64 || len.is_nan())
    };
    match normal.iter().position(bad) {
        None => Ok(()),
        Some(i) => Err(PriorError::invalid(
            path,
            format!("pixel {i}: normal {:?}, expected a unit vector (or [0, 0, 0] for none)", normal[i]),
        )),
    }
}

/// A prior file name is one plain name inside `priors/`: not empty, no `/` or `\\`, not `.` or
/// `..`, no NUL.
pub fn check_file_name(name: &str) -> Result<(), String> {
    if name.is_empty() || name == "." || name == ".." || name.contains(['/', '\\', '\0']) {
        return Err(format!("expected a plain file name inside {PRIORS_DIR}/ (no directory, `..` or absolute path)"));
    }
    Ok(())
}

/// `dir/name` for a checked plain `name`, refused when a symbolic link leads it out of `dir`
/// (a missing file is left to its reader, which names it).
fn inside(dir: &Path, name: &str) -> Result<std::path::PathBuf, PriorError> {
    let path = dir.join(name);
    if let (Ok(root), Ok(real)) = (dir.canonicalize(), path.canonicalize()) {
        if !real.starts_with(&root) {
            return Err(PriorError::invalid(
                &path,
                format!("leads to {} through a symbolic link, outside {}", real.display(), root.display()),
            ));
        }
    }
    Ok(path)
}

/// File names (relative to `priors/`) of one image's maps.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PriorFiles {
    pub depth: String,
    pub normal: String,
    pub ground: String,
    pub object: String,
    pub mask: String,
    pub depth_png: String,
    pub normal_png: String,
}

impl PriorFiles {
    pub fn for_image(frame: usize, camera: &str) -> Self {
        let f = |s: &str| format!("{frame:06}_{camera}.{s}");
        Self {
            depth: f("depth.f32.gz"),
            normal: f("normal.f32.gz"),
            ground: f("ground.png"),
            object: f("object.png"),
            mask: f("mask.png"),
            depth_png: f("depth.png"),
            normal_png: f("normal.png"),
        }
    }
}

/// One image's entry in `priors.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PriorEntry {
    pub frame: usize,
    pub camera: String,
    pub width: usize,
    pub height: usize,
    pub depth_source: DepthSource,
    pub valid_depth_fraction: f64,
    pub ground_fraction: f64,
    pub object_fraction: f64,
    pub mask_fraction: f64,
    /// The RANSAC ground plane in the ego frame, if one was found.
    pub ground_plane: Option<Plane>,
    pub files: PriorFiles,
}

/// Parsed `priors.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PriorIndex {
    pub format: String,
    pub settings: serde_json::Value,
    pub images: Vec<PriorEntry>,
}

/// One image's priors, row-major from the top-left pixel.
#[derive(Clone, Debug, PartialEq)]
pub struct PriorMaps {
    pub width: usize,
    pub height: usize,
    /// z-depth along the optical axis (m), 0 = none.
    pub depth: Vec<f32>,
    /// Unit normal in Waymo camera axes (x forward, y left, z up), `[0, 0, 0]` = none.
    pub normal: Vec<[f32; 3]>,
    pub ground: Vec<bool>,
    pub object: Vec<bool>,
    pub mask: Vec<bool>,
}

impl PriorIndex {
    /// Reads `<scene_dir>/priors/priors.json`; errors name the file (and field).
    pub fn load(scene_dir: &Path) -> Result<PriorIndex, PriorError> {
        let file = scene_dir.join(PRIORS_DIR).join(PRIORS_FILE);
        let meta = std::fs::metadata(&file).map_err(|e| PriorError::io(&file, e))?;
        if !meta.is_file() || meta.len() > MAX_INDEX_BYTES {
            return Err(PriorError::invalid(
                &file,
                format!(
                    "expected a regular file of at most {MAX_INDEX_BYTES} bytes (found {} bytes, regular file: {})",
                    meta.len(),
                    meta.is_file()
                ),
            ));
        }
        let index: PriorIndex = scene::format::read_json(&file)?;
        if index.format != PRIORS_FORMAT {
            return Err(PriorError::invalid(
                &file,
                format!("format is \"{}\", expected \"{PRIORS_FORMAT}\"", index.format),
            ));
        }
        index.check_file_names(&file)?;
        Ok(index)
    }

    /// Every file name of every entry is a plain name inside `priors/`; the error names the entry
    /// (`images[3]` of frame and camera) and the field.
    fn check_file_names(&self, file: &Path) -> Result<(), PriorError> {
        for (i, e) in self.images.iter().enumerate() {
            let f = &e.files;
            let fields = [
                ("depth", &f.depth),
                ("normal", &f.normal),
                ("ground", &f.ground),
                ("object", &f.object),
                ("mask", &f.mask),
                ("depth_png", &f.depth_png),
                ("normal_png", &f.normal_png),
            ];
            for (field, name) in fields {
                check_file_name(name).map_err(|why| {
                    PriorError::invalid(
                        file,
                        format!(
                            "images[{i}] (frame {}, camera {}): `files.{field}` is {name:?}: {why}",
                            e.frame, e.camera
                        ),
                    )
                })?;
            }
        }
        Ok(())
    }

    pub fn entry(&self, frame: usize, camera: &str) -> Option<&PriorEntry> {
        self.images.iter().find(|e| e.frame == frame && e.camera == camera)
    }

    /// Decodes the maps of one image; `None` when the index has no entry for it.
    pub fn maps(&self, scene_dir: &Path, frame: usize, camera: &str) -> Result<Option<PriorMaps>, PriorError> {
        let Some(e) = self.entry(frame, camera) else { return Ok(None) };
        let dir = scene_dir.join(PRIORS_DIR);
        let n = e.width.checked_mul(e.height).filter(|n| *n <= MAX_PIXELS).ok_or_else(|| {
            let file = dir.join(PRIORS_FILE);
            PriorError::invalid(
                file,
                format!("image {frame} {camera}: {}x{} pixels, at most {MAX_PIXELS}", e.width, e.height),
            )
        })?;
        let depth_path = inside(&dir, &e.files.depth)?;
        let depth = read_gz_f32(&depth_path, n)?;
        check_depth(&depth_path, &depth)?;
        let normal_path = inside(&dir, &e.files.normal)?;
        let normal: Vec<[f32; 3]> =
            read_gz_f32(&normal_path, 3 * n)?.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        check_normals(&normal_path, &normal)?;
        let mask = |f: &str| read_mask_png(&inside(&dir, f)?, e.width, e.height);
        Ok(Some(PriorMaps {
            width: e.width,
            height: e.height,
            depth,
            normal,
            ground: mask(&e.files.ground)?,
            object: mask(&e.files.object)?,
            mask: mask(&e.files.mask)?,
        }))
    }
}
