//! External depth maps (`--depth-dir`): one file per image, named like the image's stem
//! (`<frame:06>_<CAMERA>`), either `.npy` (little-endian float32, C order, shape `(height,
//! width)`) or a 16-bit grey `.png` holding the value times 256 (KITTI's depth convention;
//! 0 = none). `--depth-kind metric` takes the values as z-depth in metres; `disparity` takes
//! them as relative inverse depth (monocular networks) and aligns them by least squares,
//! `1/z = s * value + t`, to sparse metric depth of the same image (LiDAR or stereo).

use super::error::PriorError;
use std::path::{Path, PathBuf};

/// What the files in `--depth-dir` hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DepthKind {
    Metric,
    Disparity,
}

/// The file for an image stem, `.npy` preferred over `.png`.
pub fn find(dir: &Path, stem: &str) -> Option<PathBuf> {
    ["npy", "png"].iter().map(|e| dir.join(format!("{stem}.{e}"))).find(|p| p.is_file())
}

fn read_npy(path: &Path, w: usize, h: usize) -> Result<Vec<f32>, PriorError> {
    let bytes = std::fs::read(path).map_err(|e| PriorError::io(path, e))?;
    let bad = |m: String| PriorError::invalid(path, m);
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(bad("not a .npy file (no \\x93NUMPY magic)".into()));
    }
    let (hlen, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize, 12),
        v => return Err(bad(format!("unsupported .npy version {v}"))),
    };
    let header =
        bytes.get(start..start + hlen).map(|h| String::from_utf8_lossy(h).replace(' ', "")).unwrap_or_default();
    if !header.contains("'descr':'<f4'") || header.contains("'fortran_order':True") {
        return Err(bad(format!("expected little-endian float32 in C order, header {header}")));
    }
    if !header.contains(&format!("'shape':({h},{w})")) {
        return Err(bad(format!("expected shape ({h}, {w}), header {header}")));
    }
    let data = &bytes[start + hlen..];
    if data.len() != w * h * 4 {
        return Err(bad(format!("{} data bytes, expected {}", data.len(), w * h * 4)));
    }
    Ok(data.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
}

fn read_png16(path: &Path, w: usize, h: usize) -> Result<Vec<f32>, PriorError> {
    let img = image::ImageReader::open(path)
        .map_err(|e| PriorError::io(path, e))?
        .decode()
        .map_err(|e| PriorError::invalid(path, format!("cannot decode: {e}")))?;
    if img.color() != image::ColorType::L16 {
        return Err(PriorError::invalid(path, format!("expected a 16-bit grey PNG, got {:?}", img.color())));
    }
    let img = img.into_luma16();
    if (img.width() as usize, img.height() as usize) != (w, h) {
        return Err(PriorError::invalid(path, format!("is {}x{}, expected {w}x{h}", img.width(), img.height())));
    }
    Ok(img.into_raw().into_iter().map(|v| v as f32 / 256.0).collect())
}

/// Reads one external map (values as stored; non-finite or non-positive = none).
pub fn read(path: &Path, w: usize, h: usize) -> Result<Vec<f32>, PriorError> {
    let v = if path.extension().is_some_and(|e| e == "npy") { read_npy(path, w, h)? } else { read_png16(path, w, h)? };
    Ok(v.into_iter().map(|x| if x.is_finite() && x > 0.0 { x } else { 0.0 }).collect())
}

/// Aligns relative disparity to metric depth: least squares `1/z = s d + t` over pixels where
/// both exist (at least 20), then `z = 1 / (s d + t)` where that is positive. `None` when the
/// fit is impossible.
pub fn align_disparity(disp: &[f32], sparse_depth: &[f32]) -> Option<(Vec<f32>, f64, f64)> {
    let (mut n, mut sx, mut sy, mut sxx, mut sxy) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
    for (&d, &z) in disp.iter().zip(sparse_depth) {
        if d > 0.0 && z > 0.0 {
            let (x, y) = (d as f64, 1.0 / z as f64);
            n += 1.0;
            sx += x;
            sy += y;
            sxx += x * x;
            sxy += x * y;
        }
    }
    let den = n * sxx - sx * sx;
    if n < 20.0 || den.abs() < 1e-12 {
        return None;
    }
    let s = (n * sxy - sx * sy) / den;
    let t = (sy - s * sx) / n;
    let z = disp
        .iter()
        .map(|&d| {
            let inv = s * d as f64 + t;
            if d > 0.0 && inv > 0.0 {
                (1.0 / inv) as f32
            } else {
                0.0
            }
        })
        .collect();
    Some((z, s, t))
}
