//! PandaSet cameras: finding the camera folders under `camera/`, checking each is complete
//! (its name usable as a scene camera name, its three JSON files and every image there, all
//! images of one size within the budgets), and the rig's fixed `ego_from_camera` from the
//! logged camera poses. A camera folder with a fault is refused, naming the input file, never
//! dropped: a scene silently missing a camera would look like a smaller rig.

use super::files::{check_intrinsics, presence, read_intrinsics, read_poses, read_times, stat};
use crate::error::{content, IngestError};
use crate::input_file::image_size;
pub use crate::input_file::MAX_IMAGE_BYTES;
use scene::frames::cv_from_waymo_camera;
use scene::glam::{DMat3, DQuat, DVec3};
use scene::{Camera, Distortion, Frame, Intrinsics, RollingShutter, Transform3};
use std::path::{Path, PathBuf};

/// The JSON files every camera folder needs.
pub const CAMERA_FILES: [&str; 3] = ["intrinsics.json", "poses.json", "timestamps.json"];
/// The camera folders under `cam_root`, sorted by name: every sub-folder (symbolic links
/// followed) that holds images or one of [`CAMERA_FILES`]. Each must have a name a scene camera
/// may have (letters, digits, `_`, `-`) and all of [`CAMERA_FILES`]; a folder that cannot be
/// read is refused with the OS error. Plain files (a README) are not cameras.
pub fn camera_folders(cam_root: &Path) -> Result<Vec<(String, PathBuf)>, IngestError> {
    fn io(p: &Path) -> impl Fn(std::io::Error) -> IngestError + '_ {
        move |e| IngestError::Io { file: p.to_path_buf(), source: e }
    }
    let mut out = Vec::new();
    for e in std::fs::read_dir(cam_root).map_err(io(cam_root))? {
        let path = e.map_err(io(cam_root))?.path();
        if !stat(&path)?.is_some_and(|m| m.is_dir()) {
            continue;
        }
        let mut holds_camera_files = false;
        for f in std::fs::read_dir(&path).map_err(io(&path))? {
            let n = f.map_err(io(&path))?.file_name();
            let n = n.to_string_lossy();
            holds_camera_files |= n.ends_with(".jpg") || CAMERA_FILES.contains(&n.as_ref());
        }
        if !holds_camera_files {
            tracing::warn!(folder = %path.display(), "holds no images and no camera files; not a camera");
            continue;
        }
        let name = path.file_name().and_then(|n| n.to_str()).ok_or_else(|| {
            content(&path, "the folder name is not UTF-8; a camera name is letters, digits, '_' or '-'")
        })?;
        if !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-') {
            return Err(content(
                &path,
                format!("{name:?} cannot name a camera: expected letters, digits, '_' or '-' (rename the folder)"),
            ));
        }
        for f in CAMERA_FILES {
            if !presence(&path.join(f))? {
                return Err(content(path.join(f), format!("missing: camera folder {name} needs {CAMERA_FILES:?}")));
            }
        }
        out.push((name.to_string(), path));
    }
    out.sort();
    Ok(out)
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

pub struct CameraData {
    pub camera: Camera,
    pub times: Vec<f64>,
    pub images: Vec<PathBuf>,
}

pub fn read_camera(dir: &Path, name: &str, frames: &[Frame], lidar_times: &[f64]) -> Result<CameraData, IngestError> {
    let n = frames.len();
    let k_file = dir.join("intrinsics.json");
    let k = read_intrinsics(&k_file)?;
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
    for p in &images {
        if !presence(p)? {
            return Err(content(
                p,
                format!("missing: camera {name} has {n} poses, so every image 00..{} must be there", n - 1),
            ));
        }
    }
    let (width, height) = image_size(&images[0])?;
    scene::camera::check_camera_size(width.into(), height.into()).map_err(|m| content(&images[0], m))?;
    check_intrinsics(&k_file, &k, width, height)?;
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
