//! KITTI odometry sequence folders to a scene (`docs/scene-format.md`, "KITTI odometry").
//!
//! A folder holds `image_0/` and `image_1/` (rectified left and right grey PNGs named by the
//! source frame number), `calib.txt` (the row-major 3x4 projections `P0` and `P1`, with or
//! without `P0:` labels), `poses.txt` (line k: row-major 3x4 `world_from_left_camera` of the k-th
//! image in name order, KITTI world = left camera at frame 0, OpenCV axes) and `times.txt` (s).
//! The scene gets two cameras, `LEFT` and `RIGHT`, an ego pose per image and no tracks.
//!
//! Frames: the ego origin sits on the road `KITTI_CAMERA_HEIGHT_M` (1.65 m) below the left
//! camera, axes parallel to the left camera's (x forward, y left, z up); the world is KITTI's
//! turned z-up with its origin on the road below the frame-0 camera (`scene::frames`). The PNG
//! bytes are copied unchanged (grey stays grey).
//!
//! Every input file is opened through `crate::input_file`: a FIFO, device, directory, looping
//! or dangling link, or unreadable file where a text file or image is expected is refused,
//! naming it (never waited on); the text files are read within `MAX_TEXT_BYTES` and images
//! within `MAX_IMAGE_BYTES`, from their sizes before reading, and only the image headers are read
//! for the sizes. The intrinsics of `P0` are checked for the image size
//! (`camera_check::check_intrinsics`). KITTI's `velodyne/` sweeps are not read.

use crate::error::{content, IngestError};
use crate::input_file::{copy_regular, image_size, is_there, read_text};
use scene::format::{image_rel_path_ext, IMAGES_DIR};
use scene::frames::{waymo_camera_from_kitti_camera, world_from_kitti_world, KITTI_CAMERA_HEIGHT_M};
use scene::glam::{DMat3, DVec3};
use scene::model::DEFAULT_EGO_SIZE_LWH;
use scene::{
    Camera, Distortion, Ego, EgoSizeSource, Frame, ImageRef, Intrinsics, RollingShutter, Scene, Source, SourceKind,
    Transform3, SCENE_FORMAT,
};
use std::path::Path;

pub const LEFT: &str = "LEFT";
pub const RIGHT: &str = "RIGHT";

/// True when `dir` looks like a KITTI odometry sequence folder: something at `calib.txt` and
/// `poses.txt` (one that is not a usable file is refused by [`read`], naming it) and an
/// `image_0/` folder.
pub fn looks_like(dir: &Path) -> bool {
    is_there(&dir.join("calib.txt")) && is_there(&dir.join("poses.txt")) && dir.join("image_0").is_dir()
}

/// One non-empty line of numbers: 1-based line number, optional `label:` prefix, the values.
type NumericLine = (usize, Option<String>, Vec<f64>);

/// Non-empty lines of a text file, each checked to hold `n` numbers.
fn numeric_lines(file: &Path, n: usize, what: &str) -> Result<Vec<NumericLine>, IngestError> {
    let text = read_text(file)?;
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let mut words: Vec<&str> = line.split_whitespace().collect();
        if words.is_empty() {
            continue;
        }
        let label = words[0].strip_suffix(':').map(|l| l.to_string());
        if label.is_some() {
            words.remove(0);
        }
        let bad = |message: String| IngestError::Line { file: file.to_path_buf(), line: i + 1, message };
        let values = words
            .iter()
            .map(|w| {
                w.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| bad(format!("`{w}` is not a finite number")))
            })
            .collect::<Result<Vec<f64>, _>>()?;
        if values.len() != n {
            return Err(bad(format!("expected {n} numbers ({what}), got {}", values.len())));
        }
        out.push((i + 1, label, values));
    }
    Ok(out)
}

/// The rectified stereo calibration: shared intrinsics and the baseline (m, right of the left camera).
struct Calib {
    k: Intrinsics,
    baseline_m: f64,
    /// The line of `P0` in `calib.txt`.
    p0_line: usize,
}

/// Refuses `P0`'s intrinsics when implausible for the `width` x `height` images
/// (`camera_check::check_intrinsics`), naming `file`, the line, the matrix entry, its value and
/// the allowed range.
fn check_calib_intrinsics(file: &Path, calib: &Calib, width: u32, height: u32) -> Result<(), IngestError> {
    crate::camera_check::check_intrinsics(&calib.k, width, height).map_err(|(field, m)| {
        let entry = match field {
            "fx" => "P0[0][0]",
            "fy" => "P0[1][1]",
            "cx" => "P0[0][2]",
            _ => "P0[1][2]",
        };
        IngestError::Line {
            file: file.to_path_buf(),
            line: calib.p0_line,
            message: format!("{entry}: {m}, for the {width}x{height} images"),
        }
    })
}

fn read_calib(file: &Path) -> Result<Calib, IngestError> {
    let lines = numeric_lines(file, 12, "a row-major 3x4 projection matrix")?;
    let pick = |label: &str, pos: usize| {
        let labelled = lines.iter().find(|l| l.1.as_deref() == Some(label));
        labelled.or_else(|| lines.iter().filter(|l| l.1.is_none()).nth(pos)).ok_or_else(|| IngestError::Line {
            file: file.to_path_buf(),
            line: lines.len() + 1,
            message: format!("missing the projection {label} (expected a line of 12 numbers)"),
        })
    };
    let (l0, _, p0) = pick("P0", 0)?;
    let (l1, _, p1) = pick("P1", 1)?;
    let bad = |line: &usize, message: String| IngestError::Line { file: file.to_path_buf(), line: *line, message };
    let k = Intrinsics { fx: p0[0], fy: p0[5], cx: p0[2], cy: p0[6] };
    if k.fx <= 0.0 || k.fy <= 0.0 || p0[1].abs() > 1e-9 || p0[4].abs() > 1e-9 || p0[8..11] != [0.0, 0.0, 1.0] {
        return Err(bad(l0, "P0 is not a rectified pinhole projection [fx 0 cx 0; 0 fy cy 0; 0 0 1 0]".into()));
    }
    if [p0[3], p0[7], p0[11]].iter().any(|v| v.abs() > 1e-9) {
        return Err(bad(l0, "P0 must have a zero last column (it defines the left camera)".into()));
    }
    let same = [0, 1, 2, 4, 5, 6, 8, 9, 10].iter().all(|&i| (p0[i] - p1[i]).abs() <= 1e-6 * p0[i].abs().max(1.0));
    if !same || p1[7].abs() > 1e-6 || p1[11].abs() > 1e-6 {
        return Err(bad(
            l1,
            "P1 must share P0's intrinsics and differ only by -fx*baseline in row 1 (a rectified pair)".into(),
        ));
    }
    let baseline_m = -p1[3] / k.fx;
    if baseline_m <= 0.0 {
        return Err(bad(
            l1,
            format!("P1[0][3] = {} gives a baseline of {baseline_m} m (the right camera must be at +x)", p1[3]),
        ));
    }
    Ok(Calib { k, baseline_m, p0_line: *l0 })
}

fn png_names(dir: &Path) -> Result<Vec<String>, IngestError> {
    let rd = std::fs::read_dir(dir).map_err(|e| IngestError::Io { file: dir.to_path_buf(), source: e })?;
    let mut names = Vec::new();
    for e in rd {
        let n = e.map_err(|e| IngestError::Io { file: dir.to_path_buf(), source: e })?.file_name();
        let n = n.to_string_lossy().into_owned();
        if n.to_ascii_lowercase().ends_with(".png") {
            names.push(n);
        }
    }
    names.sort();
    Ok(names)
}

/// A PNG's width and height from its header (`input_file::image_size`).
fn png_size(path: &Path) -> Result<(u32, u32), IngestError> {
    image_size(path).map_err(|e| match e {
        IngestError::Content { file, message } if message.starts_with("not a readable image") => {
            content(file, message.replacen("not a readable image", "not a readable PNG image", 1))
        }
        other => other,
    })
}

/// Reads a KITTI odometry folder; with `staging`, copies the images under it.
pub fn read(dir: &Path, staging: Option<&Path>, progress: &indicatif::ProgressBar) -> Result<Scene, IngestError> {
    let calib_file = dir.join("calib.txt");
    let calib = read_calib(&calib_file)?;
    let (left_dir, right_dir) = (dir.join("image_0"), dir.join("image_1"));
    let names = png_names(&left_dir)?;
    if names.is_empty() {
        return Err(content(&left_dir, "no PNG images"));
    }
    let right_names = png_names(&right_dir)?;
    for n in &names {
        if right_names.binary_search(n).is_err() {
            return Err(content(right_dir.join(n), "missing (image_0 has this frame; stereo pairs must match)"));
        }
    }
    if let Some(extra) = right_names.iter().find(|n| names.binary_search(n).is_err()) {
        return Err(content(left_dir.join(extra), "missing (image_1 has this frame; stereo pairs must match)"));
    }
    let poses_file = dir.join("poses.txt");
    let poses = numeric_lines(&poses_file, 12, "a row-major 3x4 [R|t] world_from_left_camera")?;
    if poses.len() != names.len() {
        return Err(content(
            &poses_file,
            format!("holds {} poses but image_0 holds {} images", poses.len(), names.len()),
        ));
    }
    let times_file = dir.join("times.txt");
    let times = numeric_lines(&times_file, 1, "a time in seconds")?;
    if times.len() != names.len() {
        return Err(content(
            &times_file,
            format!("holds {} times but image_0 holds {} images", times.len(), names.len()),
        ));
    }
    for w in times.windows(2) {
        if w[1].2[0] <= w[0].2[0] {
            return Err(IngestError::Line {
                file: times_file.clone(),
                line: w[1].0,
                message: format!("time {} s is not after the previous {} s", w[1].2[0], w[0].2[0]),
            });
        }
    }
    let (width, height) = png_size(&left_dir.join(&names[0]))?;
    scene::camera::check_camera_size(width.into(), height.into()).map_err(|m| content(left_dir.join(&names[0]), m))?;
    check_calib_intrinsics(&calib_file, &calib, width, height)?;
    let h = KITTI_CAMERA_HEIGHT_M;
    let camera = |name: &str, y: f64| Camera {
        name: name.into(),
        width,
        height,
        intrinsics: calib.k,
        distortion: Distortion::default(),
        // Waymo camera axes are parallel to the ego's; the right camera is `baseline` to the right (-y).
        ego_from_camera: Transform3::from_rotation_translation(DMat3::IDENTITY, DVec3::new(0.0, y, h)),
        rolling_shutter: RollingShutter::GlobalShutter,
    };
    let cameras = vec![camera(LEFT, 0.0), camera(RIGHT, -calib.baseline_m)];
    let left_from_ego = cameras[0].ego_from_camera.inverse();
    let world_from_kitti = world_from_kitti_world(h);
    let kitti_cam_from_waymo_cam = waymo_camera_from_kitti_camera().inverse();
    if let Some(root) = staging {
        let p = root.join(IMAGES_DIR);
        std::fs::create_dir_all(&p).map_err(|e| IngestError::Io { file: p, source: e })?;
    }
    progress.set_length(names.len() as u64);
    let mut frames = Vec::with_capacity(names.len());
    for (i, name) in names.iter().enumerate() {
        let (line, _, v) = &poses[i];
        let kitti_world_from_left = Transform3::from_row_major(&[
            [v[0], v[1], v[2], v[3]],
            [v[4], v[5], v[6], v[7]],
            [v[8], v[9], v[10], v[11]],
            [0.0, 0.0, 0.0, 1.0],
        ])
        .filter(|t| {
            t.orthonormality_error() <= scene::transform::ORTHONORMAL_TOLERANCE && t.rotation().determinant() > 0.0
        })
        .ok_or_else(|| IngestError::Line {
            file: poses_file.clone(),
            line: *line,
            message: "the 3x3 block is not a rotation (orthonormal to 1e-3, determinant +1)".into(),
        })?;
        let world_from_ego = world_from_kitti * kitti_world_from_left * kitti_cam_from_waymo_cam * left_from_ego;
        let mut images = Vec::new();
        for (cam, src_dir) in [(LEFT, &left_dir), (RIGHT, &right_dir)] {
            let src = src_dir.join(name);
            let size = png_size(&src)?;
            if size != (width, height) {
                return Err(content(
                    &src,
                    format!("is {}x{}, expected {width}x{height} like the first image", size.0, size.1),
                ));
            }
            let rel = image_rel_path_ext(i, cam, "png");
            if let Some(root) = staging {
                copy_regular(&src, &root.join(&rel))?;
            }
            images.push(ImageRef::at_frame_time(cam, rel));
        }
        frames.push(Frame { index: i, timestamp_s: times[i].2[0], world_from_ego, images, lidar: None });
        progress.inc(1);
    }
    let id = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "kitti".into());
    tracing::info!(frames = frames.len(), baseline_m = calib.baseline_m, "KITTI odometry folder read");
    Ok(Scene {
        format: SCENE_FORMAT.into(),
        name: id.clone(),
        source: Source {
            kind: SourceKind::KittiOdometry,
            files: vec!["calib.txt".into(), "poses.txt".into(), "times.txt".into()],
            id,
        },
        ego: Ego { size_lwh: DEFAULT_EGO_SIZE_LWH, size_source: EgoSizeSource::Default, track_id: None },
        cameras,
        frames,
        tracks: Vec::new(),
        map: None,
    })
}
