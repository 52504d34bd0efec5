//! Ground-truth maps of synthetic scenes (`docs/scene-format.md`, "Ground truth"): per frame and
//! camera, raw little-endian arrays (depth, normals in camera and world axes, instance ids) and a
//! PNG sky mask under `gt/`, described by `gt/gt.json` (sizes, dtypes, instance -> track id, the
//! LiDAR geometry). The files go into the staged scene directory, which is renamed into place
//! only when complete.

use crate::error::SynthError;
use crate::lidar::LidarSpec;
use crate::raycast::CameraImage;
use serde::Serialize;
use std::path::Path;

pub const GT_DIR: &str = "gt";
pub const GT_FORMAT: &str = "carla-gs-gt/1";

/// Relative path of a GT map: `gt/<frame:06>_<CAMERA>.<kind>`, e.g. `depth.f32`.
pub fn gt_rel_path(frame: usize, camera: &str, kind: &str) -> String {
    format!("{GT_DIR}/{frame:06}_{camera}.{kind}")
}

/// One file kind of the GT maps.
#[derive(Clone, Debug, Serialize)]
pub struct GtFile {
    /// File name suffix after `<frame:06>_<CAMERA>.`.
    pub suffix: &'static str,
    /// Element type (`f32`, `u16` little-endian, or `png`).
    pub dtype: &'static str,
    /// Values per pixel.
    pub channels: usize,
    pub meaning: &'static str,
}

pub const GT_FILES: [GtFile; 5] = [
    GtFile {
        suffix: "depth.f32",
        dtype: "f32",
        channels: 1,
        meaning: "depth along the camera's optical axis (camera x) of the pixel-centre ray's first hit, metres; +inf where sky",
    },
    GtFile {
        suffix: "normal_cam.f32",
        dtype: "f32",
        channels: 3,
        meaning: "unit outward surface normal in Waymo camera axes (x forward, y left, z up); 0 0 0 where sky",
    },
    GtFile {
        suffix: "normal_world.f32",
        dtype: "f32",
        channels: 3,
        meaning: "unit outward surface normal in the world frame; 0 0 0 where sky",
    },
    GtFile {
        suffix: "instance.u16",
        dtype: "u16",
        channels: 1,
        meaning: "0 static world or sky, k > 0 a vehicle (see instances)",
    },
    GtFile { suffix: "sky.png", dtype: "png", channels: 1, meaning: "8-bit grey: 255 sky, 0 surface" },
];

#[derive(Clone, Debug, Serialize)]
pub struct GtCamera {
    pub name: String,
    pub width: u32,
    pub height: u32,
}

#[derive(Clone, Debug, Serialize)]
pub struct GtInstance {
    pub instance: u16,
    pub track_id: String,
}

/// Contents of `gt/gt.json`.
#[derive(Clone, Debug, Serialize)]
pub struct GtIndex {
    pub format: &'static str,
    /// "row-major from the top-left pixel; pixel (u, v) centre at (u + 0.5, v + 0.5)".
    pub layout: &'static str,
    pub files: Vec<GtFile>,
    pub cameras: Vec<GtCamera>,
    pub instances: Vec<GtInstance>,
    pub lidar: LidarSpec,
}

fn write(dir: &Path, rel: &str, bytes: &[u8]) -> Result<(), SynthError> {
    let path = dir.join(rel);
    std::fs::write(&path, bytes).map_err(|e| SynthError::io(path, e))
}

fn le_f32(values: impl Iterator<Item = f32>) -> Vec<u8> {
    values.flat_map(f32::to_le_bytes).collect()
}

/// Writes the GT maps of one camera image under `dir/gt/`.
pub fn write_maps(dir: &Path, frame: usize, camera: &str, img: &CameraImage) -> Result<(), SynthError> {
    write(dir, &gt_rel_path(frame, camera, "depth.f32"), &le_f32(img.depth.iter().copied()))?;
    write(dir, &gt_rel_path(frame, camera, "normal_cam.f32"), &le_f32(img.normal_cam.iter().flatten().copied()))?;
    write(dir, &gt_rel_path(frame, camera, "normal_world.f32"), &le_f32(img.normal_world.iter().flatten().copied()))?;
    let inst: Vec<u8> = img.instance.iter().flat_map(|v| v.to_le_bytes()).collect();
    write(dir, &gt_rel_path(frame, camera, "instance.u16"), &inst)?;
    let sky: Vec<u8> = img.sky.iter().map(|&s| if s { 255 } else { 0 }).collect();
    let rel = gt_rel_path(frame, camera, "sky.png");
    let png = crate::preview::encode_png_luma(&sky, img.width, img.height)
        .map_err(|message| SynthError::Image { path: dir.join(&rel), message })?;
    write(dir, &rel, &png)
}

/// Reads a little-endian f32 GT map (`depth.f32`, `normal_*.f32`).
pub fn read_f32(path: &Path) -> Result<Vec<f32>, SynthError> {
    let bytes = std::fs::read(path).map_err(|e| SynthError::io(path, e))?;
    Ok(bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
}

/// Reads a little-endian u16 instance map.
pub fn read_u16(path: &Path) -> Result<Vec<u16>, SynthError> {
    let bytes = std::fs::read(path).map_err(|e| SynthError::io(path, e))?;
    Ok(bytes.chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]])).collect())
}
