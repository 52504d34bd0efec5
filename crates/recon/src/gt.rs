//! Reading the exact ground truth of synthetic scenes (`<scene>/gt/`, format in
//! docs/scene-format.md) at a view's size: camera-frame normals (converted from Waymo camera axes
//! to the rasterizer's OpenCV axes) and instance ids with their track ids. Maps are sampled at the
//! full-size pixel nearest to each view pixel's centre (no blending across edges).

use crate::error::ReconError;
use serde::Deserialize;
use std::io::Read;
use std::path::Path;

#[derive(Deserialize)]
struct Instance {
    instance: u16,
    track_id: String,
}

#[derive(Deserialize)]
struct Index {
    instances: Vec<Instance>,
}

/// Ground truth of one view at the view's size.
pub struct GroundTruth {
    /// Unit normals in OpenCV camera axes; `[0, 0, 0]` for sky.
    pub normal: Vec<[f64; 3]>,
    /// Track id of the vehicle at each pixel, if any.
    pub track: Vec<Option<usize>>,
    /// Track ids, indexed by the values of `track`.
    pub track_ids: Vec<String>,
}

/// The gzip file at `path` inflated, refused unless it is a regular file inflating to exactly
/// `expected` bytes (at most `expected + 1` are inflated: a gzip bomb is refused, not followed).
fn gunzip(path: &Path, expected: usize) -> Result<Vec<u8>, ReconError> {
    let bad = |detail: String| ReconError::Format { file: path.to_path_buf(), detail };
    if !std::fs::metadata(path).map_err(crate::error::io(path))?.is_file() {
        return Err(bad("is not a regular file".into()));
    }
    let f = std::fs::File::open(path).map_err(crate::error::io(path))?;
    let mut out = Vec::new();
    flate2::read::GzDecoder::new(f).take(expected as u64 + 1).read_to_end(&mut out).map_err(crate::error::io(path))?;
    if out.len() != expected {
        let got = if out.len() > expected { format!("more than {expected}") } else { out.len().to_string() };
        return Err(bad(format!("{got} bytes, expected {expected}")));
    }
    Ok(out)
}

/// Nearest-pixel resampling of a `sw x sh` map to `w x h` (each output pixel takes the source
/// pixel under its centre; no blending across edges).
pub fn resample<T: Copy>(src: &[T], sw: usize, sh: usize, w: usize, h: usize) -> Vec<T> {
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let sx = (((x as f64 + 0.5) * sw as f64 / w as f64) as usize).min(sw - 1);
            let sy = (((y as f64 + 0.5) * sh as f64 / h as f64) as usize).min(sh - 1);
            src[sy * sw + sx]
        })
        .collect()
}

/// The ground truth of `(frame, camera)` at `w x h`, or `None` when the scene has no `gt/`.
pub fn load(
    scene_dir: &Path,
    frame: usize,
    camera: &scene::Camera,
    w: usize,
    h: usize,
) -> Result<Option<GroundTruth>, ReconError> {
    let gt = scene_dir.join("gt");
    let index_path = gt.join("gt.json");
    if !index_path.is_file() {
        return Ok(None);
    }
    let index: Index = scene::format::read_json(&index_path)?;
    let (sw, sh) = (camera.width as usize, camera.height as usize);
    let stem = format!("{frame:06}_{}", camera.name);
    let npath = gt.join(format!("{stem}.normal_cam.f32.gz"));
    let nb = gunzip(&npath, sw * sh * 12)?;
    let f: Vec<f32> = nb.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
    let normals: Vec<[f64; 3]> =
        f.chunks_exact(3).map(|n| crate::camera::cv_normal_from_waymo([n[0], n[1], n[2]])).collect();
    let ipath = gt.join(format!("{stem}.instance.u16.gz"));
    let ib = gunzip(&ipath, sw * sh * 2)?;
    let inst: Vec<u16> = ib.chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]])).collect();
    let track_ids: Vec<String> = index.instances.iter().map(|i| i.track_id.clone()).collect();
    let track: Vec<Option<usize>> = inst
        .iter()
        .map(|k| if *k == 0 { None } else { index.instances.iter().position(|i| i.instance == *k) })
        .collect();
    Ok(Some(GroundTruth { normal: resample(&normals, sw, sh, w, h), track: resample(&track, sw, sh, w, h), track_ids }))
}
