//! Is the adversary drawn where the executed trajectory says? The box at the back-projected pose
//! is projected into a camera (the convex hull of its eight corners, filled) and compared, as
//! intersection over union, with the alpha mask of a render of that one actor alone. The videos
//! of `run` carry this check at a few frames (in `metrics.json`) and the tests assert it.
//!
//! The box hull is larger than the vehicle's silhouette (wheels, cabin, rounded corners), so a
//! correct placement reads about 0.8 to 0.95 on the synthetic street's box-like vehicles, a
//! placement off by a vehicle width well below 0.5. A real car fills only about two thirds of
//! its box's hull (measured on PandaSet 002: 0.64 to 0.69 for a well-reconstructed car seen
//! from behind), so a second IoU is taken against the vehicle's two-box profile
//! (`scene::frames::vehicle_profile_corners`: lower body and cabin), which a real car fills.

use crate::asset::align::convex_hull;
use crate::backproject::Backprojection;
use crate::canvas::Canvas;
use crate::RenderError;
use recon::backend::Backend;
use recon::compose::Layers;
use recon::pose::BoxPose;
use recon::SceneModel;
use scene::frames::{box_corners, vehicle_profile_corners};
use scene::Scene;
use serde::{Deserialize, Serialize};

/// Alpha above which a pixel counts as covered by the actor.
pub const ALPHA_COVERED: f64 = 0.5;
/// Fewer box pixels than this in the image: too small to judge.
pub const MIN_BOX_PIXELS: usize = 40;

/// One placement check.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Placement {
    pub t: f64,
    pub camera: String,
    pub iou: f64,
    pub box_pixels: usize,
    pub drawn_pixels: usize,
    /// How far the drawn pose is from the logged box then (m); `None` where the log has none.
    pub offset_from_log_m: Option<f64>,
    /// IoU against the vehicle's two-box profile instead of its box's hull (see the module).
    #[serde(default)]
    pub profile_iou: Option<f64>,
}

/// The pixels (row-major, `width x height`) whose centres fall inside the projected box, or
/// `None` when a corner is behind the camera's near plane.
pub fn box_mask(cam: &splat::Camera, pose: &BoxPose, size_lwh: [f64; 3]) -> Option<Vec<bool>> {
    corners_mask(cam, pose, &box_corners(size_lwh))
}

/// The union of the masks of the two boxes of the vehicle's profile, or `None` as [`box_mask`].
pub fn profile_mask(cam: &splat::Camera, pose: &BoxPose, size_lwh: [f64; 3]) -> Option<Vec<bool>> {
    let [a, b] = vehicle_profile_corners(size_lwh);
    let (a, b) = (corners_mask(cam, pose, &a)?, corners_mask(cam, pose, &b)?);
    Some(a.iter().zip(&b).map(|(x, y)| *x || *y).collect())
}

/// The pixels inside the convex hull of box-frame points `corners` projected at `pose`.
fn corners_mask(cam: &splat::Camera, pose: &BoxPose, corners: &[scene::glam::DVec3]) -> Option<Vec<bool>> {
    let world_from_box = pose.world_from_box();
    let m = &cam.camera_from_world;
    let mut pts = Vec::with_capacity(8);
    for &c in corners {
        let w = world_from_box.transform_point(c).to_array();
        let p: [f64; 3] = std::array::from_fn(|r| m[r][0] * w[0] + m[r][1] * w[1] + m[r][2] * w[2] + m[r][3]);
        if p[2] <= cam.near.max(0.05) {
            return None;
        }
        pts.push([cam.fx * p[0] / p[2] + cam.cx, cam.fy * p[1] / p[2] + cam.cy]);
    }
    let hull = convex_hull(&pts);
    let (w, h) = (cam.width as usize, cam.height as usize);
    let inside = |x: f64, y: f64| {
        hull.len() >= 3
            && (0..hull.len()).all(|i| {
                let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
                (b[0] - a[0]) * (y - a[1]) - (b[1] - a[1]) * (x - a[0]) >= 0.0
            })
    };
    Some((0..w * h).map(|i| inside((i % w) as f64 + 0.5, (i / w) as f64 + 0.5)).collect())
}

/// Intersection over union of two masks.
pub fn iou(a: &[bool], b: &[bool]) -> f64 {
    let (mut inter, mut union) = (0usize, 0usize);
    for (&x, &y) in a.iter().zip(b) {
        inter += (x && y) as usize;
        union += (x || y) as usize;
    }
    if union == 0 {
        0.0
    } else {
        inter as f64 / union as f64
    }
}

/// A picture of one check: the actor's render, with pixels only in the box tinted red, pixels
/// only drawn tinted green, and both yellow.
pub fn overlay(width: usize, height: usize, rgb: &[[f64; 3]], boxed: &[bool], drawn: &[bool]) -> Canvas {
    let mut c = Canvas::from_rgb_f64(width, height, rgb);
    for i in 0..width * height {
        let tint = match (boxed[i], drawn[i]) {
            (true, true) => [230, 200, 40],
            (true, false) => [220, 40, 40],
            (false, true) => [40, 200, 60],
            (false, false) => continue,
        };
        for (v, t) in c.rgb[i * 3..i * 3 + 3].iter_mut().zip(tint) {
            *v = ((*v as u16 + t as u16) / 2) as u8;
        }
    }
    c
}

/// Checks the adversary's placement at time `t` in camera `camera` (at `scale` of its size).
/// `Ok(None)` when it cannot be judged then: not drawn, behind the camera, or too small.
/// With `picture`, the [`overlay`] of the check is returned too.
#[allow(clippy::too_many_arguments)]
pub fn check<B: Backend>(
    backend: &B,
    model: &SceneModel,
    scene: &Scene,
    adversary: &Backprojection,
    camera: &str,
    t: f64,
    scale: f64,
) -> Result<Option<(Placement, Canvas)>, RenderError> {
    let actor = crate::video::actor_index(model, &adversary.track_id)?;
    let Some(pose) = adversary.pose_at(scene, t) else { return Ok(None) };
    let cam = crate::video::camera_at(scene, camera, t, scale)?;
    let size = model.actors[actor].size_lwh;
    let Some(boxed) = box_mask(&cam, &pose, size) else { return Ok(None) };
    let box_pixels = boxed.iter().filter(|&&b| b).count();
    if box_pixels < MIN_BOX_PIXELS {
        return Ok(None);
    }
    let only = |i: usize| Some(if i == actor { Some(pose) } else { None });
    let drawn = recon::view::draw(backend, model, scene, &cam, t, Layers::ActorsOnly, &only);
    let mask: Vec<bool> = drawn.alpha.iter().map(|&a| a > ALPHA_COVERED).collect();
    let picture = overlay(drawn.width, drawn.height, &drawn.rgb, &boxed, &mask);
    let p = Placement {
        t,
        camera: camera.to_string(),
        iou: iou(&boxed, &mask),
        box_pixels,
        drawn_pixels: mask.iter().filter(|&&b| b).count(),
        offset_from_log_m: adversary.offset_from_log_m(scene, t),
        profile_iou: profile_mask(&cam, &pose, size).map(|m| iou(&m, &mask)),
    };
    Ok(Some((p, picture)))
}

/// The placement check at `t` in the camera that sees the most of the adversary's box (`None`
/// when no camera can judge it then).
pub fn check_best_camera<B: Backend>(
    backend: &B,
    model: &SceneModel,
    scene: &Scene,
    adversary: &Backprojection,
    t: f64,
    scale: f64,
) -> Result<Option<(Placement, Canvas)>, RenderError> {
    let Some(pose) = adversary.pose_at(scene, t) else { return Ok(None) };
    let size = model.actors[crate::video::actor_index(model, &adversary.track_id)?].size_lwh;
    let mut best: Option<(usize, &str)> = None;
    for cam in &scene.cameras {
        let c = crate::video::camera_at(scene, &cam.name, t, scale)?;
        let n = box_mask(&c, &pose, size).map_or(0, |m| m.iter().filter(|&&b| b).count());
        if n >= MIN_BOX_PIXELS && best.is_none_or(|(m, _)| n > m) {
            best = Some((n, &cam.name));
        }
    }
    match best {
        Some((_, name)) => check(backend, model, scene, adversary, name, t, scale),
        None => Ok(None),
    }
}

/// Times to check a case at: `n` evenly over the corner case (plan start to the last executed
/// step) and the time the drawn adversary is farthest from its logged box (sampled at 10 Hz).
pub fn check_times(scene: &Scene, adversary: &Backprojection, plan_start: f64, n: usize) -> Vec<f64> {
    let (_, end) = adversary.executed_span();
    let start = plan_start.min(end);
    let mut times: Vec<f64> =
        (0..n).map(|k| if n == 1 { end } else { start + (end - start) * k as f64 / (n - 1) as f64 }).collect();
    let samples = ((end - start) * 10.0).ceil().max(0.0) as usize;
    let far = (0..=samples)
        .map(|k| (start + k as f64 * 0.1).min(end))
        .filter_map(|t| adversary.offset_from_log_m(scene, t).map(|d| (t, d)))
        .max_by(|a, b| a.1.total_cmp(&b.1));
    if let Some((t, _)) = far {
        times.push(t);
    }
    times.sort_by(f64::total_cmp);
    times.dedup_by(|a, b| (*a - *b).abs() < 1e-6);
    times
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hull_of_a_square_with_an_inner_point() {
        let h = convex_hull(&[[0.0, 0.0], [2.0, 0.0], [1.0, 1.0], [2.0, 2.0], [0.0, 2.0]]);
        assert_eq!(h.len(), 4, "{h:?}");
        assert!(!h.contains(&[1.0, 1.0]));
    }

    #[test]
    fn iou_counts_overlap() {
        assert_eq!(iou(&[true, true, false], &[true, false, false]), 0.5);
        assert_eq!(iou(&[false], &[false]), 0.0);
    }
}
