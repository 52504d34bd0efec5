//! Ground plane per image by RANSAC in the **ego frame** (z up), on back-projected valid depth.
//!
//! Candidates come from three random points (ChaCha8 seeded per image from `--seed`, frame and
//! camera, so the result does not depend on the order of work). A candidate counts only if it is
//! near-horizontal (normal within `MAX_TILT_DEG` of ego +z) and below the camera by at least
//! `MIN_DROP_M`; its score is the number of points within `INLIER_M` of it. The best one is
//! refined by least squares (`z = a x + b y + c`) on its inliers. The ground mask is every pixel
//! whose 3D point lies within `INLIER_M` of the plane.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use scene::glam::DVec3;
use scene::Transform3;
use serde::{Deserialize, Serialize};

pub const INLIER_M: f64 = 0.1;
pub const MAX_TILT_DEG: f64 = 15.0;
pub const MIN_DROP_M: f64 = 0.5;
pub const ITERATIONS: usize = 300;
/// At most this many points take part in the RANSAC scoring (every k-th valid pixel).
pub const MAX_POINTS: usize = 20_000;

/// A plane `normal . p = offset` in the ego frame (unit normal pointing up).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Plane {
    pub normal_ego: [f64; 3],
    pub offset_m: f64,
    /// Height of the camera above the plane (m).
    pub camera_height_m: f64,
    /// Fraction of the scored points within `INLIER_M`.
    pub inlier_fraction: f64,
}

fn plane_of(a: DVec3, b: DVec3, c: DVec3) -> Option<(DVec3, f64)> {
    let n = (b - a).cross(c - a);
    let l = n.length();
    if l < 1e-9 {
        return None;
    }
    let n = if n.z < 0.0 { -n / l } else { n / l };
    Some((n, n.dot(a)))
}

/// Least-squares `z = a x + b y + c` through `pts`.
fn refine(pts: &[DVec3]) -> Option<(DVec3, f64)> {
    let (mut m, mut r) = ([[0.0f64; 3]; 3], [0.0f64; 3]);
    for p in pts {
        let row = [p.x, p.y, 1.0];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += row[i] * row[j];
            }
            r[i] += row[i] * p.z;
        }
    }
    let mat = scene::glam::DMat3::from_cols_array_2d(&m).transpose();
    if mat.determinant().abs() < 1e-9 {
        return None;
    }
    let s = mat.inverse() * DVec3::from(r);
    let n = DVec3::new(-s.x, -s.y, 1.0);
    let l = n.length();
    Some((n / l, s.z / l))
}

/// Fits the ground plane to ego-frame points; `camera_ego` is the camera's position.
pub fn fit(points_ego: &[DVec3], camera_ego: DVec3, seed: u64) -> Option<Plane> {
    if points_ego.len() < 3 {
        return None;
    }
    let stride = points_ego.len().div_ceil(MAX_POINTS);
    let pts: Vec<DVec3> = points_ego.iter().step_by(stride).copied().collect();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let cos_tilt = MAX_TILT_DEG.to_radians().cos();
    let mut best: Option<(usize, DVec3, f64)> = None;
    for _ in 0..ITERATIONS {
        let pick = |rng: &mut ChaCha8Rng| pts[rng.random_range(0..pts.len())];
        let Some((n, off)) = plane_of(pick(&mut rng), pick(&mut rng), pick(&mut rng)) else { continue };
        if n.z < cos_tilt || n.dot(camera_ego) - off < MIN_DROP_M {
            continue;
        }
        let count = pts.iter().filter(|p| (n.dot(**p) - off).abs() <= INLIER_M).count();
        if best.is_none_or(|b| count > b.0) {
            best = Some((count, n, off));
        }
    }
    let (_, n, off) = best?;
    let inliers: Vec<DVec3> = pts.iter().filter(|p| (n.dot(**p) - off).abs() <= INLIER_M).copied().collect();
    let (n, off) = refine(&inliers).filter(|(rn, _)| rn.z >= cos_tilt).unwrap_or((n, off));
    let count = pts.iter().filter(|p| (n.dot(**p) - off).abs() <= INLIER_M).count();
    Some(Plane {
        normal_ego: n.to_array(),
        offset_m: off,
        camera_height_m: n.dot(camera_ego) - off,
        inlier_fraction: count as f64 / pts.len() as f64,
    })
}

/// Pixels whose OpenCV-camera point lies within `INLIER_M` of the plane.
pub fn mask(points_cv: &[Option<DVec3>], ego_from_cv: &Transform3, plane: &Plane) -> Vec<bool> {
    let n = DVec3::from_array(plane.normal_ego);
    points_cv
        .iter()
        .map(|p| p.is_some_and(|p| (n.dot(ego_from_cv.transform_point(p)) - plane.offset_m).abs() <= INLIER_M))
        .collect()
}
