//! `ingest`: driving logs and photo sets to carla-gs scenes.
//!
//! Inputs are TFRecord files of Waymo v1 perception `Frame`s (one segment, possibly split over
//! several files) or of WOMD `Scenario`s (one scene per record), or one folder: a KITTI odometry
//! sequence (`kitti`), a PandaSet sequence (`pandaset`) or an instant-ngp / nerfstudio `transforms.json` set (`transforms_json`).
//! The kind is detected from the content (`detect`, `folder`) or forced. Output goes to a staging directory that is renamed into place
//! only when everything converted and validated, so bad input never leaves a partial scene.

pub mod camera_check;
pub mod detect;
pub mod error;
pub mod folder;
pub mod input_file;
pub mod kitti;
pub mod pandaset;
pub mod proto;
pub mod range_image;
pub mod shared;
pub mod tfrecord;
pub mod transforms_json;
pub mod undistort;
pub mod waymo_frame;
pub mod womd;

pub use detect::Expect;
pub use error::IngestError;

use detect::{decode_record, Decoded};
use indicatif::ProgressBar;
use scene::{Scene, StagedDir};
use std::path::{Path, PathBuf};
use tfrecord::TfRecordReader;
use waymo_frame::WaymoFrameBuilder;

enum Collected<'a> {
    Nothing,
    Frames(WaymoFrameBuilder<'a>),
    Scenarios(Vec<Scene>),
}

/// Reads every record of every input and converts it. With `staging`, images and LiDAR of a
/// Frame segment are written under it (scene JSON is written by the caller).
fn convert(
    inputs: &[PathBuf],
    expect: Expect,
    staging: Option<&Path>,
    progress: &ProgressBar,
) -> Result<Vec<Scene>, IngestError> {
    if let Some(dir) = folder::folder_of(inputs, expect) {
        return Ok(vec![folder::read_folder(&dir, expect, staging, progress)?]);
    }
    if let Some(e @ (Expect::KittiOdometry | Expect::TransformsJson | Expect::Pandaset)) = Some(expect) {
        let first = inputs.first().cloned().unwrap_or_default();
        return Err(error::content(first, format!("{e:?} input must be one folder")));
    }
    let total: u64 = inputs.iter().filter_map(|p| std::fs::metadata(p).ok()).map(|m| m.len()).sum();
    progress.set_length(total);
    let mut collected = Collected::Nothing;
    for file in inputs {
        let f = std::fs::File::open(file).map_err(|e| IngestError::Io { file: file.clone(), source: e })?;
        let mut records = 0usize;
        for rec in TfRecordReader::new(std::io::BufReader::with_capacity(1 << 20, f)) {
            let rec = rec.map_err(|source| IngestError::Record { file: file.clone(), source })?;
            records += 1;
            progress.inc(rec.data.len() as u64 + 16);
            let decoded = decode_record(&rec.data, expect).map_err(|detail| IngestError::Unrecognised {
                file: file.clone(),
                index: rec.index,
                offset: rec.offset,
                detail,
            })?;
            let mismatch = |found: &'static str, expected: &'static str| IngestError::MixedKinds {
                file: file.clone(),
                found,
                expected,
            };
            match (&mut collected, decoded) {
                (Collected::Nothing, Decoded::Frame(fr)) => {
                    let mut b = WaymoFrameBuilder::new(staging)?;
                    b.add(file, rec.index, &fr)?;
                    collected = Collected::Frames(b);
                }
                (Collected::Nothing, Decoded::Scenario(sc)) => {
                    collected = Collected::Scenarios(vec![womd::scenario_to_scene(file, rec.index, &sc)?]);
                }
                (Collected::Frames(b), Decoded::Frame(fr)) => b.add(file, rec.index, &fr)?,
                (Collected::Scenarios(v), Decoded::Scenario(sc)) => {
                    v.push(womd::scenario_to_scene(file, rec.index, &sc)?)
                }
                (Collected::Frames(_), d) => return Err(mismatch(d.kind_name(), "Waymo Frame")),
                (Collected::Scenarios(_), d) => return Err(mismatch(d.kind_name(), "WOMD Scenario")),
            }
        }
        if records == 0 {
            return Err(IngestError::Empty { file: file.clone() });
        }
    }
    match collected {
        Collected::Nothing => Ok(Vec::new()),
        Collected::Frames(b) => Ok(vec![b.finish()?]),
        Collected::Scenarios(v) => Ok(v),
    }
}

/// Reads and converts inputs without writing anything (for `inspect`). Scenes are validated
/// (except for file existence).
pub fn read_scenes(inputs: &[PathBuf], expect: Expect, progress: &ProgressBar) -> Result<Vec<Scene>, IngestError> {
    let scenes = convert(inputs, expect, None, progress)?;
    for s in &scenes {
        validate_converted(inputs, s)?;
    }
    Ok(scenes)
}

/// Validates a converted scene's content; a failure names the input it came from (the one input,
/// or the scene's first source file), not the output being written.
fn validate_converted(inputs: &[PathBuf], s: &Scene) -> Result<(), IngestError> {
    scene::validate::validate_scene(s, None).map_err(|(field, message)| {
        let file = match (inputs, s.source.files.first()) {
            ([one], _) => one.clone(),
            (_, Some(f)) => PathBuf::from(f),
            _ => inputs.first().cloned().unwrap_or_default(),
        };
        IngestError::Scene(scene::SceneError::Invalid {
            file,
            field,
            message: format!("{message} (in the scene converted from this input)"),
        })
    })
}

/// A scene written by [`ingest`].
#[derive(Debug)]
pub struct Written {
    pub dir: PathBuf,
    pub scene: Scene,
}

/// Directory name for a scenario id: letters, digits, `_`, `-`, `.` only.
fn safe_dir_name(id: &str) -> Option<&str> {
    let ok =
        !id.is_empty() && id != "." && id != ".." && id.chars().all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c));
    ok.then_some(id)
}

/// What `--force` looks for before replacing an existing `--out`.
const SCENE_MARKER: &str = "scene.json of format carla-gs-scene/1, or only sub-directories holding one";

/// A scene directory, or a directory of scene directories (several WOMD scenarios).
fn is_scene_output(dir: &Path) -> bool {
    let marked = |d: &Path| scene::has_format_marker(d, "scene.json", scene::SCENE_FORMAT);
    if marked(dir) {
        return true;
    }
    let Ok(entries) = std::fs::read_dir(dir) else { return false };
    let entries: Vec<_> = entries.flatten().map(|e| e.path()).collect();
    !entries.is_empty() && entries.iter().all(|p| p.is_dir() && marked(p))
}

/// Converts `inputs` into scene directories under `out`: a Frame segment or a single Scenario
/// becomes the scene `out`; several Scenarios become `out/<scenario_id>/`. Nothing appears at
/// `out` unless every input converted and validated; on failure the folders above `out` that
/// this call created are removed again.
pub fn ingest(
    inputs: &[PathBuf],
    out: &Path,
    expect: Expect,
    overwrite: bool,
    progress: &ProgressBar,
) -> Result<Vec<Written>, IngestError> {
    let missing = missing_parents(out);
    let result = ingest_into(inputs, out, expect, overwrite, progress);
    if result.is_err() {
        for dir in &missing {
            // Only empty folders go (anything another process put there stays); one that was never
            // created is not there to remove.
            match std::fs::remove_dir(dir) {
                Ok(()) => {}
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => {
                    tracing::warn!(dir = %dir.display(), error = %e, "a folder created for the output was not removed");
                    break;
                }
            }
        }
    }
    result
}

/// The folders above `out` that do not exist yet, deepest first.
fn missing_parents(out: &Path) -> Vec<PathBuf> {
    let mut missing = Vec::new();
    let mut dir = out.parent();
    while let Some(d) = dir.filter(|d| !d.as_os_str().is_empty()) {
        // A `..` or `.` step is not a folder this call could create under that name.
        let named = matches!(d.components().next_back(), Some(std::path::Component::Normal(_)));
        if !named || std::fs::symlink_metadata(d).is_ok() {
            break;
        }
        missing.push(d.to_path_buf());
        dir = d.parent();
    }
    missing
}

fn ingest_into(
    inputs: &[PathBuf],
    out: &Path,
    expect: Expect,
    overwrite: bool,
    progress: &ProgressBar,
) -> Result<Vec<Written>, IngestError> {
    scene::check_replaceable(out, overwrite, "a scene directory", SCENE_MARKER, is_scene_output)?;
    let staged = StagedDir::new(out, overwrite)?;
    let scenes = convert(inputs, expect, Some(staged.path()), progress)?;
    if scenes.is_empty() {
        return Err(IngestError::Empty { file: inputs.first().cloned().unwrap_or_default() });
    }
    let single = scenes.len() == 1;
    let mut rel_dirs = Vec::new();
    for s in &scenes {
        let rel = if single {
            PathBuf::new()
        } else {
            let name = safe_dir_name(&s.source.id).ok_or_else(|| {
                IngestError::Scene(scene::SceneError::Invalid {
                    file: PathBuf::from(&s.source.files[0]),
                    field: "scenario_id".into(),
                    message: format!("`{}` cannot name a directory", s.source.id),
                })
            })?;
            PathBuf::from(name)
        };
        if rel_dirs.contains(&rel) {
            return Err(IngestError::Field {
                file: PathBuf::from(&s.source.files[0]),
                field: "scenario_id".into(),
                message: format!(
                    "scenario `{}` appears more than once in the input; give each scenario once",
                    s.source.id
                ),
            });
        }
        validate_converted(inputs, s)?;
        let dir = staged.path().join(&rel);
        std::fs::create_dir_all(&dir).map_err(|e| IngestError::Io { file: dir.clone(), source: e })?;
        scene::write_scene(&dir, s)?;
        rel_dirs.push(rel);
    }
    let out = staged.commit()?;
    Ok(scenes.into_iter().zip(rel_dirs).map(|(scene, rel)| Written { dir: out.join(rel), scene }).collect())
}
