//! Undistortion of camera images at ingest, so every later stage sees an ideal pinhole camera.
//!
//! The output keeps the input's intrinsics `K` and size. Each output pixel centre `(u + 0.5,
//! v + 0.5)` is inverse-mapped: normalised `n = ((u + 0.5 - cx) / fx, (v + 0.5 - cy) / fy)`, then
//! `scene::Distortion::apply(n)` gives where that ray lands in the distorted input, which is
//! sampled bilinearly (pixel centres at half-integers). Samples outside the input are black.
//! No iteration is needed in this direction, so the result is exact up to interpolation.

use rayon::prelude::*;
use scene::glam::DVec2;
use scene::{Distortion, Intrinsics};

/// Bilinear sample of an interleaved 8-bit image at continuous pixel coordinates `(x, y)` (the
/// top-left corner of the image is `(0, 0)`); `None` outside the band of pixel centres.
fn sample(src: &[u8], width: usize, height: usize, channels: usize, x: f64, y: f64, out: &mut [u8]) -> bool {
    let (fx, fy) = (x - 0.5, y - 0.5);
    if !(fx >= -0.5 && fy >= -0.5 && fx <= width as f64 - 0.5 && fy <= height as f64 - 0.5) {
        return false;
    }
    let fx = fx.clamp(0.0, (width - 1) as f64);
    let fy = fy.clamp(0.0, (height - 1) as f64);
    let (x0, y0) = (fx.floor() as usize, fy.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(width - 1), (y0 + 1).min(height - 1));
    let (ax, ay) = (fx - x0 as f64, fy - y0 as f64);
    for (c, o) in out.iter_mut().enumerate().take(channels) {
        let p = |xx: usize, yy: usize| src[(yy * width + xx) * channels + c] as f64;
        let top = p(x0, y0) * (1.0 - ax) + p(x1, y0) * ax;
        let bottom = p(x0, y1) * (1.0 - ax) + p(x1, y1) * ax;
        *o = (top * (1.0 - ay) + bottom * ay).round().clamp(0.0, 255.0) as u8;
    }
    true
}

/// Where the output pixel `(u, v)`'s centre comes from in the distorted image (continuous
/// pixel coordinates, corner origin).
pub fn source_position(k: &Intrinsics, d: &Distortion, u: usize, v: usize) -> DVec2 {
    source_position_at(k, d, u as f64 + 0.5, v as f64 + 0.5)
}

/// Where the continuous output position `(x, y)` comes from in the distorted image.
pub fn source_position_at(k: &Intrinsics, d: &Distortion, x: f64, y: f64) -> DVec2 {
    let n = DVec2::new((x - k.cx) / k.fx, (y - k.cy) / k.fy);
    let m = d.apply(n);
    DVec2::new(k.fx * m.x + k.cx, k.fy * m.y + k.cy)
}

/// Undistorts an interleaved 8-bit image (`channels` per pixel) to the same size and `K`.
pub fn undistort(src: &[u8], width: usize, height: usize, channels: usize, k: &Intrinsics, d: &Distortion) -> Vec<u8> {
    let mut out = vec![0u8; src.len()];
    out.par_chunks_mut(width * channels).enumerate().for_each(|(v, row)| {
        for u in 0..width {
            let s = source_position(k, d, u, v);
            let px = &mut row[u * channels..(u + 1) * channels];
            if !sample(src, width, height, channels, s.x, s.y, px) {
                px.fill(0);
            }
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Inverts the distortion by fixed-point iteration (test only: builds a distorted image).
    fn undistort_point(d: &Distortion, m: DVec2) -> DVec2 {
        let mut n = m;
        for _ in 0..50 {
            n += m - d.apply(n);
        }
        n
    }

    /// A smooth grid (period 0.2 in normalised coordinates, about 50 pixels here): its dark
    /// valleys are straight lines in the ideal camera and bend in the distorted one.
    fn grid(n: DVec2) -> f64 {
        let c = |x: f64| (std::f64::consts::TAU * 5.0 * x).cos();
        127.5 + 100.0 * c(n.x) * c(n.y)
    }

    #[test]
    fn distorted_grid_straightens() {
        let (w, h) = (320usize, 240usize);
        let k = Intrinsics { fx: 250.0, fy: 250.0, cx: 160.0, cy: 120.0 };
        let d = Distortion { k1: -0.25, k2: 0.08, p1: 0.001, p2: -0.0015, k3: 0.0 };
        let norm = |i: usize| DVec2::new(((i % w) as f64 + 0.5 - k.cx) / k.fx, ((i / w) as f64 + 0.5 - k.cy) / k.fy);
        let ideal: Vec<f64> = (0..w * h).map(|i| grid(norm(i))).collect();
        // The distorted photo: each distorted pixel shows the ideal grid at its undistorted ray.
        let distorted: Vec<u8> = (0..w * h).map(|i| grid(undistort_point(&d, norm(i))).round() as u8).collect();
        let fixed = undistort(&distorted, w, h, 1, &k, &d);
        // Mean absolute difference from the ideal image away from the border (no data there).
        let error = |img: &[u8]| {
            let (mut sum, mut n) = (0.0, 0usize);
            for v in 20..h - 20 {
                for u in 20..w - 20 {
                    sum += (img[v * w + u] as f64 - ideal[v * w + u]).abs();
                    n += 1;
                }
            }
            sum / n as f64
        };
        let (before, after) = (error(&distorted), error(&fixed));
        assert!(before > 20.0, "the test distortion should visibly bend the grid ({before} grey levels)");
        assert!(after < 1.5, "undistorted grid is {after} grey levels from the ideal one (before: {before})");
        // The dark line of the ideal grid at x_n = 0.1 stays on one column in every row.
        let u = (k.cx + 0.1 * k.fx - 0.5).round() as usize;
        for v in 20..h - 20 {
            let i = v * w + u;
            assert!((fixed[i] as f64 - ideal[i]).abs() < 4.0, "row {v}: {} vs {}", fixed[i], ideal[i]);
        }
    }

    #[test]
    fn zero_distortion_is_identity() {
        let (w, h) = (7usize, 5usize);
        let src: Vec<u8> = (0..w * h * 3).map(|i| (i * 7 % 251) as u8).collect();
        let k = Intrinsics { fx: 5.0, fy: 5.0, cx: 3.5, cy: 2.5 };
        assert_eq!(undistort(&src, w, h, 3, &k, &Distortion::default()), src);
    }
}
