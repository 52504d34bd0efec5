//! Waymo LiDAR range images to ego-frame points.
//!
//! `range_image_compressed` is zlib(`MatrixFloat`) of shape `[H, W, 4]` (range, intensity,
//! elongation, no-label-zone). Pixel `(i, j)` with range `r > 0` is the point
//! `r (cos(inc_i) cos(az_j), cos(inc_i) sin(az_j), sin(inc_i))` in the laser frame, mapped to the
//! ego frame by the calibration's `ego_from_laser` extrinsic, where
//! * `inc_i`: row 0 is the highest beam. With explicit `beam_inclinations` (ascending, one per
//!   row) row `i` uses `beam_inclinations[H-1-i]`; otherwise rows are uniform between min and
//!   max: `inc_i = min + (H - 1 - i + 0.5) / H * (max - min)`;
//! * `az_j = (2 (W - j - 0.5) / W - 1) pi - atan2(E10, E00)` with `E` the extrinsic.
//!
//! Limitation: the per-pixel `range_image_pose` (rolling-shutter ego-motion compensation of the
//! TOP laser) is not applied; points are in the frame's ego pose.

use crate::proto::{LaserCalibration, MatrixFloat};
use prost::Message;
use scene::glam::DVec3;
use scene::Transform3;
use std::io::Read;

/// A decoded range image: `[H, W, C]` values, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct RangeImage {
    pub height: usize,
    pub width: usize,
    pub channels: usize,
    pub values: Vec<f32>,
}

/// Inflates and parses `range_image_compressed`.
pub fn decompress(bytes: &[u8]) -> Result<RangeImage, String> {
    let mut raw = Vec::new();
    flate2::read::ZlibDecoder::new(bytes).read_to_end(&mut raw).map_err(|e| format!("zlib: {e}"))?;
    let m = MatrixFloat::decode(&raw[..]).map_err(|e| format!("MatrixFloat: {e}"))?;
    let dims = m.shape.map(|s| s.dims).unwrap_or_default();
    if dims.len() != 3 || dims.iter().any(|d| *d <= 0) {
        return Err(format!("expected shape [H, W, C] with positive dims, got {dims:?}"));
    }
    let (h, w, c) = (dims[0] as usize, dims[1] as usize, dims[2] as usize);
    if c < 2 || m.data.len() != h * w * c {
        return Err(format!("shape {dims:?} needs {} values and >= 2 channels, found {}", h * w * c, m.data.len()));
    }
    Ok(RangeImage { height: h, width: w, channels: c, values: m.data })
}

/// Row inclinations (radians), index 0 = top row.
pub fn row_inclinations(cal: &LaserCalibration, height: usize) -> Result<Vec<f64>, String> {
    if !cal.beam_inclinations.is_empty() {
        if cal.beam_inclinations.len() != height {
            return Err(format!(
                "beam_inclinations has {} entries for a range image of {height} rows",
                cal.beam_inclinations.len()
            ));
        }
        return Ok(cal.beam_inclinations.iter().rev().copied().collect());
    }
    let (lo, hi) = match (cal.beam_inclination_min, cal.beam_inclination_max) {
        (Some(lo), Some(hi)) => (lo, hi),
        _ => return Err("neither beam_inclinations nor beam_inclination_min/max is set".into()),
    };
    Ok((0..height).map(|i| lo + ((height - 1 - i) as f64 + 0.5) / height as f64 * (hi - lo)).collect())
}

/// Converts a range image to ego-frame `[x, y, z, intensity]` points (pixels with range > 0).
pub fn to_points(
    img: &RangeImage,
    cal: &LaserCalibration,
    ego_from_laser: &Transform3,
) -> Result<Vec<[f32; 4]>, String> {
    let inclinations = row_inclinations(cal, img.height)?;
    let r = ego_from_laser.rotation();
    let az_correction = r.x_axis.y.atan2(r.x_axis.x);
    let w = img.width as f64;
    let azimuths: Vec<(f64, f64)> = (0..img.width)
        .map(|j| {
            let az = (2.0 * (w - j as f64 - 0.5) / w - 1.0) * std::f64::consts::PI - az_correction;
            (az.cos(), az.sin())
        })
        .collect();
    let mut out = Vec::new();
    for (i, inc) in inclinations.iter().enumerate() {
        let (ci, si) = (inc.cos(), inc.sin());
        for (j, (ca, sa)) in azimuths.iter().enumerate() {
            let px = &img.values[(i * img.width + j) * img.channels..][..img.channels];
            let range = px[0] as f64;
            if range.is_nan() || range <= 0.0 {
                continue;
            }
            let p = ego_from_laser.transform_point(DVec3::new(range * ci * ca, range * ci * sa, range * si));
            out.push([p.x as f32, p.y as f32, p.z as f32, px[1]]);
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::proto::{MatrixShape, Transform as PbTransform};
    use std::io::Write;

    /// Builds a compressed range image from known ego-frame points by inverting the model
    /// independently (ego -> laser frame, then azimuth/inclination -> nearest column/row).
    fn build(
        points: &[DVec3],
        ego_from_laser: &Transform3,
        incl: &[f64],
        width: usize,
    ) -> (Vec<u8>, Vec<(usize, usize, f64)>) {
        let h = incl.len();
        let laser_from_ego = ego_from_laser.inverse();
        let az_correction = {
            let x = ego_from_laser.rotation().x_axis;
            x.y.atan2(x.x)
        };
        let mut data = vec![0f32; h * width * 4];
        let mut placed = Vec::new();
        for p in points {
            let q = laser_from_ego.transform_point(*p);
            let range = q.length();
            let inc = (q.z / range).asin();
            let az = q.y.atan2(q.x);
            // Invert az = (2 (W - j - 0.5) / W - 1) pi - corr  =>  j = W - 0.5 - (az + corr + pi) W / (2 pi)
            let jf =
                width as f64 - 0.5 - (az + az_correction + std::f64::consts::PI) * width as f64 / std::f64::consts::TAU;
            let j = (jf.round() as i64).rem_euclid(width as i64) as usize;
            // incl is ascending; row 0 is the top beam.
            let k = (0..h).min_by(|a, b| (incl[*a] - inc).abs().total_cmp(&(incl[*b] - inc).abs())).unwrap();
            let i = h - 1 - k;
            data[(i * width + j) * 4] = range as f32;
            data[(i * width + j) * 4 + 1] = 0.5;
            placed.push((i, j, range));
        }
        let m = MatrixFloat { data, shape: Some(MatrixShape { dims: vec![h as i32, width as i32, 4] }) };
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&m.encode_to_vec()).unwrap();
        (z.finish().unwrap(), placed)
    }

    fn calibration(ego_from_laser: &Transform3, incl: Vec<f64>) -> LaserCalibration {
        LaserCalibration {
            name: Some(1),
            beam_inclinations: incl,
            beam_inclination_min: None,
            beam_inclination_max: None,
            extrinsic: Some(PbTransform { transform: ego_from_laser.to_row_major().concat() }),
        }
    }

    #[test]
    fn decodes_known_geometry() {
        // A laser 2 m up and 1.4 m forward, yawed by 0.3 rad; points chosen exactly on beams
        // and column centres so reconstruction is exact up to f32 rounding.
        let ego_from_laser = Transform3::from_yaw_translation(0.3, DVec3::new(1.4, 0.0, 2.0));
        let incl: Vec<f64> = (0..32).map(|k| -0.3 + 0.02 * k as f64).collect();
        let width = 360;
        let mut truth = Vec::new();
        for (k, j) in [(3usize, 10usize), (10, 95), (20, 180), (31, 300), (0, 359)] {
            let corr = 0.3;
            let az = (2.0 * (width as f64 - j as f64 - 0.5) / width as f64 - 1.0) * std::f64::consts::PI - corr;
            let range = 5.0 + k as f64;
            let q = DVec3::new(incl[k].cos() * az.cos(), incl[k].cos() * az.sin(), incl[k].sin()) * range;
            truth.push(ego_from_laser.transform_point(q));
        }
        let (bytes, placed) = build(&truth, &ego_from_laser, &incl, width);
        assert_eq!(placed.len(), truth.len());
        let img = decompress(&bytes).unwrap();
        assert_eq!((img.height, img.width, img.channels), (32, 360, 4));
        let pts = to_points(&img, &calibration(&ego_from_laser, incl), &ego_from_laser).unwrap();
        assert_eq!(pts.len(), truth.len());
        for t in &truth {
            let best = pts
                .iter()
                .map(|p| (DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64) - *t).length())
                .fold(f64::MAX, f64::min);
            assert!(best < 1e-4, "point {t} recovered with error {best}");
        }
    }

    #[test]
    fn ground_plane_stays_flat() {
        // Sample a flat ground (z = 0 in the ego frame) seen from a laser 2 m up; after the round
        // trip through beams/columns every decoded point must lie near z = 0 and at the right
        // side of the car (sign of y preserved).
        let ego_from_laser = Transform3::from_yaw_translation(-0.7, DVec3::new(0.0, 0.0, 2.0));
        let incl: Vec<f64> = (0..64).map(|k| -0.4 + 0.005 * k as f64).collect();
        // Points only on the left half (y > 0), each angle with its own radius, so a flipped
        // azimuth sign or a mirrored column order cannot pass.
        let step = std::f64::consts::TAU / 72.0;
        let radius = |a: f64| 6.0 + 0.1 * a;
        let pts: Vec<DVec3> = (1..36)
            .map(|a| {
                let ang = a as f64 * step;
                DVec3::new(radius(a as f64) * ang.cos(), radius(a as f64) * ang.sin(), 0.0)
            })
            .collect();
        let (bytes, _) = build(&pts, &ego_from_laser, &incl, 2650);
        let img = decompress(&bytes).unwrap();
        let out = to_points(&img, &calibration(&ego_from_laser, incl), &ego_from_laser).unwrap();
        assert_eq!(out.len(), pts.len());
        for p in &out {
            assert!(p[1] > 0.0, "point moved to the right side: {p:?}");
            assert!(p[2].abs() < 0.1, "z {}", p[2]);
            let ang = (p[1] as f64).atan2(p[0] as f64);
            let a = (ang / step).round();
            assert!((ang - a * step).abs() < 0.01, "azimuth {ang}");
            let horiz = ((p[0] * p[0] + p[1] * p[1]) as f64).sqrt();
            assert!((horiz - radius(a)).abs() < 0.1, "radius {horiz} at angle index {a}");
        }
    }

    #[test]
    fn uniform_inclinations_when_no_table() {
        let cal = LaserCalibration {
            beam_inclination_min: Some(-0.2),
            beam_inclination_max: Some(0.2),
            ..Default::default()
        };
        let inc = row_inclinations(&cal, 4).unwrap();
        let expect = [0.15, 0.05, -0.05, -0.15];
        for (a, b) in inc.iter().zip(expect) {
            assert!((a - b).abs() < 1e-12);
        }
        assert!(row_inclinations(&LaserCalibration::default(), 4).is_err());
    }

    #[test]
    fn rejects_bad_payloads() {
        assert!(decompress(b"not zlib").is_err());
        let m = MatrixFloat { data: vec![1.0; 5], shape: Some(MatrixShape { dims: vec![2, 2, 4] }) };
        let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
        z.write_all(&m.encode_to_vec()).unwrap();
        assert!(decompress(&z.finish().unwrap()).is_err());
    }
}
