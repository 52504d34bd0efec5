//! instant-ngp / nerfstudio `transforms.json` photo sets to a background-only scene.
//!
//! The file gives shared intrinsics (`fl_x`, `fl_y`, `cx`, `cy`, `w`, `h`, OpenCV `k1 k2 k3 p1
//! p2`, or only `camera_angle_x` / `camera_angle_y`), optionally overridden per frame, and per
//! frame a `file_path` and a `transform_matrix` (camera-to-world, OpenGL camera axes x right,
//! y up, z back). Frames are sorted by `file_path` (stable every-n-th held-out splits) and get a
//! **synthetic clock**: frame k is at `k` seconds. Each distinct intrinsics set is one camera
//! (`CAM0`, `CAM1`, ...; usually just `CAM0`) whose `ego_from_camera` is the identity, so
//! `world_from_ego` is the camera pose in Waymo camera axes. Distorted images are undistorted
//! once here (`undistort`, same `K` and size) and written as JPEG at quality
//! [`UNDISTORTED_JPEG_QUALITY`]; undistorted inputs are copied byte for byte. Units are the
//! file's own (instant-ngp scenes are not metric).
//!
//! `transforms.json` and every image it names are opened through `crate::input_file`: a FIFO,
//! device, directory, looping or dangling link, or unreadable file in their place is refused,
//! naming it (never waited on, never taken for a missing image); `transforms.json` is read
//! within `MAX_JSON_BYTES` and images within `MAX_IMAGE_BYTES`, from their sizes before
//! reading, with only the header read where just the size is needed. Each camera's intrinsics
//! are checked for its image size (`camera_check::check_intrinsics`), the error naming the key
//! where it is written (`frames[3].fl_x`, or `camera_angle_x` when the focal length comes from
//! the angle).

use crate::error::{content, IngestError};
use crate::input_file::{copy_regular, decode_image, image_size, is_there, presence, MAX_IMAGE_BYTES};
use crate::undistort::undistort;
use rayon::prelude::*;
use scene::format::{image_rel_path_ext, IMAGES_DIR};
use scene::frames::{waymo_camera_from_opengl_camera, world_from_nerf_world};
use scene::model::DEFAULT_EGO_SIZE_LWH;
use scene::{
    Camera, Distortion, Ego, EgoSizeSource, Frame, ImageRef, Intrinsics, RollingShutter, Scene, Source, SourceKind,
    Transform3, SCENE_FORMAT,
};
use serde::Deserialize;
use std::path::{Path, PathBuf};

pub const FILE_NAME: &str = "transforms.json";
/// JPEG quality of undistorted images (re-encoded once; visually lossless).
pub const UNDISTORTED_JPEG_QUALITY: u8 = 95;

#[derive(Clone, Debug, Default, Deserialize)]
struct Intr {
    camera_model: Option<String>,
    camera_angle_x: Option<f64>,
    camera_angle_y: Option<f64>,
    fl_x: Option<f64>,
    fl_y: Option<f64>,
    cx: Option<f64>,
    cy: Option<f64>,
    w: Option<f64>,
    h: Option<f64>,
    k1: Option<f64>,
    k2: Option<f64>,
    k3: Option<f64>,
    p1: Option<f64>,
    p2: Option<f64>,
}

impl Intr {
    fn over(&self, base: &Intr) -> Intr {
        macro_rules! pick { ($($f:ident),*) => { Intr { $($f: self.$f.clone().or_else(|| base.$f.clone()),)* } } }
        pick!(camera_model, camera_angle_x, camera_angle_y, fl_x, fl_y, cx, cy, w, h, k1, k2, k3, p1, p2)
    }
}

#[derive(Debug, Deserialize)]
struct FrameJson {
    file_path: String,
    transform_matrix: [[f64; 4]; 4],
    #[serde(flatten)]
    intr: Intr,
}

#[derive(Debug, Deserialize)]
struct FileJson {
    #[serde(flatten)]
    intr: Intr,
    frames: Vec<FrameJson>,
}

/// True when `dir` holds something named `transforms.json` (one that is not a usable file is
/// refused by [`read`], naming it).
pub fn looks_like(dir: &Path) -> bool {
    is_there(&dir.join(FILE_NAME))
}

fn field_err(file: &Path, field: String, message: impl Into<String>) -> IngestError {
    IngestError::Field { file: file.to_path_buf(), field, message: message.into() }
}

/// The image a frame names; NeRF-synthetic files omit the extension (`./train/r_0`). `Ok(None)`
/// when nothing is there under any of the names; something there that is not a regular file is
/// refused, naming it (`input_file::presence`), and so is an image past `MAX_IMAGE_BYTES`.
fn resolve_image(dir: &Path, rel: &str) -> Result<Option<PathBuf>, IngestError> {
    let exact = dir.join(rel);
    let candidates =
        std::iter::once(exact).chain(["png", "jpg", "jpeg"].iter().map(|e| dir.join(format!("{rel}.{e}"))));
    for p in candidates {
        if presence(&p)? {
            let len = crate::input_file::stat(&p)?.map_or(0, |m| m.len());
            if len > MAX_IMAGE_BYTES {
                return Err(content(&p, format!("is {len} bytes; an image may have at most {MAX_IMAGE_BYTES} bytes")));
            }
            return Ok(Some(p));
        }
    }
    Ok(None)
}

/// The camera of a frame whose own intrinsics keys are `own` and merged ones (its own over the
/// file's shared ones) `i`; `field` is the frame's prefix (`frames[3].`).
fn camera_of(file: &Path, field: &str, own: &Intr, i: &Intr, image: &Path) -> Result<Camera, IngestError> {
    if let Some(m) = &i.camera_model {
        if !matches!(m.as_str(), "OPENCV" | "PINHOLE" | "SIMPLE_PINHOLE") {
            return Err(field_err(
                file,
                format!("{field}camera_model"),
                format!("`{m}` is not supported (OPENCV or PINHOLE)"),
            ));
        }
    }
    let (w, h) = match (i.w, i.h) {
        (Some(w), Some(h)) => (w, h),
        _ => {
            let (w, h) = image_size(image)?;
            (w as f64, h as f64)
        }
    };
    if !(w >= 1.0 && h >= 1.0 && w.fract() == 0.0 && h.fract() == 0.0) {
        return Err(field_err(
            file,
            format!("{field}w"),
            format!("w and h must be positive whole pixels, got {w} x {h}"),
        ));
    }
    scene::camera::check_camera_size(w.min(u64::MAX as f64) as u64, h.min(u64::MAX as f64) as u64)
        .map_err(|m| field_err(file, format!("{field}w"), m))?;
    let from_angle = |a: Option<f64>, side: f64| {
        a.filter(|a| *a > 0.0 && *a < std::f64::consts::PI).map(|a| 0.5 * side / (0.5 * a).tan())
    };
    let fx = i.fl_x.or_else(|| from_angle(i.camera_angle_x, w)).ok_or_else(|| {
        field_err(file, format!("{field}fl_x"), "missing: need fl_x or camera_angle_x (0 < angle < pi)")
    })?;
    let fy = i.fl_y.or_else(|| from_angle(i.camera_angle_y, h)).unwrap_or(fx);
    let k = Intrinsics { fx, fy, cx: i.cx.unwrap_or(w / 2.0), cy: i.cy.unwrap_or(h / 2.0) };
    let d = Distortion {
        k1: i.k1.unwrap_or(0.0),
        k2: i.k2.unwrap_or(0.0),
        p1: i.p1.unwrap_or(0.0),
        p2: i.p2.unwrap_or(0.0),
        k3: i.k3.unwrap_or(0.0),
    };
    crate::camera_check::check_intrinsics(&k, w as u32, h as u32).map_err(|(name, m)| {
        // The key the value came from, where it is written (the frame's own or the shared one).
        let (key, own) = match name {
            "fx" if i.fl_x.is_none() => ("camera_angle_x", own.camera_angle_x.is_some()),
            "fx" => ("fl_x", own.fl_x.is_some()),
            "fy" if i.fl_y.is_none() && i.camera_angle_y.is_some() => ("camera_angle_y", own.camera_angle_y.is_some()),
            "fy" if i.fl_y.is_none() => ("fl_x", own.fl_x.is_some()),
            "fy" => ("fl_y", own.fl_y.is_some()),
            "cx" => ("cx", own.cx.is_some()),
            _ => ("cy", own.cy.is_some()),
        };
        let at = if own { format!("{field}{key}") } else { key.to_string() };
        field_err(file, at, format!("{m}, for the {w}x{h} image"))
    })?;
    let coeffs = [d.k1, d.k2, d.p1, d.p2, d.k3];
    if coeffs.iter().any(|v| !v.is_finite()) {
        return Err(field_err(file, format!("{field}k1"), "distortion coefficients must be finite"));
    }
    Ok(Camera {
        name: String::new(),
        width: w as u32,
        height: h as u32,
        intrinsics: k,
        distortion: d,
        ego_from_camera: Transform3::IDENTITY,
        rolling_shutter: RollingShutter::Unknown,
    })
}

/// Refuses distortion that makes the undistortion map degenerate, naming the coefficient where
/// it is written (the frame's own or the file's shared one).
fn check_distortion_of(file: &Path, field: &str, own: &Intr, cam: &Camera) -> Result<(), IngestError> {
    let Err(m) = crate::camera_check::check_distortion(&cam.intrinsics, &cam.distortion, cam.width, cam.height) else {
        return Ok(());
    };
    let (name, value) = crate::camera_check::dominant_coefficient(&cam.distortion);
    let set_here = match name {
        "k1" => own.k1,
        "k2" => own.k2,
        "k3" => own.k3,
        "p1" => own.p1,
        _ => own.p2,
    };
    let at = if set_here.is_some() { format!("{field}{name}") } else { name.to_string() };
    Err(field_err(file, at, format!("{name} = {value}: {m}")))
}

/// Writes one image under `staging`: a byte copy when undistorted, else undistorted JPEG.
fn write_image(src: &Path, cam: &Camera, staging: &Path, frame: usize) -> Result<String, IngestError> {
    let lower = src.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let ext = match lower.as_str() {
        "jpg" | "jpeg" => "jpg",
        "png" => "png",
        _ => return Err(content(src, "unsupported image type (expected .jpg, .jpeg or .png)")),
    };
    if cam.distortion.is_zero() {
        let rel = image_rel_path_ext(frame, &cam.name, ext);
        copy_regular(src, &staging.join(&rel))?;
        return Ok(rel);
    }
    let img = decode_image(src)?;
    if (img.width(), img.height()) != (cam.width, cam.height) {
        return Err(content(
            src,
            format!("is {}x{}, transforms.json says {}x{}", img.width(), img.height(), cam.width, cam.height),
        ));
    }
    let grey = matches!(
        img.color(),
        image::ColorType::L8 | image::ColorType::L16 | image::ColorType::La8 | image::ColorType::La16
    );
    let (bytes, channels, colour) = if grey {
        (img.into_luma8().into_raw(), 1, image::ExtendedColorType::L8)
    } else {
        (img.into_rgb8().into_raw(), 3, image::ExtendedColorType::Rgb8)
    };
    let (w, h) = (cam.width as usize, cam.height as usize);
    let out = undistort(&bytes, w, h, channels, &cam.intrinsics, &cam.distortion);
    let mut jpeg = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, UNDISTORTED_JPEG_QUALITY)
        .encode(&out, cam.width, cam.height, colour)
        .map_err(|e| content(src, format!("cannot encode the undistorted JPEG: {e}")))?;
    let rel = image_rel_path_ext(frame, &cam.name, "jpg");
    let dest = staging.join(&rel);
    std::fs::write(&dest, jpeg).map_err(|e| IngestError::Io { file: dest, source: e })?;
    Ok(rel)
}

/// The intrinsics keys read through `#[serde(flatten)]`, where serde cannot say which key failed.
const INTRINSIC_KEYS: [&str; 14] = [
    "camera_model",
    "camera_angle_x",
    "camera_angle_y",
    "fl_x",
    "fl_y",
    "cx",
    "cy",
    "w",
    "h",
    "k1",
    "k2",
    "k3",
    "p1",
    "p2",
];

/// A parse error reported at `.` (inside a flattened struct) names the intrinsics key at fault.
fn name_flattened_field(file: &Path, bytes: &[u8], e: scene::SceneError) -> IngestError {
    let at_root = matches!(&e, scene::SceneError::Json { field, .. } if field == "." || field.is_empty());
    let Some(v) = at_root.then(|| serde_json::from_slice(bytes).ok()).flatten() else {
        return e.into();
    };
    let v: serde_json::Value = v;
    let bad = |obj: &serde_json::Value, at: &str| {
        INTRINSIC_KEYS.iter().find_map(|k| {
            let x = obj.get(*k)?;
            let fine = if *k == "camera_model" { x.is_string() } else { x.is_number() };
            (!fine && !x.is_null()).then(|| {
                field_err(
                    file,
                    format!("{at}{k}"),
                    format!("expected a {}, got {x}", if *k == "camera_model" { "string" } else { "number" }),
                )
            })
        })
    };
    let frames = v.get("frames").and_then(|f| f.as_array()).cloned().unwrap_or_default();
    bad(&v, "")
        .or_else(|| frames.iter().enumerate().find_map(|(i, f)| bad(f, &format!("frames[{i}]."))))
        .unwrap_or_else(|| e.into())
}

/// Reads `dir/transforms.json`; with `staging`, writes the (undistorted) images under it.
pub fn read(dir: &Path, staging: Option<&Path>, progress: &indicatif::ProgressBar) -> Result<Scene, IngestError> {
    let file = dir.join(FILE_NAME);
    let bytes = crate::input_file::read_capped(&file, crate::input_file::MAX_JSON_BYTES, "transforms.json")?;
    let de = &mut serde_json::Deserializer::from_slice(&bytes);
    let parsed: FileJson = serde_path_to_error::deserialize(de).map_err(|e| {
        let e =
            scene::SceneError::Json { file: file.clone(), field: e.path().to_string(), message: e.inner().to_string() };
        name_flattened_field(&file, &bytes, e)
    })?;
    if parsed.frames.is_empty() {
        return Err(field_err(&file, "frames".into(), "no frames"));
    }
    let mut order: Vec<usize> = (0..parsed.frames.len()).collect();
    order.sort_by(|a, b| parsed.frames[*a].file_path.cmp(&parsed.frames[*b].file_path));
    let opengl_from_waymo = waymo_camera_from_opengl_camera().inverse();
    let mut cameras: Vec<Camera> = Vec::new();
    let mut pending = Vec::new();
    for (k, &j) in order.iter().enumerate() {
        let f = &parsed.frames[j];
        let field = format!("frames[{j}].");
        let src = resolve_image(dir, &f.file_path)?.ok_or_else(|| {
            content(dir.join(&f.file_path), format!("missing (named by `{field}file_path` of {})", file.display()))
        })?;
        let mut cam = camera_of(&file, &field, &f.intr, &f.intr.over(&parsed.intr), &src)?;
        check_distortion_of(&file, &field, &f.intr, &cam)?;
        let same = |c: &Camera| {
            (c.width, c.height, c.intrinsics, c.distortion) == (cam.width, cam.height, cam.intrinsics, cam.distortion)
        };
        cam.name = match cameras.iter().find(|c| same(c)) {
            Some(c) => c.name.clone(),
            None => {
                cam.name = format!("CAM{}", cameras.len());
                cameras.push(cam.clone());
                cam.name.clone()
            }
        };
        let mut m = f.transform_matrix;
        if m[3] != [0.0, 0.0, 0.0, 1.0] {
            m[3] = [0.0, 0.0, 0.0, 1.0];
            if f.transform_matrix[3].iter().zip([0.0, 0.0, 0.0, 1.0]).any(|(a, b)| (a - b).abs() > 1e-9) {
                return Err(field_err(&file, format!("{field}transform_matrix"), "last row must be 0 0 0 1"));
            }
        }
        let world_from_gl = Transform3::from_row_major(&m)
            .filter(|t| t.is_finite() && t.orthonormality_error() <= 1e-3 && t.rotation().determinant() > 0.0)
            .ok_or_else(|| {
                field_err(
                    &file,
                    format!("{field}transform_matrix"),
                    "not a rigid camera-to-world transform (rotation orthonormal to 1e-3)",
                )
            })?;
        let world_from_ego = world_from_nerf_world() * world_from_gl * opengl_from_waymo;
        pending.push((k, src, cam, world_from_ego));
    }
    if let Some(root) = staging {
        let p = root.join(IMAGES_DIR);
        std::fs::create_dir_all(&p).map_err(|e| IngestError::Io { file: p, source: e })?;
    }
    progress.set_length(pending.len() as u64);
    let rels: Vec<String> = pending
        .par_iter()
        .map(|(k, src, cam, _)| {
            let rel = match staging {
                Some(root) => write_image(src, cam, root, *k)?,
                None => image_rel_path_ext(*k, &cam.name, "jpg"),
            };
            progress.inc(1);
            Ok(rel)
        })
        .collect::<Result<_, IngestError>>()?;
    let frames = pending
        .into_iter()
        .zip(rels)
        .map(|((k, _, cam, world_from_ego), path)| Frame {
            index: k,
            timestamp_s: k as f64,
            world_from_ego,
            images: vec![ImageRef::at_frame_time(cam.name, path)],
            lidar: None,
        })
        .collect();
    for c in &mut cameras {
        c.distortion = Distortion::default();
    }
    let id = dir.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "transforms".into());
    Ok(Scene {
        format: SCENE_FORMAT.into(),
        name: id.clone(),
        source: Source { kind: SourceKind::TransformsJson, files: vec![FILE_NAME.into()], id },
        ego: Ego { size_lwh: DEFAULT_EGO_SIZE_LWH, size_source: EgoSizeSource::Default, track_id: None },
        cameras,
        frames,
        tracks: Vec::new(),
        map: None,
    })
}
