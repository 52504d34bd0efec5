//! PandaSet sequence folders to a scene (`docs/scene-format.md`, "PandaSet").
//!
//! A folder holds `camera/<name>/` (images `NN.jpg`, `intrinsics.json`, `poses.json` =
//! `world_from_camera` in OpenCV axes, `timestamps.json`), `lidar/` (`poses.json` =
//! `world_from_lidar`, `timestamps.json`, sweeps `NN.bin` of f32 x y z intensity in the world
//! frame) and `annotations/cuboids/NN.json.gz` (or `.json`). Every camera folder present (one
//! holding images or camera files) becomes a camera; one that is incomplete or unreadable is
//! refused, never dropped (`camera`). The devkit's own pandas pickles (`.pkl.gz`) are refused
//! with the name of the converter shipped in `tools/`.
//!
//! * **Clock**: frame k is at the LiDAR's time k (the log's frame clock, UNIX seconds); each
//!   image keeps its camera's own time (`ImageRef::timestamp_s`), at which its pose is the ego's
//!   interpolated pose times the rig's `ego_from_camera`.
//! * **Ego**: PandaSet has no vehicle frame; the ego is the LiDAR pose turned so that x points
//!   along the direction the vehicle drives (established in `ego` from the motion, expected +y) and
//!   moved down onto the road (the height measured from the sweeps' ground points), through
//!   `scene::frames::pandaset_lidar_from_ego`. The vehicle is a Chrysler Pacifica.
//! * **Rig**: each camera's fixed `ego_from_camera` is the rotation-averaged (chordal mean) and
//!   translation-averaged `ego_from_world(t_image) * world_from_camera` over all frames; the
//!   largest deviation of a logged camera centre from the rig's is logged and kept in the scene
//!   name's log line (a rigid rig gives centimetres).
//! * **Tracks** from the cuboids (`cuboids`), each box at its frame's time; **LiDAR** sweeps are
//!   stored in the ego frame of their frame, as the scene format wants. Boxes and sweeps hold one
//!   instant, the frame's: a moving car's raw points fill its box best at the frame's time (the
//!   shared-data test), and the images, taken 39 to 61 ms before it, show the car where its box
//!   is at their own times (docs/pandaset.md, "When a box was seen").
//!
//! Every check happens before anything is copied; errors name the file and field. Every input
//! file is checked to be a regular file before it is opened, and one that is there but cannot
//! be used (a directory, FIFO, device, a symbolic link that loops, no permission) is refused,
//! never taken for absent (`crate::input_file`, shared with the other folder readers). The submodules: `files` (reading within budgets
//! and ranges), `ego` (forward axis, LiDAR height), `camera` (camera folders, images, rig),
//! `lidar` (sweeps), `cuboids` and `cuboid_records` (tracks).

pub mod camera;
pub mod cuboid_records;
pub mod cuboids;
pub mod ego;
pub mod files;
pub mod lidar;

pub use ego::MIN_PATH_FOR_AXIS_M;

use crate::error::{content, IngestError};
use files::{presence, read_poses, read_times, stat};
use scene::format::{image_rel_path_ext, IMAGES_DIR, LIDAR_DIR};
use scene::frames::pandaset_lidar_from_ego;
use scene::{Ego, EgoSizeSource, Frame, ImageRef, Scene, Source, SourceKind, SCENE_FORMAT};
use std::path::Path;

/// The converter a PandaSet user runs on the devkit's pickles.
pub const CONVERTER: &str = "tools/pandaset-to-json.py";
/// Chrysler Pacifica (length, width, height), PandaSet's recording vehicle.
pub const PACIFICA_SIZE_LWH: [f64; 3] = [5.17, 2.02, 1.78];

/// True when `dir` looks like a PandaSet sequence folder (something at `lidar/poses.json`: one
/// that is not a usable file is refused by [`read`], naming it).
pub fn looks_like(dir: &Path) -> bool {
    dir.join("camera").is_dir() && crate::input_file::is_there(&dir.join("lidar").join("poses.json"))
}

fn has_ext(dir: &Path, suffix: &str) -> bool {
    std::fs::read_dir(dir)
        .map(|rd| rd.filter_map(|e| e.ok()).any(|e| e.file_name().to_string_lossy().ends_with(suffix)))
        .unwrap_or(false)
}

/// Refuses a folder that holds the devkit's pickles where JSON / binary files are expected.
fn refuse_pickles(dir: &Path) -> Result<(), IngestError> {
    let cub = dir.join("annotations").join("cuboids");
    let lidar = dir.join("lidar");
    let pickled_cuboids = has_ext(&cub, ".pkl.gz") && !has_ext(&cub, ".json.gz") && !has_ext(&cub, ".json");
    let pickled_lidar = has_ext(&lidar, ".pkl.gz") && !has_ext(&lidar, ".bin");
    if pickled_cuboids || pickled_lidar {
        let which = if pickled_cuboids { cub } else { lidar };
        return Err(content(
            which,
            format!(
                "holds the PandaSet devkit's pandas pickles (.pkl.gz), which carla-gs does not unpickle; convert \
                 the sequence once with `python3 {CONVERTER} {}` (needs pandas, which the devkit installs)",
                dir.display()
            ),
        ));
    }
    Ok(())
}

fn empty_scene() -> Scene {
    Scene {
        format: SCENE_FORMAT.into(),
        name: String::new(),
        source: Source { kind: SourceKind::Pandaset, files: Vec::new(), id: String::new() },
        ego: Ego { size_lwh: PACIFICA_SIZE_LWH, size_source: EgoSizeSource::Documented, track_id: None },
        cameras: Vec::new(),
        frames: Vec::new(),
        tracks: Vec::new(),
        map: None,
    }
}

/// Reads a PandaSet folder; with `staging`, copies images and writes LiDAR under it.
pub fn read(dir: &Path, staging: Option<&Path>, progress: &indicatif::ProgressBar) -> Result<Scene, IngestError> {
    refuse_pickles(dir)?;
    let lidar_dir = dir.join("lidar");
    let world_from_lidar = read_poses(&lidar_dir.join("poses.json"))?;
    let lidar_times_file = lidar_dir.join("timestamps.json");
    let lidar_times = read_times(&lidar_times_file)?;
    let n = world_from_lidar.len();
    if lidar_times.len() != n {
        return Err(content(
            &lidar_times_file,
            format!("holds {} times but poses.json holds {n} poses", lidar_times.len()),
        ));
    }
    let forward = ego::forward_axis(&world_from_lidar).map_err(|m| content(lidar_dir.join("poses.json"), m))?;
    let sweeps = lidar::find_sweeps(&lidar_dir, n)?;
    let lidar_above_road = lidar::lidar_above_road(&sweeps, &world_from_lidar, forward)?;
    let lidar_from_ego = pandaset_lidar_from_ego(forward, lidar_above_road);
    let mut frames: Vec<Frame> = (0..n)
        .map(|k| Frame {
            index: k,
            timestamp_s: lidar_times[k],
            world_from_ego: world_from_lidar[k] * lidar_from_ego,
            images: Vec::new(),
            lidar: None,
        })
        .collect();
    let cam_root = dir.join("camera");
    let folders = camera::camera_folders(&cam_root)?;
    if folders.is_empty() {
        return Err(content(&cam_root, "holds no camera folder (camera/<name>/ with images and poses.json)"));
    }
    let cams = folders
        .iter()
        .map(|(name, path)| camera::read_camera(path, name, &frames, &lidar_times))
        .collect::<Result<Vec<_>, _>>()?;
    let cuboid_frames = read_cuboids(dir, n)?;
    let (tracks, report) = cuboids::tracks(&cuboid_frames, &lidar_times);
    tracing::info!(
        records = report.records,
        sibling_duplicates = report.sibling_duplicates,
        refused_sibling_links = report.refused_sibling_links,
        duplicate_uuid_records = report.duplicate_uuid_records,
        tracks = tracks.len(),
        lidar_above_road_m = lidar_above_road,
        "PandaSet cuboids read"
    );
    // Everything is checked: now copy.
    if let Some(root) = staging {
        for sub in [IMAGES_DIR, LIDAR_DIR] {
            let p = root.join(sub);
            std::fs::create_dir_all(&p).map_err(|e| IngestError::Io { file: p, source: e })?;
        }
    }
    progress.set_length((n * cams.len() + sweeps.len()) as u64);
    for c in &cams {
        for (k, src) in c.images.iter().enumerate() {
            let rel = image_rel_path_ext(k, &c.camera.name, "jpg");
            if let Some(root) = staging {
                crate::input_file::copy_regular(src, &root.join(&rel))?;
            }
            frames[k].images.push(ImageRef { camera: c.camera.name.clone(), path: rel, timestamp_s: Some(c.times[k]) });
            progress.inc(1);
        }
    }
    lidar::write_sweeps(&sweeps, &mut frames, staging, progress)?;
    let id = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "pandaset".into());
    let mut files = vec!["lidar/poses.json".to_string(), "lidar/timestamps.json".to_string()];
    files.extend(folders.iter().map(|(n, _)| format!("camera/{n}/poses.json")));
    Ok(Scene {
        name: format!("pandaset-{id}"),
        source: Source { kind: SourceKind::Pandaset, files, id },
        cameras: cams.into_iter().map(|c| c.camera).collect(),
        frames,
        tracks,
        ..empty_scene()
    })
}

/// Per frame, its cuboids (`NN.json.gz` or `NN.json`), within [`cuboids::MAX_CUBOID_RECORDS`] in
/// all. A cuboid folder or file that is there but cannot be used is refused, and so is a frame
/// without a file when other frames have one: its boxes would be silently lost (a sequence without
/// any cuboid file has no tracks, and says so).
fn read_cuboids(dir: &Path, n: usize) -> Result<Vec<Vec<cuboids::Cuboid>>, IngestError> {
    let cub = dir.join("annotations").join("cuboids");
    match stat(&cub)? {
        None => {
            tracing::warn!(dir = %cub.display(), "no cuboid folder: the scene has no tracks");
            return Ok(vec![Vec::new(); n]);
        }
        Some(m) if !m.is_dir() => return Err(content(&cub, "is not a folder; expected the cuboid files NN.json.gz")),
        Some(_) => {}
    }
    let mut out = Vec::with_capacity(n);
    let (mut found, mut records, mut missing) = (0, 0, Vec::new());
    for k in 0..n {
        let mut file = None;
        for name in [format!("{k:02}.json.gz"), format!("{k:02}.json")] {
            let p = cub.join(name);
            if presence(&p)? && file.is_none() {
                file = Some(p);
            }
        }
        match file {
            Some(f) => {
                found += 1;
                let left = cuboids::MAX_CUBOID_RECORDS - records;
                let frame = cuboid_records::parse_frame_within(&f, &files::read_bytes(&f)?, left)?;
                records += frame.len();
                out.push(frame);
            }
            None => {
                missing.push(k);
                out.push(Vec::new())
            }
        }
    }
    if let (true, Some(k)) = (found > 0, missing.first()) {
        return Err(content(
            cub.join(format!("{k:02}.json.gz")),
            format!(
                "missing (nor {k:02}.json), while {found} of the {n} frames have a cuboid file: frame {k} would lose                  every box ({} frame(s) without one)",
                missing.len()
            ),
        ));
    }
    if found == 0 {
        tracing::warn!(dir = %cub.display(), "no cuboid files: the scene has no tracks");
    }
    Ok(out)
}
