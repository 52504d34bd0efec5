//! Actor mask IoU on real logs, which have no instance masks: each **moving vehicle**'s rendered
//! silhouette (its actor drawn alone, alpha > 0.5) against the convex hull of its logged 3D box
//! projected into the held-out view. A car fills most but not all of its box's hull (the hull of a
//! box seen at an angle includes the air over the bonnet and around the roof), so a perfect model
//! scores below 1: about 0.8 to 0.9 for a car seen from behind or the side. It measures what the
//! paper's actor IoU is for: a moving car rendered where the log has it, whole and not smeared.
//! A vehicle counts as moving at a frame when the log labels it `Moving` there, or, without labels,
//! when its speed is above [`MOVING_SPEED`]. Boxes with a corner behind the camera or fewer than
//! [`MIN_PIXELS`] pixels in the image are skipped.

use crate::backend::Backend;
use crate::compose::Layers;
use crate::data::View;
use crate::metrics::iou;
use crate::model::SceneModel;
use crate::priors::objects::{fill_hull, hull};
use crate::view::draw;
use scene::frames::{box_corners, world_from_box};
use scene::glam::DVec2;
use scene::{LoggedMotion, ObjectClass, Scene, TrackState};

/// Speed above which an unlabelled vehicle counts as moving (m/s).
pub const MOVING_SPEED: f64 = 1.0;
/// A box must cover at least this many pixels of the view to be scored.
pub const MIN_PIXELS: usize = 50;

fn moving(s: &TrackState) -> bool {
    match s.motion {
        Some(m) => m == LoggedMotion::Moving,
        None => s.velocity.is_some_and(|v| v.truncate().length() > MOVING_SPEED),
    }
}

/// The hull mask of a box state in the view's camera, if every corner is in front.
fn box_mask(v: &View, s: &TrackState) -> Option<Vec<bool>> {
    let c = &v.cam;
    let m = &c.camera_from_world;
    let world_from_b = world_from_box(s.center, s.heading);
    let px: Option<Vec<DVec2>> = box_corners(s.size_lwh)
        .iter()
        .map(|k| {
            let p = world_from_b.transform_point(*k);
            let q: [f64; 3] = std::array::from_fn(|r| m[r][0] * p.x + m[r][1] * p.y + m[r][2] * p.z + m[r][3]);
            (q[2] > 0.1).then(|| DVec2::new(c.fx * q[0] / q[2] + c.cx, c.fy * q[1] / q[2] + c.cy))
        })
        .collect();
    let (w, h) = (v.width(), v.height());
    let mut mask = vec![false; w * h];
    fill_hull(&hull(px?), w, h, &mut mask);
    Some(mask)
}

/// (track id, IoU) for every moving vehicle of the model seen in view `v` (see the module comment).
pub fn moving_vehicle_iou<B: Backend>(backend: &B, model: &SceneModel, scene: &Scene, v: &View) -> Vec<(String, f64)> {
    let mut out = Vec::new();
    for (ai, actor) in model.actors.iter().enumerate() {
        let Some(track) = scene.track(&actor.track_id) else { continue };
        if track.class != ObjectClass::Vehicle {
            continue;
        }
        let Some(state) = track.state_at(v.frame).filter(|s| moving(s)) else { continue };
        let Some(truth) = box_mask(v, state) else { continue };
        if truth.iter().filter(|x| **x).count() < MIN_PIXELS {
            continue;
        }
        let alone = draw(backend, model, scene, &v.cam, v.time, Layers::ActorsOnly, &|i| (i != ai).then_some(None));
        let mask: Vec<bool> = alone.alpha.iter().map(|a| *a > 0.5).collect();
        if let Some(x) = iou(&mask, &truth) {
            out.push((actor.track_id.clone(), x));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::glam::DVec3;

    #[test]
    fn a_box_straight_ahead_fills_its_hull() {
        let cam = splat::Camera {
            width: 64,
            height: 48,
            fx: 40.0,
            fy: 40.0,
            cx: 32.0,
            cy: 24.0,
            camera_from_world: [
                [0.0, -1.0, 0.0, 0.0],
                [0.0, 0.0, -1.0, 0.0],
                [1.0, 0.0, 0.0, 0.0],
                [0.0, 0.0, 0.0, 1.0],
            ],
            near: 0.01,
            far: 1e4,
        };
        let v = View { frame: 0, camera: "C".into(), time: 0.0, cam, targets: Default::default(), held_out: true };
        let s = TrackState {
            frame: 0,
            center: DVec3::new(10.0, 0.0, 0.0),
            heading: 0.0,
            size_lwh: [4.0, 2.0, 1.5],
            velocity: None,
            valid: true,
            motion: Some(LoggedMotion::Moving),
        };
        let m = box_mask(&v, &s).unwrap();
        // The rear face spans 2 m x 1.5 m at 8 m: 10 x 7.5 px; the hull (front face too) is
        // larger, the far face at 12 m smaller: between the two.
        let n = m.iter().filter(|x| **x).count();
        assert!((70..=90).contains(&n), "{n} pixels");
        assert!(m[24 * 64 + 32], "the box centre is inside");
        assert!(moving(&s));
        // Behind the camera: no mask.
        let behind = TrackState { center: DVec3::new(-10.0, 0.0, 0.0), ..s };
        assert!(box_mask(&v, &behind).is_none());
    }
}
