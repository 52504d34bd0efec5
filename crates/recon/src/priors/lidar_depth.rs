//! Depth prior from the scene's LiDAR: every point of the frame's sweep (ego frame) is
//! projected into the camera and z-buffered (nearest wins) at the pixel it falls in. Then two
//! conservative passes:
//!
//! * **Occlusion filter**: the LiDAR sees past foreground edges the camera cannot (it sits
//!   elsewhere), so a sample is dropped when a sample within `OCCLUSION_RADIUS` pixels is nearer
//!   by more than `OCCLUSION_REL` of its depth (costs a little true background at edges).
//! * **Gap fill**: an empty pixel is filled with the median of the samples within `FILL_RADIUS`
//!   pixels only when there are at least `FILL_MIN` of them on both sides (left and right or above
//!   and below) and their depths agree within `FILL_REL` (relative). Large holes stay empty.
//!
//! The result has a validity flag by construction (0 = no depth).

use scene::glam::DVec3;
use scene::Camera;

pub const OCCLUSION_RADIUS: i64 = 2;
pub const OCCLUSION_REL: f32 = 0.1;
pub const FILL_RADIUS: i64 = 2;
pub const FILL_MIN: usize = 2;
pub const FILL_REL: f32 = 0.05;
/// Points nearer than this along the optical axis are ignored (m).
pub const MIN_DEPTH_M: f64 = 0.5;

/// The raw z-buffered projection: z-depth per pixel, 0 where no point landed.
pub fn project(camera: &Camera, points_ego: &[[f32; 4]]) -> Vec<f32> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let cv_from_ego = camera.cv_from_ego();
    let mut depth = vec![0f32; w * h];
    for p in points_ego {
        let q = cv_from_ego.transform_point(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
        if q.z < MIN_DEPTH_M {
            continue;
        }
        let Some(uv) = camera.project_cv(q) else { continue };
        if !(uv.x >= 0.0 && uv.y >= 0.0 && uv.x < w as f64 && uv.y < h as f64) {
            continue;
        }
        let i = uv.y as usize * w + uv.x as usize;
        let z = q.z as f32;
        if depth[i] == 0.0 || z < depth[i] {
            depth[i] = z;
        }
    }
    depth
}

fn window(w: usize, h: usize, u: usize, v: usize, r: i64) -> impl Iterator<Item = (i64, i64, usize)> {
    (-r..=r).flat_map(move |dv| (-r..=r).map(move |du| (du, dv))).filter_map(move |(du, dv)| {
        let (x, y) = (u as i64 + du, v as i64 + dv);
        (x >= 0 && y >= 0 && x < w as i64 && y < h as i64 && (du, dv) != (0, 0))
            .then(|| (du, dv, y as usize * w + x as usize))
    })
}

/// Drops samples hidden behind a clearly nearer neighbour sample.
pub fn occlusion_filter(depth: &[f32], w: usize, h: usize) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            let z = depth[i];
            if z == 0.0 {
                return 0.0;
            }
            let hidden = window(w, h, i % w, i / w, OCCLUSION_RADIUS)
                .any(|(_, _, j)| depth[j] > 0.0 && depth[j] < z * (1.0 - OCCLUSION_REL));
            if hidden {
                0.0
            } else {
                z
            }
        })
        .collect()
}

/// Fills small gaps between agreeing samples (see the module comment).
pub fn fill_gaps(depth: &[f32], w: usize, h: usize) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            if depth[i] > 0.0 {
                return depth[i];
            }
            let mut vals = Vec::new();
            let (mut left, mut right, mut up, mut down) = (false, false, false, false);
            for (du, dv, j) in window(w, h, i % w, i / w, FILL_RADIUS) {
                if depth[j] > 0.0 {
                    vals.push(depth[j]);
                    left |= du < 0;
                    right |= du > 0;
                    up |= dv < 0;
                    down |= dv > 0;
                }
            }
            if vals.len() < FILL_MIN || !((left && right) || (up && down)) {
                return 0.0;
            }
            vals.sort_by(f32::total_cmp);
            let (lo, hi) = (vals[0], vals[vals.len() - 1]);
            if hi - lo > FILL_REL * lo {
                return 0.0;
            }
            vals[vals.len() / 2]
        })
        .collect()
}

/// The LiDAR depth prior of one camera image.
pub fn lidar_depth(camera: &Camera, points_ego: &[[f32; 4]]) -> Vec<f32> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let raw = project(camera, points_ego);
    fill_gaps(&occlusion_filter(&raw, w, h), w, h)
}
