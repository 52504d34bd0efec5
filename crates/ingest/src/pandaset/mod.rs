//! PandaSet sequence folders to a scene (`docs/scene-format.md`, "PandaSet").
//!
//! A folder holds `camera/<name>/` (images `NN.jpg`, `intrinsics.json`, `poses.json` =
//! `world_from_camera` in OpenCV axes, `timestamps.json`), `lidar/` (`poses.json` =
//! `world_from_lidar`, `timestamps.json`, sweeps `NN.bin` of f32 x y z intensity in the world
//! frame) and `annotations/cuboids/NN.json.gz` (or `.json`). Every camera folder present becomes
//! a camera. The devkit's own pandas pickles (`.pkl.gz`) are refused with the name of the
//! converter shipped in `tools/`.
//!
//! * **Clock**: frame k is at the LiDAR's time k (the log's frame clock, UNIX seconds); each
//!   image keeps its camera's own time (`ImageRef::timestamp_s`), at which its pose is the ego's
//!   interpolated pose times the rig's `ego_from_camera`.
//! * **Ego**: PandaSet has no vehicle frame; the ego is the LiDAR pose turned so that x points
//!   along the direction the vehicle drives (established here from the motion, expected +y) and
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
//! Every check happens before anything is copied; errors name the file and field.

pub mod cuboids;
pub mod files;

use crate::error::{content, IngestError};
use files::{read_intrinsics, read_poses, read_sweep, read_times};
use scene::format::{image_rel_path_ext, lidar_rel_path, IMAGES_DIR, LIDAR_DIR};
use scene::frames::{cv_from_waymo_camera, pandaset_lidar_from_ego, PANDASET_LIDAR_FORWARD};
use scene::glam::{DMat3, DQuat, DVec3};
use scene::{
    Camera, Distortion, Ego, EgoSizeSource, Frame, ImageRef, Intrinsics, LidarRef, RollingShutter, Scene, Source,
    SourceKind, Transform3, SCENE_FORMAT,
};
use std::path::{Path, PathBuf};

/// The converter a PandaSet user runs on the devkit's pickles.
pub const CONVERTER: &str = "tools/pandaset-to-json.py";
/// Chrysler Pacifica (length, width, height), PandaSet's recording vehicle.
pub const PACIFICA_SIZE_LWH: [f64; 3] = [5.17, 2.02, 1.78];
/// Below this much driving (m) the forward axis cannot be told from the motion.
pub const MIN_PATH_FOR_AXIS_M: f64 = 1.0;

/// True when `dir` looks like a PandaSet sequence folder.
pub fn looks_like(dir: &Path) -> bool {
    dir.join("camera").is_dir() && dir.join("lidar").join("poses.json").is_file()
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

/// The vehicle's forward axis in the LiDAR frame, from the motion (nearest of +-x, +-y).
fn forward_axis(world_from_lidar: &[Transform3]) -> Result<DVec3, String> {
    let mut sum = DVec3::ZERO;
    let mut path = 0.0;
    for w in world_from_lidar.windows(2) {
        let d = w[1].translation() - w[0].translation();
        if d.length() > 0.02 {
            sum += w[0].inverse().transform_vector(d).normalize();
            path += d.length();
        }
    }
    if path < MIN_PATH_FOR_AXIS_M {
        tracing::warn!(path_m = path, "the ego barely moves; taking PandaSet's documented forward axis (+y)");
        return Ok(PANDASET_LIDAR_FORWARD);
    }
    let mean = DVec3::new(sum.x, sum.y, 0.0).normalize();
    let axes = [DVec3::X, DVec3::NEG_X, DVec3::Y, DVec3::NEG_Y];
    let best = axes.into_iter().max_by(|a, b| a.dot(mean).total_cmp(&b.dot(mean))).unwrap_or(DVec3::Y);
    if best.dot(mean) < 30f64.to_radians().cos() {
        return Err(format!("the ego's mean motion {mean:.3} (LiDAR frame) runs along no LiDAR axis"));
    }
    if best != PANDASET_LIDAR_FORWARD {
        tracing::warn!(axis = %best, "the ego drives along a LiDAR axis other than PandaSet's usual +y");
    }
    Ok(best)
}

/// Height of the LiDAR pose's origin above the road in one sweep: the mode (5 cm bins) of the
/// heights of the points within 3 m sideways and 15 m along the forward axis.
fn lidar_height_in(points_lidar: &[DVec3], forward: DVec3) -> Option<f64> {
    let side = DVec3::Z.cross(forward);
    let mut bins = vec![0usize; 100]; // -4.0 .. +1.0 m
    for p in points_lidar {
        if p.dot(forward).abs() < 15.0 && p.dot(side).abs() < 3.0 && p.z > -4.0 && p.z < 1.0 {
            bins[((p.z + 4.0) / 0.05) as usize] += 1;
        }
    }
    let (i, n) = bins.iter().enumerate().max_by_key(|(_, n)| **n)?;
    (*n >= 50).then(|| -(-4.0 + (i as f64 + 0.5) * 0.05))
}

/// Frames (index, file) that have a sweep `NN.bin`.
fn sweep_files(lidar_dir: &Path, n: usize) -> Vec<(usize, PathBuf)> {
    (0..n).map(|k| (k, lidar_dir.join(format!("{k:02}.bin")))).filter(|(_, p)| p.is_file()).collect()
}

/// The rig's `ego_from_camera` (Waymo camera axes) from per-frame estimates, and the largest
/// distance of an estimate's origin from the mean (m).
fn rig_mean(estimates: &[Transform3]) -> (Transform3, f64) {
    let n = estimates.len().max(1) as f64;
    let t = estimates.iter().map(|e| e.translation()).sum::<DVec3>() / n;
    let m: DMat3 = estimates.iter().fold(DMat3::ZERO, |acc, e| acc + e.rotation()) * (1.0 / n);
    // Chordal mean: the nearest rotation to the mean matrix, through the quaternion of its
    // (near-orthonormal) value, re-normalised.
    let q = DQuat::from_mat3(&m).normalize();
    let spread = estimates.iter().map(|e| (e.translation() - t).length()).fold(0.0, f64::max);
    (Transform3::from_rotation_translation(DMat3::from_quat(q), t), spread)
}

struct CameraData {
    camera: Camera,
    times: Vec<f64>,
    images: Vec<PathBuf>,
}

fn image_size(path: &Path) -> Result<(u32, u32), IngestError> {
    image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| IngestError::Io { file: path.to_path_buf(), source: e })?
        .into_dimensions()
        .map_err(|e| content(path, format!("not a readable image: {e}")))
}

fn read_camera(dir: &Path, name: &str, frames: &[Frame], lidar_times: &[f64]) -> Result<CameraData, IngestError> {
    let n = frames.len();
    let k = read_intrinsics(&dir.join("intrinsics.json"))?;
    let poses_file = dir.join("poses.json");
    let poses = read_poses(&poses_file)?;
    let times_file = dir.join("timestamps.json");
    let times = read_times(&times_file)?;
    for (file, got) in [(&poses_file, poses.len()), (&times_file, times.len())] {
        if got != n {
            return Err(content(file, format!("holds {got} entries but the LiDAR has {n} frames")));
        }
    }
    if let Some(i) = (0..n).find(|&i| (times[i] - lidar_times[i]).abs() > 0.5) {
        return Err(IngestError::Field {
            file: times_file,
            field: format!("[{i}]"),
            message: format!("{} s is more than 0.5 s from the LiDAR's frame time {} s", times[i], lidar_times[i]),
        });
    }
    let images: Vec<PathBuf> = (0..n).map(|i| dir.join(format!("{i:02}.jpg"))).collect();
    if let Some(missing) = images.iter().find(|p| !p.is_file()) {
        return Err(content(
            missing,
            format!("missing: camera {name} has {n} poses, so every image 00..{} must be there", n - 1),
        ));
    }
    let (width, height) = image_size(&images[0])?;
    for p in &images[1..] {
        let size = image_size(p)?;
        if size != (width, height) {
            return Err(content(
                p,
                format!("is {}x{}, expected {width}x{height} like {}", size.0, size.1, images[0].display()),
            ));
        }
    }
    let estimates: Vec<Transform3> = (0..n)
        .map(|i| scene::model::world_from_ego_at(frames, times[i]).inverse() * poses[i] * cv_from_waymo_camera())
        .collect();
    let (ego_from_camera, spread) = rig_mean(&estimates);
    tracing::info!(camera = name, spread_m = spread, "camera rig from the logged camera poses");
    if spread > 0.25 {
        tracing::warn!(camera = name, spread_m = spread, "logged camera poses stray from a rigid rig by > 0.25 m");
    }
    let camera = Camera {
        name: name.to_string(),
        width,
        height,
        intrinsics: Intrinsics { fx: k.fx, fy: k.fy, cx: k.cx, cy: k.cy },
        distortion: Distortion::default(),
        ego_from_camera,
        rolling_shutter: RollingShutter::Unknown,
    };
    Ok(CameraData { camera, times, images })
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
    let forward = forward_axis(&world_from_lidar).map_err(|m| content(lidar_dir.join("poses.json"), m))?;
    let sweeps = sweep_files(&lidar_dir, n);
    let mut heights = Vec::new();
    let mut sweep_points = Vec::new();
    for (k, file) in &sweeps {
        let pts = read_sweep(file)?;
        let lidar_from_world = world_from_lidar[*k].inverse();
        let local: Vec<DVec3> = pts
            .iter()
            .map(|p| lidar_from_world.transform_point(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64)))
            .collect();
        heights.extend(lidar_height_in(&local, forward));
        sweep_points.push((*k, pts));
    }
    heights.sort_by(f64::total_cmp);
    let lidar_above_road = heights.get(heights.len() / 2).copied().unwrap_or_else(|| {
        tracing::warn!("no LiDAR ground found; the ego origin stays at the LiDAR pose's height");
        0.0
    });
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
    let rd = std::fs::read_dir(&cam_root).map_err(|e| IngestError::Io { file: cam_root.clone(), source: e })?;
    let mut names: Vec<String> = rd
        .filter_map(|e| e.ok())
        .filter(|e| e.path().join("poses.json").is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    if names.is_empty() {
        return Err(content(&cam_root, "holds no camera folder (camera/<name>/ with poses.json)"));
    }
    let cams = names
        .iter()
        .map(|name| read_camera(&cam_root.join(name), name, &frames, &lidar_times))
        .collect::<Result<Vec<_>, _>>()?;
    let cuboid_frames = read_cuboids(dir, n)?;
    let (tracks, report) = cuboids::tracks(&cuboid_frames, &lidar_times);
    tracing::info!(
        records = report.records,
        sibling_duplicates = report.sibling_duplicates,
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
    progress.set_length((n * cams.len() + sweep_points.len()) as u64);
    for c in &cams {
        for (k, src) in c.images.iter().enumerate() {
            let rel = image_rel_path_ext(k, &c.camera.name, "jpg");
            if let Some(root) = staging {
                std::fs::copy(src, root.join(&rel)).map_err(|e| IngestError::Io { file: src.clone(), source: e })?;
            }
            frames[k].images.push(ImageRef { camera: c.camera.name.clone(), path: rel, timestamp_s: Some(c.times[k]) });
            progress.inc(1);
        }
    }
    for (k, pts) in &sweep_points {
        let ego_from_world = frames[*k].world_from_ego.inverse();
        let ego: Vec<[f32; 4]> = pts
            .iter()
            .map(|p| {
                let q = ego_from_world.transform_point(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
                [q.x as f32, q.y as f32, q.z as f32, p[3]]
            })
            .collect();
        let rel = lidar_rel_path(*k);
        if let Some(root) = staging {
            scene::format::write_lidar(&root.join(&rel), &ego)?;
        }
        frames[*k].lidar = Some(LidarRef { path: rel, points: ego.len() });
        progress.inc(1);
    }
    let id = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "pandaset".into());
    let mut files = vec!["lidar/poses.json".to_string(), "lidar/timestamps.json".to_string()];
    files.extend(names.iter().map(|n| format!("camera/{n}/poses.json")));
    Ok(Scene {
        name: format!("pandaset-{id}"),
        source: Source { kind: SourceKind::Pandaset, files, id },
        cameras: cams.into_iter().map(|c| c.camera).collect(),
        frames,
        tracks,
        ..empty_scene()
    })
}

/// Per frame, its cuboids (`NN.json.gz` or `NN.json`; a frame without a file has none).
fn read_cuboids(dir: &Path, n: usize) -> Result<Vec<Vec<cuboids::Cuboid>>, IngestError> {
    let cub = dir.join("annotations").join("cuboids");
    let mut out = Vec::with_capacity(n);
    let mut found = 0;
    for k in 0..n {
        let file =
            [format!("{k:02}.json.gz"), format!("{k:02}.json")].map(|f| cub.join(f)).into_iter().find(|p| p.is_file());
        match file {
            Some(f) => {
                found += 1;
                out.push(cuboids::parse_frame(&f, &files::read_bytes(&f)?)?);
            }
            None => out.push(Vec::new()),
        }
    }
    if found == 0 {
        tracing::warn!(dir = %cub.display(), "no cuboid files: the scene has no tracks");
    }
    Ok(out)
}
