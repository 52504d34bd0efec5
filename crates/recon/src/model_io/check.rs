//! The one validation of a model directory's `model.json` that every loader goes through
//! ([`super::load_model`], used by `render`, `eval-recon`, `run`, `video`, `replace`, `asset`,
//! the demo and the report), so every command refuses the same records, naming the field:
//!
//! * [`check_record`] (no scene needed): every file it names (`background_file`,
//!   `actors[i].file`) is a plain relative name inside the model folder (no absolute path, no
//!   `..`, no `.`, no symbolic link leading out of the folder), track ids are non-empty and
//!   unique, box sizes finite and non-negative, `scale` in (0, 1] as `train` writes it,
//!   `extent` finite and non-negative, `sky_res` from 1 (an empty sky has no texel to look up);
//! * [`check_scene`] (a command that also reads a scene): the model was trained on that scene:
//!   the same `scene_name`, every actor a track of it, and, where the model folder still holds the
//!   training checkpoint, the same `scene.json` (the fingerprint the checkpoint's header records).
//!
//! Why: a record is input like any other; before this, `run`, `video`, `replace` and `asset`
//! followed `"background_file": "/elsewhere/x.ply"` or `"../x.ply"`, kept two actors with one
//! track id, and took a zero or NaN scale, while `render` and `eval-recon` refused some of it.

use super::ModelRecord;
use crate::error::ReconError;
use scene::Scene;
use std::path::{Component, Path};

/// The `model.json` of `dir`, for error messages.
fn record_file(dir: &Path) -> std::path::PathBuf {
    dir.join("model.json")
}

fn refuse(dir: &Path, detail: String) -> ReconError {
    ReconError::Format { file: record_file(dir), detail }
}

/// `name` (field `field` of `model.json` in `dir`) is a relative path of plain names that stays
/// inside `dir`, also once symbolic links are followed (checked when the file exists; a missing
/// file is reported by its reader, naming it).
pub fn check_file_name(dir: &Path, field: &str, name: &str) -> Result<(), ReconError> {
    let p = Path::new(name);
    let plain = !name.is_empty()
        && !name.contains('\\')
        && p.components().all(|c| matches!(c, Component::Normal(_)))
        && !name.split('/').any(|part| part.is_empty() || part == "." || part == "..");
    if !plain {
        return Err(refuse(
            dir,
            format!("`{field}` is {name:?}, expected a plain relative file name inside the model folder (no absolute path, `.` or `..`)"),
        ));
    }
    let joined = dir.join(p);
    if let (Ok(root), Ok(file)) = (dir.canonicalize(), joined.canonicalize()) {
        if !file.starts_with(&root) {
            return Err(refuse(
                dir,
                format!(
                    "`{field}` {name:?} leads to {} through a symbolic link, outside the model folder {}",
                    file.display(),
                    root.display()
                ),
            ));
        }
    }
    Ok(())
}

/// Everything of a record that needs no scene (see the module header); errors name the field.
pub fn check_record(dir: &Path, record: &ModelRecord) -> Result<(), ReconError> {
    if !(record.scale.is_finite() && record.scale > 0.0 && record.scale <= 1.0) {
        return Err(refuse(
            dir,
            format!("`scale` is {}, expected a finite fraction of the camera's image size in (0, 1]", record.scale),
        ));
    }
    if !(record.extent.is_finite() && record.extent >= 0.0) {
        return Err(refuse(dir, format!("`extent` is {}, expected a finite length >= 0", record.extent)));
    }
    if !(1..=crate::budget::MAX_SKY_RES).contains(&record.sky_res) {
        return Err(refuse(
            dir,
            format!("`sky_res` is {}, expected 1 to {} texels", record.sky_res, crate::budget::MAX_SKY_RES),
        ));
    }
    check_file_name(dir, "background_file", &record.background_file)?;
    let mut ids = std::collections::HashMap::new();
    let mut files = std::collections::HashMap::new();
    for (i, a) in record.actors.iter().enumerate() {
        if a.track_id.is_empty() {
            return Err(refuse(dir, format!("`actors[{i}].track_id` is empty, expected a track id")));
        }
        if let Some(first) = ids.insert(a.track_id.as_str(), i) {
            return Err(refuse(
                dir,
                format!(
                    "`actors[{i}].track_id` {:?} is also `actors[{first}].track_id`, expected one entry per track",
                    a.track_id
                ),
            ));
        }
        if a.size_lwh.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(refuse(
                dir,
                format!("`actors[{i}].size_lwh` is {:?}, expected three finite lengths >= 0", a.size_lwh),
            ));
        }
        let field = format!("actors[{i}].file");
        check_file_name(dir, &field, &a.file)?;
        if a.file == record.background_file {
            return Err(refuse(dir, format!("`{field}` {:?} is also `background_file`", a.file)));
        }
        if let Some(first) = files.insert(a.file.as_str(), i) {
            return Err(refuse(dir, format!("`{field}` {:?} is also `actors[{first}].file`", a.file)));
        }
    }
    Ok(())
}

/// The model in `dir` (record `record`) was trained on `scene`, read from `scene_dir`: same
/// `scene_name`, every actor a track of it, and the same `scene.json` where the model folder's
/// checkpoint records its fingerprint. Errors name the field and both scenes.
pub fn check_scene(dir: &Path, record: &ModelRecord, scene_dir: &Path, scene: &Scene) -> Result<(), ReconError> {
    if record.scene_name != scene.name {
        return Err(refuse(
            dir,
            format!(
                "`scene_name` is {:?}: the model was trained on another scene than {} ({:?})",
                record.scene_name,
                scene_dir.display(),
                scene.name
            ),
        ));
    }
    for (i, a) in record.actors.iter().enumerate() {
        if scene.track(&a.track_id).is_none() {
            return Err(refuse(
                dir,
                format!(
                    "`actors[{i}].track_id` {:?} is not a track of scene {:?} in {}",
                    a.track_id,
                    scene.name,
                    scene_dir.display()
                ),
            ));
        }
    }
    if let Some(fp) = crate::checkpoint::header_run(&dir.join("checkpoint.bin")).map(|r| r.scene_fingerprint) {
        let file = scene_dir.join(scene::format::SCENE_FILE);
        let now = crate::checkpoint::scene_fingerprint(scene_dir)?;
        if now != fp {
            return Err(ReconError::Format {
                file: dir.join("checkpoint.bin"),
                detail: format!(
                    "`scene_fingerprint` {fp}: the model was trained on another {} (fingerprint now {now}), \
                     though both are named {:?}",
                    file.display(),
                    scene.name
                ),
            });
        }
    }
    Ok(())
}
