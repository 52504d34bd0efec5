//! Object masks: pixels inside the projected 3D boxes of the tracks (vehicles, pedestrians,
//! cyclists) valid at a frame. A box counts only when all eight corners are in front of the
//! camera; its mask is the convex hull of the eight projected corners (pixel centres inside).

use scene::frames::{box_corners, world_from_box};
use scene::glam::DVec2;
use scene::{Camera, ObjectClass, Scene, Transform3};

/// Convex hull (counter-clockwise in pixel coordinates) by the monotone chain.
pub fn hull(mut pts: Vec<DVec2>) -> Vec<DVec2> {
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut out: Vec<DVec2> = Vec::new();
    for pass in 0..2 {
        let start = out.len();
        let iter: Box<dyn Iterator<Item = &DVec2>> =
            if pass == 0 { Box::new(pts.iter()) } else { Box::new(pts.iter().rev()) };
        for &p in iter {
            while out.len() >= start + 2 && cross(out[out.len() - 2], out[out.len() - 1], p) <= 0.0 {
                out.pop();
            }
            out.push(p);
        }
        out.pop();
    }
    out
}

/// Sets the pixels of a `w x h` mask whose centres lie inside the convex polygon `poly`.
pub fn fill_hull(poly: &[DVec2], w: usize, h: usize, mask: &mut [bool]) {
    if poly.len() < 3 {
        return;
    }
    let (lo, hi) =
        poly.iter().fold((DVec2::splat(f64::MAX), DVec2::splat(f64::MIN)), |(a, b), p| (a.min(*p), b.max(*p)));
    let (u0, u1) = (lo.x.floor().max(0.0) as usize, (hi.x.ceil().max(0.0) as usize).min(w));
    let (v0, v1) = (lo.y.floor().max(0.0) as usize, (hi.y.ceil().max(0.0) as usize).min(h));
    for v in v0..v1 {
        for u in u0..u1 {
            let c = DVec2::new(u as f64 + 0.5, v as f64 + 0.5);
            let inside = (0..poly.len()).all(|k| (poly[(k + 1) % poly.len()] - poly[k]).perp_dot(c - poly[k]) >= 0.0);
            if inside {
                mask[v * w + u] = true;
            }
        }
    }
}

/// The object mask of `camera` at `frame` (with the frame's `world_from_ego`).
pub fn object_mask(scene: &Scene, frame: usize, camera: &Camera, world_from_ego: &Transform3) -> Vec<bool> {
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut mask = vec![false; w * h];
    let cv_from_world = camera.cv_from_ego() * world_from_ego.inverse();
    for t in &scene.tracks {
        if !matches!(t.class, ObjectClass::Vehicle | ObjectClass::Pedestrian | ObjectClass::Cyclist) {
            continue;
        }
        let Some(s) = t.state_at(frame) else { continue };
        let cv_from_box = cv_from_world * world_from_box(s.center, s.heading);
        let corners: Option<Vec<DVec2>> =
            box_corners(s.size_lwh).iter().map(|c| camera.project_cv(cv_from_box.transform_point(*c))).collect();
        if let Some(c) = corners {
            fill_hull(&hull(c), w, h, &mut mask);
        }
    }
    mask
}
