//! Where a vehicle's logged box falls in an image, shared by the appearance metrics
//! (`eval_vehicle`) and the close-up and turned protocols (`protocol`), so both read the same
//! pixels. A box at its pose becomes, in a view's pixels:
//! - the convex **hull** of its projection. The box is first clipped at a plane [`NEAR_M`] in
//!   front of the camera (the corners in front, plus where the edges cross the plane), so a car
//!   right beside the camera, whose rear corners are behind it, still has the region it covers in
//!   the image: the cars a corner case brings closest are exactly those;
//! - drivestudio's axis-aligned **rectangle** around the projected (clipped) corners, the mask the
//!   Street-Gaussians and OmniRe literature scores dynamic objects on.
//!
//! Masks set the pixels whose centres lie inside (`fill_hull`'s rule). The hull's area inside the
//! image is computed exactly (the polygon clipped to the image rectangle), so a selection rule can
//! be stated at the camera's stored size whatever the scale a model was trained at.

use crate::priors::objects::{fill_hull, hull};
use scene::frames::box_corners;
use scene::glam::{DVec2, DVec3};
use scene::Transform3;

/// The clipping plane's distance in front of the camera (m).
pub const NEAR_M: f64 = 0.1;

/// A box's region in one view's pixels (pixel centres at integer + 0.5).
#[derive(Clone, Debug, PartialEq)]
pub struct Region {
    /// The hull of the projected, near-clipped box (counter-clockwise in image axes).
    pub hull: Vec<DVec2>,
    /// `[x0, y0, x1, y1]` of the projected corners, not clipped to the image.
    pub rect: [f64; 4],
}

/// A point of the camera frame (OpenCV axes) in pixels.
fn pixel(cam: &splat::Camera, q: DVec3) -> DVec2 {
    DVec2::new(cam.fx * q.x / q.z + cam.cx, cam.fy * q.y / q.z + cam.cy)
}

/// The region of a box of size `size_lwh` at `world_from_box` in `cam`, or `None` when no part of
/// it is in front of the clipping plane.
pub fn project_box(cam: &splat::Camera, world_from_box: &Transform3, size_lwh: [f64; 3]) -> Option<Region> {
    let corners = box_corners(size_lwh).map(|k| {
        let p = world_from_box.transform_point(k);
        DVec3::from(cam.to_camera(p.into()))
    });
    if corners.iter().any(|c| !c.is_finite()) {
        return None;
    }
    let mut kept: Vec<DVec3> = corners.iter().copied().filter(|c| c.z >= NEAR_M).collect();
    if kept.is_empty() {
        return None;
    }
    // The 12 edges join corners that differ in one bit of their index (`box_corners`).
    for i in 0..8usize {
        for bit in [1usize, 2, 4] {
            let j = i | bit;
            if j == i {
                continue;
            }
            let (a, b) = (corners[i], corners[j]);
            if (a.z >= NEAR_M) != (b.z >= NEAR_M) {
                let s = (NEAR_M - a.z) / (b.z - a.z);
                kept.push(a + (b - a) * s);
            }
        }
    }
    let px: Vec<DVec2> = kept.iter().map(|q| pixel(cam, *q)).collect();
    let (lo, hi) = px.iter().fold((DVec2::splat(f64::MAX), DVec2::splat(f64::MIN)), |(a, b), p| (a.min(*p), b.max(*p)));
    let hull = hull(px);
    (hull.len() >= 3).then_some(Region { hull, rect: [lo.x, lo.y, hi.x, hi.y] })
}

impl Region {
    /// The hull's pixels in a `width x height` image.
    pub fn hull_mask(&self, width: usize, height: usize) -> Vec<bool> {
        let mut m = vec![false; width * height];
        fill_hull(&self.hull, width, height, &mut m);
        m
    }

    /// Sets the rectangle's pixels (centres inside it) in `mask`, a `width x height` image.
    pub fn fill_rect(&self, width: usize, height: usize, mask: &mut [bool]) {
        let [x0, y0, x1, y1] = self.rect;
        // Pixel u's centre u + 0.5 lies in [x0, x1] for u in [ceil(x0 - 0.5), floor(x1 - 0.5)].
        let range = |a: f64, b: f64, n: usize| {
            let lo = (a - 0.5).ceil().clamp(0.0, n as f64);
            let hi = ((b - 0.5).floor() + 1.0).clamp(lo, n as f64);
            (lo as usize, hi as usize)
        };
        let ((u0, u1), (v0, v1)) = (range(x0, x1, width), range(y0, y1, height));
        for v in v0..v1 {
            mask[v * width + u0..v * width + u1].iter_mut().for_each(|m| *m = true);
        }
    }

    /// The rectangle's pixels in a `width x height` image.
    pub fn rect_mask(&self, width: usize, height: usize) -> Vec<bool> {
        let mut m = vec![false; width * height];
        self.fill_rect(width, height, &mut m);
        m
    }

    /// The hull's area (pixels^2) inside the `width x height` image rectangle.
    pub fn area_in_image(&self, width: f64, height: f64) -> f64 {
        let clipped = clip_to_rect(&self.hull, width, height);
        let n = clipped.len();
        (0..n).map(|i| clipped[i].perp_dot(clipped[(i + 1) % n])).sum::<f64>().abs() * 0.5
    }
}

/// Sutherland-Hodgman: the convex polygon `poly` clipped to `[0, w] x [0, h]`.
fn clip_to_rect(poly: &[DVec2], w: f64, h: f64) -> Vec<DVec2> {
    // Each edge of the rectangle as (inside test value, i.e. signed distance).
    let planes: [&dyn Fn(DVec2) -> f64; 4] = [&|p| p.x, &|p| w - p.x, &|p| p.y, &|p| h - p.y];
    let mut out = poly.to_vec();
    for d in planes {
        if out.is_empty() {
            break;
        }
        let input = std::mem::take(&mut out);
        for i in 0..input.len() {
            let (a, b) = (input[i], input[(i + 1) % input.len()]);
            let (da, db) = (d(a), d(b));
            if da >= 0.0 {
                out.push(a);
            }
            if (da >= 0.0) != (db >= 0.0) {
                out.push(a + (b - a) * (da / (da - db)));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A camera at the origin looking along world +x (OpenCV: x right = world -y, y down = -z).
    fn cam() -> splat::Camera {
        splat::Camera {
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
        }
    }

    #[test]
    fn a_box_ahead_has_its_projected_hull_and_rectangle() {
        let pose = scene::frames::world_from_box(DVec3::new(10.0, 0.0, 0.0), 0.0);
        let r = project_box(&cam(), &pose, [4.0, 2.0, 1.5]).unwrap();
        // The near face (x = 8) spans y in [-1, 1], z in [-0.75, 0.75]: 40 / 8 = 5 px a metre.
        assert!((r.rect[0] - 27.0).abs() < 1e-9 && (r.rect[2] - 37.0).abs() < 1e-9, "{:?}", r.rect);
        assert!((r.rect[1] - 20.25).abs() < 1e-9 && (r.rect[3] - 27.75).abs() < 1e-9, "{:?}", r.rect);
        // Seen end-on the hull is the near face: 10 x 7.5 px.
        assert!((r.area_in_image(64.0, 48.0) - 75.0).abs() < 1e-9);
        let (h, rect) = (r.hull_mask(64, 48), r.rect_mask(64, 48));
        let count = |m: &[bool]| m.iter().filter(|x| **x).count();
        // Centres 27.5..36.5 (10 columns) and 20.5..27.5 (8 rows).
        assert_eq!(count(&rect), 80);
        assert!(h.iter().zip(&rect).all(|(a, b)| !a || *b));
        // Behind the camera: nothing.
        let behind = scene::frames::world_from_box(DVec3::new(-10.0, 0.0, 0.0), 0.0);
        assert!(project_box(&cam(), &behind, [4.0, 2.0, 1.5]).is_none());
    }

    #[test]
    fn a_box_beside_the_camera_is_clipped_not_dropped() {
        // A car 2.5 m to the left whose rear is behind the camera plane: its front half is in view.
        let pose = scene::frames::world_from_box(DVec3::new(1.0, 2.5, 0.0), 0.0);
        let r = project_box(&cam(), &pose, [4.5, 1.8, 1.5]).expect("the front half is in front");
        // It reaches the image's left edge and far beyond it (the clipped corners are close).
        assert!(r.rect[0] < -100.0, "{:?}", r.rect);
        let inside = r.area_in_image(64.0, 48.0);
        assert!(inside > 0.0 && inside <= 64.0 * 48.0, "{inside}");
        // Every clipped vertex is finite and the mask is not empty.
        assert!(r.hull.iter().all(|p| p.is_finite()));
        assert!(r.hull_mask(64, 48).iter().any(|x| *x));
    }

    #[test]
    fn clipping_keeps_the_area_inside_the_image() {
        let sq =
            vec![DVec2::new(-10.0, -10.0), DVec2::new(10.0, -10.0), DVec2::new(10.0, 10.0), DVec2::new(-10.0, 10.0)];
        let r = Region { hull: sq, rect: [-10.0, -10.0, 10.0, 10.0] };
        assert!((r.area_in_image(64.0, 48.0) - 100.0).abs() < 1e-9);
        assert!((r.area_in_image(5.0, 48.0) - 50.0).abs() < 1e-9);
        let m = r.rect_mask(64, 48);
        // Pixel centres 0.5..9.5 in both axes.
        assert_eq!(m.iter().filter(|x| **x).count(), 100);
        // Rectangles wholly beside the image on any side cover nothing.
        for rect in [[70.0, 5.0, 90.0, 9.0], [-30.0, 5.0, -2.0, 9.0], [5.0, 60.0, 9.0, 90.0], [5.0, -9.0, 9.0, -1.0]] {
            let r = Region { hull: vec![], rect };
            assert!(!r.rect_mask(64, 48).iter().any(|x| *x), "{rect:?}");
        }
    }
}
