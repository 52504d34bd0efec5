//! Reading camera images (JPEG or PNG, colour or grey) as floats for the trainer and the stereo
//! matcher, and the priors' own file encodings: gzip little-endian f32 arrays and 8-bit PNGs,
//! plus the viewable colour-mapped depth and normal images.

use super::error::PriorError;
use image::codecs::png::PngEncoder;
use image::{ExtendedColorType, ImageEncoder};
use std::io::{Read, Write};
use std::path::Path;

fn decode(path: &Path) -> Result<image::DynamicImage, PriorError> {
    image::ImageReader::open(path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| PriorError::io(path, e))?
        .decode()
        .map_err(|e| PriorError::invalid(path, format!("cannot decode the image: {e}")))
}

/// An image as `(width, height, rgb)` with values in 0..1, row-major from the top-left pixel.
/// Grey images are replicated to three channels.
pub fn load_image_rgb(path: &Path) -> Result<(usize, usize, Vec<[f32; 3]>), PriorError> {
    let img = decode(path)?.into_rgb8();
    let (w, h) = (img.width() as usize, img.height() as usize);
    let px = img.pixels().map(|p| p.0.map(|c| c as f32 / 255.0)).collect();
    Ok((w, h, px))
}

/// An image as `(width, height, luma 0..255)` (colour converted with the `image` crate's weights).
pub fn load_image_grey(path: &Path) -> Result<(usize, usize, Vec<u8>), PriorError> {
    let img = decode(path)?.into_luma8();
    Ok((img.width() as usize, img.height() as usize, img.into_raw()))
}

/// gzip (fast level, no time stamp: reproducible) of little-endian f32 values.
pub fn gzip_f32(values: impl Iterator<Item = f32>) -> Vec<u8> {
    let bytes: Vec<u8> = values.flat_map(f32::to_le_bytes).collect();
    let mut enc = flate2::write::GzEncoder::new(Vec::with_capacity(bytes.len() / 4), flate2::Compression::fast());
    enc.write_all(&bytes).expect("writing to memory");
    enc.finish().expect("writing to memory")
}

/// Reads a gzip little-endian f32 array and checks its length. At most one byte more than the
/// expected size is inflated (a gzip bomb is refused after `4 x expected + 1` bytes, not when memory
/// runs out), and only from a regular file (a link to `/dev/zero` is refused).
pub fn read_gz_f32(path: &Path, expected: usize) -> Result<Vec<f32>, PriorError> {
    let want = expected
        .checked_mul(4)
        .ok_or_else(|| PriorError::invalid(path, format!("f32 x {expected}: too many values")))?;
    let meta = std::fs::metadata(path).map_err(|e| PriorError::io(path, e))?;
    if !meta.is_file() {
        return Err(PriorError::invalid(path, "is not a regular file"));
    }
    let file = std::fs::File::open(path).map_err(|e| PriorError::io(path, e))?;
    let mut bytes = Vec::with_capacity(want.min(1 << 26));
    flate2::read::GzDecoder::new(file)
        .take(want as u64 + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| PriorError::io(path, e))?;
    if bytes.len() != want {
        let got = if bytes.len() > want { format!("more than {want}") } else { bytes.len().to_string() };
        return Err(PriorError::invalid(path, format!("inflates to {got} bytes, expected {want} (f32 x {expected})")));
    }
    Ok(bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
}

fn png(bytes: &[u8], width: usize, height: usize, colour: ExtendedColorType) -> Vec<u8> {
    let mut out = Vec::new();
    PngEncoder::new(&mut out)
        .write_image(bytes, width as u32, height as u32, colour)
        .expect("encoding a PNG of matching size into memory");
    out
}

/// An 8-bit grey PNG of a mask: 255 in, 0 out.
pub fn mask_png(mask: &[bool], width: usize, height: usize) -> Vec<u8> {
    let grey: Vec<u8> = mask.iter().map(|&m| if m { 255 } else { 0 }).collect();
    png(&grey, width, height, ExtendedColorType::L8)
}

/// Reads an 8-bit grey mask PNG (any non-zero value is in).
pub fn read_mask_png(path: &Path, width: usize, height: usize) -> Result<Vec<bool>, PriorError> {
    let img = decode(path)?.into_luma8();
    if (img.width() as usize, img.height() as usize) != (width, height) {
        return Err(PriorError::invalid(
            path,
            format!("is {}x{}, expected {width}x{height}", img.width(), img.height()),
        ));
    }
    Ok(img.into_raw().into_iter().map(|v| v > 0).collect())
}

/// Viewable depth: inverse depth through a blue-to-yellow ramp (near bright), black = none.
pub fn depth_png(depth: &[f32], width: usize, height: usize) -> Vec<u8> {
    let rgb: Vec<u8> = depth
        .iter()
        .flat_map(|&d| {
            if !(d > 0.0 && d.is_finite()) {
                return [0, 0, 0];
            }
            let t = (2.0 / d.max(2.0)).sqrt(); // 1 at 2 m, 0.25 at 32 m
            let r = (255.0 * (1.5 * t).min(1.0)) as u8;
            let g = (255.0 * t) as u8;
            let b = (255.0 * (1.0 - t) * 0.8 + 40.0) as u8;
            [r, g, b]
        })
        .collect();
    png(&rgb, width, height, ExtendedColorType::Rgb8)
}

/// Viewable normals: `(n + 1) / 2` as RGB; missing normals black.
pub fn normal_png(normal: &[[f32; 3]], width: usize, height: usize) -> Vec<u8> {
    let rgb: Vec<u8> = normal
        .iter()
        .flat_map(|n| {
            if *n == [0.0; 3] {
                [0, 0, 0]
            } else {
                n.map(|c| (127.5 * (c + 1.0)).round().clamp(0.0, 255.0) as u8)
            }
        })
        .collect();
    png(&rgb, width, height, ExtendedColorType::Rgb8)
}
