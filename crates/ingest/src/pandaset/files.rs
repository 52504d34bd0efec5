//! Reading PandaSet's small JSON files (poses, timestamps, intrinsics) and gzipped cuboid records
//! within size budgets, so a hostile or wrong file is refused before it is held in memory. Every
//! error names the file and, where it applies, the entry and field.

use crate::error::{content, IngestError};
use flate2::read::GzDecoder;
use scene::glam::DVec3;
use scene::Transform3;
use serde::Deserialize;
use std::io::Read;
use std::path::Path;

/// The largest JSON file read whole (poses, timestamps, intrinsics, one frame's cuboids after
/// decompression): far above a real sequence's (a 80-frame poses.json is 20 KB, a frame's
/// cuboids 150 KB).
pub const MAX_JSON_BYTES: u64 = 64 << 20;
/// The most frames a sequence may have (PandaSet's are 80; a day at 10 Hz is 864,000).
pub const MAX_FRAMES: usize = 100_000;

/// The bytes of `file`, gunzipped when its name ends in `.gz`, refused past [`MAX_JSON_BYTES`].
pub fn read_bytes(file: &Path) -> Result<Vec<u8>, IngestError> {
    let io = |e| IngestError::Io { file: file.to_path_buf(), source: e };
    let f = std::fs::File::open(file).map_err(io)?;
    let gz = file.extension().is_some_and(|e| e == "gz");
    let reader: Box<dyn Read> = if gz { Box::new(GzDecoder::new(f)) } else { Box::new(f) };
    let mut out = Vec::new();
    reader.take(MAX_JSON_BYTES + 1).read_to_end(&mut out).map_err(io)?;
    if out.len() as u64 > MAX_JSON_BYTES {
        return Err(content(file, format!("is larger than {MAX_JSON_BYTES} bytes (not a PandaSet JSON file?)")));
    }
    Ok(out)
}

/// `file` parsed as `T`; the error names the field's path (`[3].position.x`) and what was
/// wrong there. A bare `NaN` or `Infinity` (which Python's json writes) is not JSON: said so.
pub fn read_json<T: for<'de> Deserialize<'de>>(file: &Path) -> Result<T, IngestError> {
    let bytes = read_bytes(file)?;
    let mut de = serde_json::Deserializer::from_slice(&bytes);
    serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let field = e.path().to_string();
        let inner = e.into_inner();
        let nan =
            inner.is_syntax() && [&b"NaN"[..], b"Infinity"].iter().any(|t| bytes.windows(t.len()).any(|w| w == *t));
        let message = if nan {
            format!("holds NaN or Infinity, which is not a number in JSON ({inner})")
        } else {
            format!("not the expected value: {inner}")
        };
        IngestError::Field { file: file.to_path_buf(), field, message }
    })
}

#[derive(Deserialize)]
struct Xyz {
    x: f64,
    y: f64,
    z: f64,
}

#[derive(Deserialize)]
struct Wxyz {
    w: f64,
    x: f64,
    y: f64,
    z: f64,
}

#[derive(Deserialize)]
struct PoseJson {
    position: Xyz,
    heading: Wxyz,
}

/// A `poses.json`: one `{position, heading}` (a `world_from_sensor` unit quaternion) per frame.
pub fn read_poses(file: &Path) -> Result<Vec<Transform3>, IngestError> {
    let raw: Vec<PoseJson> = read_json(file)?;
    check_count(file, raw.len())?;
    raw.iter()
        .enumerate()
        .map(|(i, p)| {
            let t = DVec3::new(p.position.x, p.position.y, p.position.z);
            let h = &p.heading;
            Transform3::from_quaternion_translation([h.w, h.x, h.y, h.z], t).ok_or_else(|| IngestError::Field {
                file: file.to_path_buf(),
                field: format!("[{i}]"),
                message: "expected a finite position and a unit quaternion heading {w, x, y, z}".into(),
            })
        })
        .collect()
}

/// A `timestamps.json`: one UNIX time (s) per frame, finite and strictly increasing.
pub fn read_times(file: &Path) -> Result<Vec<f64>, IngestError> {
    let raw: Vec<f64> = read_json(file)?;
    check_count(file, raw.len())?;
    for (i, t) in raw.iter().enumerate() {
        let field = || format!("[{i}]");
        if !t.is_finite() {
            return Err(IngestError::Field { file: file.into(), field: field(), message: "not a finite time".into() });
        }
        if i > 0 && *t <= raw[i - 1] {
            return Err(IngestError::Field {
                file: file.into(),
                field: field(),
                message: format!("time {t} s is not after the previous {} s", raw[i - 1]),
            });
        }
    }
    Ok(raw)
}

fn check_count(file: &Path, n: usize) -> Result<(), IngestError> {
    if n == 0 || n > MAX_FRAMES {
        return Err(content(file, format!("holds {n} entries; expected 1 to {MAX_FRAMES} (one per frame)")));
    }
    Ok(())
}

/// A camera's `intrinsics.json`: `fx, fy, cx, cy` in pixels.
#[derive(Clone, Copy, Debug, Deserialize)]
pub struct IntrinsicsJson {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

pub fn read_intrinsics(file: &Path) -> Result<IntrinsicsJson, IngestError> {
    let k: IntrinsicsJson = read_json(file)?;
    for (field, v, positive) in [("fx", k.fx, true), ("fy", k.fy, true), ("cx", k.cx, false), ("cy", k.cy, false)] {
        if !v.is_finite() || (positive && v <= 0.0) || v.abs() > 1e6 {
            return Err(IngestError::Field {
                file: file.into(),
                field: field.into(),
                message: format!("{v} is not a {}pixel value below 1e6", if positive { "positive " } else { "" }),
            });
        }
    }
    Ok(k)
}

/// Largest LiDAR file accepted (a full 2-sensor PandaSet sweep is about 3 MB as f32 x y z i).
pub const MAX_LIDAR_BYTES: u64 = 256 << 20;

/// A sweep `NN.bin`: little-endian f32 `x y z intensity` records in the world frame. Every value
/// must be finite (the error names the record).
pub fn read_sweep(file: &Path) -> Result<Vec<[f32; 4]>, IngestError> {
    let io = |e| IngestError::Io { file: file.to_path_buf(), source: e };
    let len = std::fs::metadata(file).map_err(io)?.len();
    if len > MAX_LIDAR_BYTES || !len.is_multiple_of(16) {
        return Err(content(
            file,
            format!("is {len} bytes; expected a multiple of 16 (f32 x y z intensity) up to {MAX_LIDAR_BYTES}"),
        ));
    }
    let bytes = std::fs::read(file).map_err(io)?;
    let mut out = Vec::with_capacity(bytes.len() / 16);
    for (i, rec) in bytes.chunks_exact(16).enumerate() {
        let v: [f32; 4] = std::array::from_fn(|k| f32::from_le_bytes(rec[4 * k..4 * k + 4].try_into().unwrap()));
        if v.iter().any(|x| !x.is_finite()) {
            return Err(IngestError::Field {
                file: file.into(),
                field: format!("point {i}"),
                message: format!("{v:?} is not finite"),
            });
        }
        out.push(v);
    }
    Ok(out)
}
