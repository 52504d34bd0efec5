//! Image encoding (JPEG at a fixed quality, PNG) and the contact sheet: a grid of a few frames
//! (rows) by the cameras in left-to-right order, plus the FRONT camera's depth and instance maps
//! as false colour, each tile downscaled so the sheet stays small.

use crate::raycast::CameraImage;
use image::codecs::jpeg::JpegEncoder;
use image::codecs::png::PngEncoder;
use image::{ExtendedColorType, ImageEncoder};

/// JPEG quality of the camera images (fixed: the output is byte-identical for a seed).
pub const JPEG_QUALITY: u8 = 90;

pub fn encode_jpeg(rgb: &[u8], width: u32, height: u32) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    JpegEncoder::new_with_quality(&mut out, JPEG_QUALITY)
        .encode(rgb, width, height, ExtendedColorType::Rgb8)
        .map_err(|e| e.to_string())?;
    Ok(out)
}

fn encode_png(bytes: &[u8], width: u32, height: u32, colour: ExtendedColorType) -> Result<Vec<u8>, String> {
    let mut out = Vec::new();
    PngEncoder::new(&mut out).write_image(bytes, width, height, colour).map_err(|e| e.to_string())?;
    Ok(out)
}

pub fn encode_png_luma(grey: &[u8], width: u32, height: u32) -> Result<Vec<u8>, String> {
    encode_png(grey, width, height, ExtendedColorType::L8)
}

/// Frames shown on the contact sheet: up to four, evenly spread, first and last included.
pub fn preview_frames(frames: usize) -> Vec<usize> {
    let mut v: Vec<usize> = (0..4).map(|i| i * frames.saturating_sub(1) / 3).collect();
    v.dedup();
    v
}

/// Left-to-right display order of the camera names.
pub const DISPLAY_ORDER: [&str; 5] = ["SIDE_LEFT", "FRONT_LEFT", "FRONT", "FRONT_RIGHT", "SIDE_RIGHT"];

/// A tile: RGB pixels at the image's size.
struct Tile {
    width: u32,
    height: u32,
    rgb: Vec<u8>,
}

fn depth_tile(img: &CameraImage) -> Tile {
    // Inverse depth, near bright; sky black.
    let rgb = img
        .depth
        .iter()
        .flat_map(|&d| {
            let v = if d.is_finite() { (4.0 / d.max(4.0)).sqrt() } else { 0.0 };
            [(255.0 * v) as u8, (255.0 * v * v) as u8, (255.0 * (1.0 - v) * v * 2.0).min(255.0) as u8]
        })
        .collect();
    Tile { width: img.width, height: img.height, rgb }
}

fn instance_tile(img: &CameraImage) -> Tile {
    let rgb = img
        .instance
        .iter()
        .zip(&img.sky)
        .flat_map(|(&k, &sky)| match (k, sky) {
            (0, true) => [20, 20, 40],
            (0, false) => [70, 70, 70],
            (k, _) => {
                let h = (k as u32).wrapping_mul(2_654_435_761);
                [(h >> 24) as u8 | 0x40, (h >> 16) as u8 | 0x40, (h >> 8) as u8 | 0x40]
            }
        })
        .collect();
    Tile { width: img.width, height: img.height, rgb }
}

/// Box-filter downscale by an integer factor.
fn downscale(t: &Tile, f: u32) -> Tile {
    let (w, h) = (t.width / f, t.height / f);
    let mut rgb = Vec::with_capacity((w * h * 3) as usize);
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                let mut s = 0u32;
                for dy in 0..f {
                    for dx in 0..f {
                        s += t.rgb[(((y * f + dy) * t.width + x * f + dx) * 3 + c) as usize] as u32;
                    }
                }
                rgb.push((s / (f * f)) as u8);
            }
        }
    }
    Tile { width: w, height: h, rgb }
}

/// The contact sheet PNG: `rows[i]` holds the images of one frame by camera name.
pub fn contact_sheet(rows: &[Vec<(String, CameraImage)>]) -> Result<Vec<u8>, String> {
    let mut grid: Vec<Vec<Tile>> = Vec::new();
    for row in rows {
        let mut tiles = Vec::new();
        for name in DISPLAY_ORDER {
            if let Some((_, img)) = row.iter().find(|(n, _)| n == name) {
                tiles.push(Tile { width: img.width, height: img.height, rgb: img.rgb.clone() });
            }
        }
        if let Some((_, img)) = row.iter().find(|(n, _)| n == "FRONT") {
            tiles.push(depth_tile(img));
            tiles.push(instance_tile(img));
        }
        let f = (tiles.first().map_or(1, |t| t.width) / 240).max(1);
        grid.push(tiles.iter().map(|t| downscale(t, f)).collect());
    }
    let gap = 4u32;
    let tw = grid.iter().flatten().map(|t| t.width).max().unwrap_or(1);
    let th = grid.iter().flatten().map(|t| t.height).max().unwrap_or(1);
    let cols = grid.iter().map(Vec::len).max().unwrap_or(1) as u32;
    let (w, h) = (cols * (tw + gap) + gap, grid.len() as u32 * (th + gap) + gap);
    let mut sheet = vec![255u8; (w * h * 3) as usize];
    for (r, row) in grid.iter().enumerate() {
        for (c, t) in row.iter().enumerate() {
            let (ox, oy) = (gap + c as u32 * (tw + gap), gap + r as u32 * (th + gap));
            for y in 0..t.height {
                let src = &t.rgb[(y * t.width * 3) as usize..((y + 1) * t.width * 3) as usize];
                let at = (((oy + y) * w + ox) * 3) as usize;
                sheet[at..at + src.len()].copy_from_slice(src);
            }
        }
    }
    encode_png(&sheet, w, h, ExtendedColorType::Rgb8)
}
