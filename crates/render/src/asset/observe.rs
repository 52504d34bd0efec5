//! What one camera image sees of a tracked box: how close the camera is, from which side it looks
//! and how many pixels the box covers. The harvest (`harvest`) adds these up over the training
//! images of a log to tell which vehicles the log saw well, and the demo compares the closest
//! approach of a corner case with the log's through the same function, so both sides of that
//! comparison measure the same thing.
//!
//! * distance: from the camera centre to the nearest point of the box (0 inside it). The nearest
//!   point, not the centre: a 5 m car passing 1 m beside a camera is 1 m away, not 2.9 m, and
//!   that is what decides how large its Gaussians are drawn.
//! * azimuth: the direction of the camera seen from the box centre, in the box frame (x forward,
//!   y left), `atan2(y, x)` in (-pi, pi]: 0 means the camera looks at the vehicle's front, +-pi at
//!   its back, +pi/2 at its left side. Binned into [`AZIMUTH_BINS`] sectors of 30 degrees.
//! * hull: the convex hull of the box's projection, clipped to the image, in pixels of the
//!   camera's size. A box reaching behind the camera is first cut at the near plane (the hull of
//!   the corners in front and of the points where box segments cross the plane), so a vehicle
//!   right beside the camera still counts with the part the camera sees.
//!
//! A box is in view when some of it is in front of the near plane and its hull covers part of
//! the image.

use crate::asset::align::convex_hull;
use recon::pose::BoxPose;
use scene::frames::box_corners;
use scene::glam::DVec3;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// Sectors of azimuth (30 degrees each).
pub const AZIMUTH_BINS: usize = 12;

/// One camera image's view of a box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Observation {
    /// From the camera centre to the nearest point of the box (m; 0 inside it).
    pub distance_m: f64,
    /// The camera's direction from the box centre in the box frame (rad, (-pi, pi]; 0: the
    /// vehicle's front is seen, +-pi its back, +pi/2 its left side).
    pub azimuth_rad: f64,
    /// Area of the box's projected hull inside the image (pixels).
    pub hull_px: f64,
}

/// Distance from `p` (box frame) to the nearest point of a centred box of `size_lwh`.
pub fn distance_to_box(p: DVec3, size_lwh: [f64; 3]) -> f64 {
    let out = |v: f64, s: f64| (v.abs() - s / 2.0).max(0.0);
    DVec3::new(out(p.x, size_lwh[0]), out(p.y, size_lwh[1]), out(p.z, size_lwh[2])).length()
}

/// The camera centre of `cam` in the frame of the box at `pose`.
pub fn camera_in_box(cam: &splat::Camera, pose: &BoxPose) -> DVec3 {
    pose.world_from_box().inverse().transform_point(DVec3::from(cam.center()))
}

/// Camera `cam`'s view of a box of `size_lwh` at `pose`, or `None` when it is not in view (all
/// of it behind the near plane, or its hull outside the image).
pub fn observe(cam: &splat::Camera, pose: &BoxPose, size_lwh: [f64; 3]) -> Option<Observation> {
    let world_from_box = pose.world_from_box();
    let corners: Vec<[f64; 3]> =
        box_corners(size_lwh).iter().map(|&c| cam.to_camera(world_from_box.transform_point(c).to_array())).collect();
    let hull_px = clipped_hull_area(cam, &corners);
    if hull_px.is_nan() || hull_px <= 0.0 {
        return None;
    }
    let c = camera_in_box(cam, pose);
    Some(Observation { distance_m: distance_to_box(c, size_lwh), azimuth_rad: c.y.atan2(c.x), hull_px })
}

/// Area inside the image of the hull of the projection of the convex body spanned by
/// `points_cam` (camera axes), cut at the near plane.
fn clipped_hull_area(cam: &splat::Camera, points_cam: &[[f64; 3]]) -> f64 {
    let near = cam.near.max(1e-3);
    let project = |p: [f64; 3]| [cam.fx * p[0] / p[2] + cam.cx, cam.fy * p[1] / p[2] + cam.cy];
    let mut pts = Vec::with_capacity(points_cam.len() * 2);
    for (i, &a) in points_cam.iter().enumerate() {
        if a[2] > near {
            pts.push(project(a));
        }
        // Every pair, not only the box's edges: a segment between two points of a convex body
        // lies in it, so the extra crossings fall inside the cut body's hull and change nothing.
        for &b in &points_cam[i + 1..] {
            if (a[2] > near) != (b[2] > near) {
                let w = (near - a[2]) / (b[2] - a[2]);
                pts.push(project([a[0] + w * (b[0] - a[0]), a[1] + w * (b[1] - a[1]), near]));
            }
        }
    }
    if pts.iter().any(|p| !(p[0].is_finite() && p[1].is_finite())) {
        return 0.0;
    }
    let hull = convex_hull(&pts);
    polygon_area(&clip_to_rect(&hull, cam.width as f64, cam.height as f64))
}

/// Sutherland-Hodgman clipping of a convex polygon to `[0, w] x [0, h]`.
fn clip_to_rect(poly: &[[f64; 2]], w: f64, h: f64) -> Vec<[f64; 2]> {
    // (axis, bound, keep the side below the bound)
    let edges = [(0, 0.0, false), (0, w, true), (1, 0.0, false), (1, h, true)];
    let mut out = poly.to_vec();
    for (axis, bound, below) in edges {
        if out.len() < 3 {
            return vec![];
        }
        let inside = |p: &[f64; 2]| if below { p[axis] <= bound } else { p[axis] >= bound };
        let input = std::mem::take(&mut out);
        for i in 0..input.len() {
            let (a, b) = (input[i], input[(i + 1) % input.len()]);
            let cross = |a: [f64; 2], b: [f64; 2]| {
                let t = (bound - a[axis]) / (b[axis] - a[axis]);
                [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]
            };
            match (inside(&a), inside(&b)) {
                (true, true) => out.push(b),
                (true, false) => out.push(cross(a, b)),
                (false, true) => {
                    out.push(cross(a, b));
                    out.push(b);
                }
                (false, false) => {}
            }
        }
    }
    out
}

/// Area of a simple polygon (shoelace).
fn polygon_area(poly: &[[f64; 2]]) -> f64 {
    if poly.len() < 3 {
        return 0.0;
    }
    let twice: f64 = (0..poly.len())
        .map(|i| {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            a[0] * b[1] - b[0] * a[1]
        })
        .sum();
    twice.abs() / 2.0
}

/// The azimuth sector of `azimuth_rad` (0 for [-180, -150) degrees, ..., 11 for [150, 180]).
pub fn azimuth_bin(azimuth_rad: f64) -> usize {
    let width = 2.0 * PI / AZIMUTH_BINS as f64;
    (((azimuth_rad + PI) / width).floor().max(0.0) as usize).min(AZIMUTH_BINS - 1)
}

/// The smallest arc (rad) holding every azimuth: 2 pi less the largest gap between neighbours
/// around the circle (0 for one direction or none).
pub fn azimuth_span(azimuths_rad: &[f64]) -> f64 {
    let mut a: Vec<f64> = azimuths_rad.iter().map(|&x| x.rem_euclid(2.0 * PI)).collect();
    if a.len() < 2 {
        return 0.0;
    }
    a.sort_by(f64::total_cmp);
    let wrap_gap = a[0] + 2.0 * PI - a[a.len() - 1];
    let gap = a.windows(2).map(|w| w[1] - w[0]).fold(wrap_gap, f64::max);
    (2.0 * PI - gap).max(0.0)
}

/// How the log saw one box over the training images.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Observed {
    /// Training images with the box in view.
    pub views: usize,
    /// The least camera-to-box distance over them (m); `None` when never in view.
    pub closest_m: Option<f64>,
    /// The 30-degree azimuth sectors seen (0: [-180, -150) degrees, ... 11: [150, 180]).
    pub azimuth_sectors: Vec<usize>,
    /// The smallest arc holding every azimuth seen (degrees).
    pub azimuth_span_deg: f64,
    pub max_hull_px: f64,
    pub total_hull_px: f64,
}

impl Observed {
    /// Sums up the views of one box.
    pub fn of(views: &[Observation]) -> Observed {
        let mut sectors: Vec<usize> = views.iter().map(|o| azimuth_bin(o.azimuth_rad)).collect();
        sectors.sort_unstable();
        sectors.dedup();
        let azimuths: Vec<f64> = views.iter().map(|o| o.azimuth_rad).collect();
        Observed {
            views: views.len(),
            closest_m: views.iter().map(|o| o.distance_m).min_by(f64::total_cmp),
            azimuth_sectors: sectors,
            azimuth_span_deg: azimuth_span(&azimuths).to_degrees(),
            max_hull_px: views.iter().map(|o| o.hull_px).fold(0.0, f64::max),
            total_hull_px: views.iter().map(|o| o.hull_px).fold(0.0, |a, b| a + b), // (an empty `sum` is -0.0)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A camera at the world origin looking along world +x (OpenCV axes: x right = world -y,
    /// y down = world -z, z forward = world +x), 1000 x 800 pixels, focal 500.
    fn forward_camera() -> splat::Camera {
        let mut c = splat::Camera::at_origin(1000, 800, 500.0);
        c.camera_from_world =
            [[0.0, -1.0, 0.0, 0.0], [0.0, 0.0, -1.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
        c.near = 0.05;
        c
    }

    #[test]
    fn a_box_straight_ahead_shows_its_back_face_only() {
        // A 4 x 2 x 1.5 m box 10 m ahead at the camera's height, driving away: the nearest point
        // is the middle of its back face, 8 m away; the hull is that face, 2 m x 1.5 m at 8 m:
        // (500 * 2 / 8) x (500 * 1.5 / 8) = 125 x 93.75 pixels.
        let o = observe(&forward_camera(), &BoxPose { center: [10.0, 0.0, 0.0], heading: 0.0 }, [4.0, 2.0, 1.5])
            .expect("in view");
        assert!((o.distance_m - 8.0).abs() < 1e-12, "{o:?}");
        assert!((o.hull_px - 125.0 * 93.75).abs() < 1e-6, "{o:?}");
        assert!((o.azimuth_rad.abs() - PI).abs() < 1e-12, "seen from behind: {o:?}");
        assert_eq!(azimuth_bin(o.azimuth_rad), if o.azimuth_rad > 0.0 { 11 } else { 0 });
        // Turned to face the camera, the front is seen (azimuth 0); driving to the camera's left
        // (heading +pi/2), its left side (+pi/2).
        let front = observe(&forward_camera(), &BoxPose { center: [10.0, 0.0, 0.0], heading: PI }, [4.0, 2.0, 1.5]);
        assert!(front.unwrap().azimuth_rad.abs() < 1e-12);
        let side =
            observe(&forward_camera(), &BoxPose { center: [10.0, 0.0, 0.0], heading: PI / 2.0 }, [4.0, 2.0, 1.5])
                .unwrap();
        assert!((side.azimuth_rad - PI / 2.0).abs() < 1e-12, "{side:?}");
        assert!((side.distance_m - 9.0).abs() < 1e-12, "the 2 m side is 1 m nearer: {side:?}");
    }

    #[test]
    fn off_image_and_behind_are_not_in_view_and_a_box_beside_is_clipped() {
        let cam = forward_camera();
        assert!(observe(&cam, &BoxPose { center: [-10.0, 0.0, 0.0], heading: 0.0 }, [4.0, 2.0, 1.5]).is_none());
        // 10 m ahead, 30 m to the left: the hull ends at u = 500 - 500 * 29 / 12 < 0.
        assert!(observe(&cam, &BoxPose { center: [10.0, 30.0, 0.0], heading: 0.0 }, [4.0, 2.0, 1.5]).is_none());
        // A box reaching from 2 m behind to 2 m ahead, its near side 1 m to the left: its front
        // part fills the image's left edge, cut at the near plane and clipped to the image.
        let o = observe(&cam, &BoxPose { center: [0.0, 1.5, 0.0], heading: 0.0 }, [4.0, 1.0, 1.5]).expect("beside");
        assert!((o.distance_m - 1.0).abs() < 1e-12, "{o:?}");
        assert!(o.hull_px > 0.0 && o.hull_px < 1000.0 * 800.0, "{o:?}");
        // Only the part left of the optical axis can show: u < 500 - 500 * 1 / 2 = 250.
        assert!(o.hull_px <= 250.0 * 800.0 + 1e-6, "{o:?}");
    }

    #[test]
    fn the_hull_area_matches_a_pixel_count() {
        // A turned box, seen obliquely: the analytic clipped area against the pixel centres
        // inside the hull (`placement::box_mask`); they differ by at most the hull's perimeter.
        let cam = forward_camera();
        let pose = BoxPose { center: [9.0, 2.0, -0.4], heading: 0.7 };
        let o = observe(&cam, &pose, [4.5, 1.9, 1.6]).unwrap();
        let mask = crate::placement::box_mask(&cam, &pose, [4.5, 1.9, 1.6]).unwrap();
        let count = mask.iter().filter(|&&b| b).count() as f64;
        assert!((o.hull_px - count).abs() < 0.02 * count, "analytic {} vs counted {count}", o.hull_px);
    }

    #[test]
    fn spans_and_bins() {
        let d = |a: f64| a.to_radians();
        assert_eq!(azimuth_span(&[]), 0.0);
        assert_eq!(azimuth_span(&[d(40.0)]), 0.0);
        assert!((azimuth_span(&[d(170.0), d(-170.0)]) - d(20.0)).abs() < 1e-12, "across +-180");
        assert!((azimuth_span(&[d(0.0), d(90.0), d(-90.0)]) - d(180.0)).abs() < 1e-12);
        assert_eq!(azimuth_bin(d(-180.0)), 0);
        assert_eq!(azimuth_bin(d(-151.0)), 0);
        assert_eq!(azimuth_bin(d(-149.0)), 1);
        assert_eq!(azimuth_bin(d(0.0)), 6);
        assert_eq!(azimuth_bin(d(180.0)), 11);
        assert_eq!(distance_to_box(DVec3::new(3.0, 2.0, 0.0), [4.0, 2.0, 1.0]), 2f64.sqrt());
        assert_eq!(distance_to_box(DVec3::new(0.5, 0.2, 0.1), [4.0, 2.0, 1.0]), 0.0);
    }
}
