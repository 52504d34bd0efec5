//! Ground-truth maps of synthetic scenes (`docs/scene-format.md`, "Ground truth"): per frame and
//! camera, gzip-compressed raw little-endian arrays (depth, normals in camera and world axes,
//! instance ids) and a PNG sky mask under `gt/`, described by `gt/gt.json` (sizes, dtypes, instance -> track id, the
//! LiDAR geometry). The files go into the staged scene directory, which is renamed into place
//! only when complete. Raw arrays keep every value exact (f32); gzip shrinks them about 12-fold
//! (large flat surfaces, sky) and any tool reads it (`gzip -dc`, Python's `gzip` + `numpy`).

use crate::error::SynthError;
use crate::lidar::LidarSpec;
use crate::raycast::CameraImage;
use serde::Serialize;
use std::path::Path;

pub const GT_DIR: &str = "gt";
pub const GT_FORMAT: &str = "carla-gs-gt/1";

/// Relative path of a GT map: `gt/<frame:06>_<CAMERA>.<kind>`, e.g. `depth.f32.gz`.
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
    /// `gzip` (a gzip stream of the raw array) or `png`.
    pub encoding: &'static str,
    /// Values per pixel.
    pub channels: usize,
    pub meaning: &'static str,
}

pub const GT_FILES: [GtFile; 5] = [
    GtFile {
        suffix: "depth.f32.gz",
        dtype: "f32",
        encoding: "gzip",
        channels: 1,
        meaning: "depth along the camera's optical axis (camera x) of the pixel-centre ray's first hit, metres; +inf where sky",
    },
    GtFile {
        suffix: "normal_cam.f32.gz",
        dtype: "f32",
        encoding: "gzip",
        channels: 3,
        meaning: "unit outward surface normal in Waymo camera axes (x forward, y left, z up); 0 0 0 where sky",
    },
    GtFile {
        suffix: "normal_world.f32.gz",
        dtype: "f32",
        encoding: "gzip",
        channels: 3,
        meaning: "unit outward surface normal in the world frame; 0 0 0 where sky",
    },
    GtFile {
        suffix: "instance.u16.gz",
        dtype: "u16",
        encoding: "gzip",
        channels: 1,
        meaning: "0 static world or sky, k > 0 a vehicle (see instances)",
    },
    GtFile { suffix: "sky.png", dtype: "png", encoding: "png", channels: 1, meaning: "8-bit grey: 255 sky, 0 surface" },
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

/// A gzip stream of `bytes` (fast level; the header has no time stamp, so output is reproducible).
fn gzip(bytes: &[u8]) -> Vec<u8> {
    use std::io::Write;
    let mut enc = flate2::write::GzEncoder::new(Vec::with_capacity(bytes.len() / 8), flate2::Compression::fast());
    enc.write_all(bytes).expect("writing to memory");
    enc.finish().expect("writing to memory")
}

fn le_f32(values: impl Iterator<Item = f32>) -> Vec<u8> {
    gzip(&values.flat_map(f32::to_le_bytes).collect::<Vec<u8>>())
}

/// The GT files of one camera image: `(path relative to the scene directory, bytes)`. Encoding
/// (gzip, PNG) is the costly part, so callers run it in parallel and only write serially.
pub fn encode_maps(frame: usize, camera: &str, img: &CameraImage) -> Result<Vec<(String, Vec<u8>)>, String> {
    let normals = |n: &[[f32; 3]]| le_f32(n.iter().flatten().copied());
    let inst: Vec<u8> = img.instance.iter().flat_map(|v| v.to_le_bytes()).collect();
    let sky: Vec<u8> = img.sky.iter().map(|&s| if s { 255 } else { 0 }).collect();
    Ok(vec![
        (gt_rel_path(frame, camera, "depth.f32.gz"), le_f32(img.depth.iter().copied())),
        (gt_rel_path(frame, camera, "normal_cam.f32.gz"), normals(&img.normal_cam)),
        (gt_rel_path(frame, camera, "normal_world.f32.gz"), normals(&img.normal_world)),
        (gt_rel_path(frame, camera, "instance.u16.gz"), gzip(&inst)),
        (gt_rel_path(frame, camera, "sky.png"), crate::preview::encode_png_luma(&sky, img.width, img.height)?),
    ])
}

/// Writes files from [`encode_maps`] under `dir`.
pub fn write_maps(dir: &Path, files: &[(String, Vec<u8>)]) -> Result<(), SynthError> {
    files.iter().try_for_each(|(rel, bytes)| write(dir, rel, bytes))
}

/// The decompressed bytes of a gzip GT map.
fn read_gz(path: &Path) -> Result<Vec<u8>, SynthError> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(|e| SynthError::io(path, e))?;
    let mut bytes = Vec::new();
    flate2::read::GzDecoder::new(file).read_to_end(&mut bytes).map_err(|e| SynthError::io(path, e))?;
    Ok(bytes)
}

/// Reads a little-endian f32 GT map (`depth.f32.gz`, `normal_*.f32.gz`).
pub fn read_f32(path: &Path) -> Result<Vec<f32>, SynthError> {
    Ok(read_gz(path)?.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
}

/// Reads a little-endian u16 instance map (`instance.u16.gz`).
pub fn read_u16(path: &Path) -> Result<Vec<u16>, SynthError> {
    Ok(read_gz(path)?.chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]])).collect())
}
