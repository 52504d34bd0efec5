//! The on-disk scene directory (`docs/scene-format.md`):
//!
//! ```text
//! <scene>/scene.json         versioned description ("format": "carla-gs-scene/1")
//! <scene>/images/<frame>_<CAMERA>.jpg|png   camera images (JPEG or PNG, colour or grey)
//! <scene>/lidar/<frame>.bin  little-endian f32 x y z intensity per point, ego frame
//! ```
//!
//! Loading parses with field paths (`serde_path_to_error`) and then validates the content
//! (`validate`), so the first bad field is reported by path. Every file is read through
//! [`crate::input`]: only a regular file, within the budget of its kind.

use crate::error::SceneError;
use crate::input::{read_capped, MAX_JSON_BYTES, MAX_LIDAR_BYTES, MAX_SCENE_JSON_BYTES};
use crate::model::Scene;
use crate::output::write_file_atomic;
use crate::validate::validate_scene;
use std::path::Path;

pub const SCENE_FILE: &str = "scene.json";
pub const IMAGES_DIR: &str = "images";
pub const LIDAR_DIR: &str = "lidar";

/// The relative path of a frame's JPEG image for a camera.
pub fn image_rel_path(frame: usize, camera: &str) -> String {
    image_rel_path_ext(frame, camera, "jpg")
}

/// The relative path of a frame's image for a camera with the file extension `ext` (`jpg`, `png`).
pub fn image_rel_path_ext(frame: usize, camera: &str, ext: &str) -> String {
    format!("{IMAGES_DIR}/{frame:06}_{camera}.{ext}")
}

/// The relative path of a frame's LiDAR sweep.
pub fn lidar_rel_path(frame: usize) -> String {
    format!("{LIDAR_DIR}/{frame:06}.bin")
}

/// Scene directories at `path`: itself if it holds `scene.json`, else its sub-directories that
/// do (sorted), e.g. the output of ingesting a file of several WOMD scenarios. Anything named
/// `scene.json` counts (a directory, a device, a broken link), so that loading it names the
/// problem rather than this saying there is no scene.
pub fn find_scene_dirs(path: &Path) -> Result<Vec<std::path::PathBuf>, SceneError> {
    let holds_scene = |d: &Path| std::fs::symlink_metadata(d.join(SCENE_FILE)).is_ok();
    if holds_scene(path) {
        return Ok(vec![path.to_path_buf()]);
    }
    let mut dirs: Vec<std::path::PathBuf> = std::fs::read_dir(path)
        .map_err(|e| SceneError::io(path, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| holds_scene(p))
        .collect();
    dirs.sort();
    if dirs.is_empty() {
        return Err(SceneError::Invalid {
            file: path.to_path_buf(),
            field: String::new(),
            message: "no scene.json here or in its sub-directories".into(),
        });
    }
    Ok(dirs)
}

/// Loads and validates `<dir>/scene.json` (and checks that referenced files exist). The file
/// must be a regular file of at most [`MAX_SCENE_JSON_BYTES`].
pub fn load_scene(dir: &Path) -> Result<Scene, SceneError> {
    let file = dir.join(SCENE_FILE);
    let bytes = read_capped(&file, MAX_SCENE_JSON_BYTES, "a scene.json")?;
    let scene: Scene = parse_json_slice(&file, &bytes)?;
    validate_scene(&scene, Some(dir)).map_err(|(field, message)| SceneError::Invalid { file, field, message })?;
    Ok(scene)
}

/// Parses scene JSON text; `file` is only used in error messages. Does not validate content.
pub fn parse_scene_json(file: &Path, text: &str) -> Result<Scene, SceneError> {
    parse_json(file, text)
}

/// Parses JSON into `T`, reporting the failing field by path; `file` names it in errors.
pub fn parse_json<T: serde::de::DeserializeOwned>(file: &Path, text: &str) -> Result<T, SceneError> {
    parse_json_slice(file, text.as_bytes())
}

/// [`parse_json`] of bytes (invalid UTF-8 is reported where it is).
pub fn parse_json_slice<T: serde::de::DeserializeOwned>(file: &Path, bytes: &[u8]) -> Result<T, SceneError> {
    let de = &mut serde_json::Deserializer::from_slice(bytes);
    serde_path_to_error::deserialize(de).map_err(|e| SceneError::Json {
        file: file.to_path_buf(),
        field: e.path().to_string(),
        message: e.inner().to_string(),
    })
}

/// Validates `scene` (files included) and writes `<dir>/scene.json` atomically. Write the
/// images and LiDAR first: validation checks that they exist. The JSON is compact (a WOMD
/// scene is ~4 MB that way); `jq . scene.json` shows it indented.
pub fn write_scene(dir: &Path, scene: &Scene) -> Result<(), SceneError> {
    let file = dir.join(SCENE_FILE);
    validate_scene(scene, Some(dir)).map_err(|(field, message)| SceneError::Invalid {
        file: file.clone(),
        field,
        message,
    })?;
    let json = serde_json::to_vec(scene).map_err(|e| SceneError::Json {
        file: file.clone(),
        field: String::new(),
        message: e.to_string(),
    })?;
    write_file_atomic(&file, &json)
}

/// Reads and parses a JSON file (no content validation): a regular file of at most
/// [`MAX_JSON_BYTES`]; [`read_json_within`] names a smaller budget.
pub fn read_json<T: serde::de::DeserializeOwned>(file: &Path) -> Result<T, SceneError> {
    read_json_within(file, MAX_JSON_BYTES, "a JSON file")
}

/// Reads and parses a JSON file of at most `max` bytes; `what` names its kind in the error.
pub fn read_json_within<T: serde::de::DeserializeOwned>(
    file: &Path,
    max: u64,
    what: &'static str,
) -> Result<T, SceneError> {
    let bytes = read_capped(file, max, what)?;
    parse_json_slice(file, &bytes)
}

/// Writes `value` as pretty JSON through a temporary file and a rename.
pub fn write_json_pretty<T: serde::Serialize>(file: &Path, value: &T) -> Result<(), SceneError> {
    let json = serde_json::to_vec_pretty(value).map_err(|e| SceneError::Json {
        file: file.to_path_buf(),
        field: String::new(),
        message: e.to_string(),
    })?;
    write_file_atomic(file, &json)
}

/// Writes a LiDAR sweep (`[x, y, z, intensity]` per point) in the scene's binary layout.
pub fn write_lidar(path: &Path, points: &[[f32; 4]]) -> Result<(), SceneError> {
    let mut bytes = Vec::with_capacity(points.len() * 16);
    for p in points {
        for v in p {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    write_file_atomic(path, &bytes)
}

/// Reads a LiDAR sweep: a regular file of at most [`MAX_LIDAR_BYTES`], a multiple of 16 bytes.
pub fn read_lidar(path: &Path) -> Result<Vec<[f32; 4]>, SceneError> {
    let bytes = read_capped(path, MAX_LIDAR_BYTES, "a LiDAR sweep")?;
    if bytes.len() % 16 != 0 {
        return Err(SceneError::Invalid {
            file: path.to_path_buf(),
            field: String::new(),
            message: format!("{} bytes is not a whole number of 16-byte points (x y z intensity f32)", bytes.len()),
        });
    }
    Ok(bytes
        .chunks_exact(16)
        .map(|c| {
            let f = |i: usize| f32::from_le_bytes([c[i], c[i + 1], c[i + 2], c[i + 3]]);
            [f(0), f(4), f(8), f(12)]
        })
        .collect())
}
