//! Actor mask IoU on real logs, which have no instance masks: each **moving vehicle**'s rendered
//! silhouette (its actor drawn alone, alpha > 0.5) against its logged box projected into the
//! held-out view, twice: against the convex hull of the box's corners, and against the vehicle's
//! two-box profile (`scene::frames::vehicle_profile_corners`: lower body and cabin). A car fills
//! only about two thirds of its box's hull (the hull of a box seen at an angle holds the air over
//! the bonnet and boot and beside the cabin: 0.64 to 0.69 for a crisp car seen from behind on
//! PandaSet 002), so the profile is the reference that a whole, unsmeared car can match. Both
//! measure what the paper's actor IoU is for: a moving car rendered where the log has it.
//! The box is taken at the view's own time (`pose::box_pose_at`, as the renderer places it), and
//! both masks are compared only where no nearer object's box hull covers the view: a car half
//! hidden behind another was never seen there, so neither its render nor its box is scored there.
//! A vehicle counts as moving at a frame when the log labels it `Moving` there, or, without labels,
//! when its speed is above [`MOVING_SPEED`]. Boxes with a corner behind the camera are skipped;
//! boxes in the image but with fewer than [`MIN_PIXELS`] visible pixels at the size scored are
//! counted, not scored ([`Pairs::too_small`]): a model scored at a quarter of the cameras' size has
//! fewer pairs than one scored at full size, and says how many fewer.
//! Where the view's frame has a LiDAR sweep of its own, a third reference is the silhouette the
//! sweep measured (`eval_lidar`): the hull of the points it took on the car.
//! Each pair also records how much of the vehicle the view shows: the visible fraction of its box
//! hull (inside the image and not behind a nearer box) and the hull's height in pixels at the
//! camera's stored size. A pair is **clear** (KITTI's "moderate" detection difficulty: at least
//! 25 pixels tall, at most partly occluded or truncated) when the fraction is at least
//! [`CLEAR_MIN_VISIBLE`] and the height at least [`CLEAR_MIN_HEIGHT_PX`]: an IoU on a car 8 pixels
//! tall, or on the sliver of one behind a parked van, measures aliasing and the box's slack, not
//! the model. Every pair is scored and kept; the clear ones are also averaged on their own.

use crate::backend::Backend;
use crate::compose::Layers;
use crate::data::View;
use crate::eval_lidar::{points_on, Sweep, MIN_POINTS};
use crate::metrics::iou;
use crate::model::SceneModel;
use crate::pose::{box_pose_at, BoxPose};
use crate::priors::objects::{fill_hull, hull};
use crate::view::draw;
use scene::frames::{box_corners, vehicle_profile_corners};
use scene::glam::{DVec2, DVec3};
use scene::{LoggedMotion, ObjectClass, Scene, TrackState};

/// Speed above which an unlabelled vehicle counts as moving (m/s).
pub const MOVING_SPEED: f64 = 1.0;
/// A box must cover at least this many pixels of the view to be scored.
pub const MIN_PIXELS: usize = 50;
/// A clear pair shows at least this fraction of its box hull...
pub const CLEAR_MIN_VISIBLE: f64 = 0.5;
/// ...and its hull is at least this many pixels tall at the camera's stored size.
pub const CLEAR_MIN_HEIGHT_PX: f64 = 25.0;

pub(crate) fn moving(s: &TrackState) -> bool {
    match s.motion {
        Some(m) => m == LoggedMotion::Moving,
        None => s.velocity.is_some_and(|v| v.truncate().length() > MOVING_SPEED),
    }
}

/// The convex hull (pixels) of box-frame points `corners` of a box at `pose` in the view's camera,
/// if every one is in front.
fn hull_px(v: &View, pose: &BoxPose, corners: &[DVec3]) -> Option<Vec<DVec2>> {
    let c = &v.cam;
    let m = &c.camera_from_world;
    let world_from_b = pose.world_from_box();
    let px: Option<Vec<DVec2>> = corners
        .iter()
        .map(|k| {
            let p = world_from_b.transform_point(*k);
            let q: [f64; 3] = std::array::from_fn(|r| m[r][0] * p.x + m[r][1] * p.y + m[r][2] * p.z + m[r][3]);
            (q[2] > 0.1).then(|| DVec2::new(c.fx * q[0] / q[2] + c.cx, c.fy * q[1] / q[2] + c.cy))
        })
        .collect();
    Some(hull(px?))
}

/// The hull mask of box-frame points `corners` of a box at `pose` in the view's camera, if every
/// one is in front.
fn hull_mask(v: &View, pose: &BoxPose, corners: &[DVec3]) -> Option<Vec<bool>> {
    hull_px(v, pose, corners).map(|poly| filled(v, &poly))
}

/// Whether the bounding box of pixel polygon `poly` overlaps the view's image.
fn reaches_image(v: &View, poly: &[DVec2]) -> bool {
    let (w, h) = (v.width() as f64, v.height() as f64);
    let (lo, hi) =
        poly.iter().fold((DVec2::splat(f64::MAX), DVec2::splat(f64::MIN)), |(a, b), p| (a.min(*p), b.max(*p)));
    lo.x < w && lo.y < h && hi.x > 0.0 && hi.y > 0.0
}

/// The view-sized mask of a convex polygon (pixels).
fn filled(v: &View, poly: &[DVec2]) -> Vec<bool> {
    let (w, h) = (v.width(), v.height());
    let mut mask = vec![false; w * h];
    fill_hull(poly, w, h, &mut mask);
    mask
}

/// The area (pixels, unclipped by the image) and height (pixels) of a convex polygon.
fn area_and_height(poly: &[DVec2]) -> (f64, f64) {
    let n = poly.len();
    let twice: f64 = (0..n).map(|i| poly[i].perp_dot(poly[(i + 1) % n])).sum();
    let (lo, hi) = poly.iter().fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.y), b.max(p.y)));
    (0.5 * twice.abs(), if n > 0 { hi - lo } else { 0.0 })
}

/// The hull mask of the LiDAR points `on_car` (box frame, `eval_lidar::points_on`) with the box at
/// `pose`, when there are at least `eval_lidar::MIN_POINTS`.
fn lidar_mask(v: &View, pose: &BoxPose, on_car: &[DVec3]) -> Option<Vec<bool>> {
    (on_car.len() >= MIN_POINTS).then(|| hull_mask(v, pose, on_car)).flatten()
}

fn box_mask(v: &View, pose: &BoxPose, size_lwh: [f64; 3]) -> Option<Vec<bool>> {
    hull_mask(v, pose, &box_corners(size_lwh))
}

fn profile_mask(v: &View, pose: &BoxPose, size_lwh: [f64; 3]) -> Option<Vec<bool>> {
    let [a, b] = vehicle_profile_corners(size_lwh);
    let (a, b) = (hull_mask(v, pose, &a)?, hull_mask(v, pose, &b)?);
    Some(a.iter().zip(&b).map(|(x, y)| *x || *y).collect())
}

/// Distance from the view's camera centre to a world point.
fn camera_distance(v: &View, p: [f64; 3]) -> f64 {
    let m = &v.cam.camera_from_world;
    let q: [f64; 3] = std::array::from_fn(|r| m[r][0] * p[0] + m[r][1] * p[1] + m[r][2] * p[2] + m[r][3]);
    (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt()
}

/// The pixels of view `v` covered by the box hull of any track (but `except`) whose centre is
/// nearer to the camera than `distance` at the view's time.
fn nearer_boxes(v: &View, scene: &Scene, except: &str, distance: f64) -> Vec<bool> {
    let mut covered = vec![false; v.width() * v.height()];
    for tr in scene.tracks.iter().filter(|t| t.id != except) {
        let Some(pose) = box_pose_at(scene, tr, v.time) else { continue };
        let Some(size) = tr.valid_states().next().map(|s| s.size_lwh) else { continue };
        if camera_distance(v, pose.center) >= distance {
            continue;
        }
        if let Some(m) = box_mask(v, &pose, size) {
            covered.iter_mut().zip(&m).for_each(|(c, b)| *c |= *b);
        }
    }
    covered
}

/// One moving vehicle in one view: its IoU against the box hull and against the profile.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct VehicleIou {
    pub track: String,
    pub box_iou: f64,
    pub profile_iou: f64,
    /// Against the silhouette the view frame's sweep measured (`eval_lidar`); `None` where the
    /// frame has no sweep or the sweep took fewer than `eval_lidar::MIN_POINTS` on the car.
    #[serde(default)]
    pub lidar_iou: Option<f64>,
    /// How many of the sweep's points were on the car (0 without a sweep).
    #[serde(default)]
    pub lidar_points: usize,
    /// The fraction of the box hull's area that is inside the image and not behind a nearer box.
    #[serde(default)]
    pub visible_fraction: f64,
    /// The box hull's height in pixels at the camera's stored size.
    #[serde(default)]
    pub height_px: f64,
    /// Pixels (at the view's size, where no nearer box covers it) of the rendered silhouette, of
    /// the profile, and of both: whether an IoU falls short by spill or by holes.
    #[serde(default)]
    pub rendered_px: usize,
    #[serde(default)]
    pub profile_px: usize,
    #[serde(default)]
    pub profile_overlap_px: usize,
}

impl VehicleIou {
    /// Whether the view shows the vehicle clearly (see the module comment).
    pub fn clear(&self) -> bool {
        self.visible_fraction >= CLEAR_MIN_VISIBLE && self.height_px >= CLEAR_MIN_HEIGHT_PX
    }

    /// The share of the rendered silhouette inside the profile (below 1: spill outside it).
    pub fn profile_precision(&self) -> Option<f64> {
        (self.rendered_px > 0).then(|| self.profile_overlap_px as f64 / self.rendered_px as f64)
    }

    /// The share of the profile the rendered silhouette covers (below 1: holes or a car drawn
    /// smaller or elsewhere).
    pub fn profile_recall(&self) -> Option<f64> {
        (self.profile_px > 0).then(|| self.profile_overlap_px as f64 / self.profile_px as f64)
    }
}

/// The moving vehicles of one view: the scored pairs, and how many were in the image but showed
/// fewer than [`MIN_PIXELS`] visible pixels at the view's size (small there, or behind nearer boxes).
#[derive(Clone, Debug, Default)]
pub struct Pairs {
    pub scored: Vec<VehicleIou>,
    pub too_small: usize,
}

/// The IoUs of every moving vehicle of the model seen in view `v` (see the module comment);
/// `sweep` is the view frame's own LiDAR sweep, if it has one.
pub fn moving_vehicle_iou<B: Backend>(
    backend: &B,
    model: &SceneModel,
    scene: &Scene,
    v: &View,
    sweep: Option<&Sweep>,
) -> Pairs {
    moving_vehicle_pairs(backend, model, scene, v, sweep, &mut |_, _| {})
}

/// The view-sized masks of one scored pair (`eval_pair_png` draws them): the rendered silhouette
/// and the profile where no nearer box covers the view, that cover, and the actor's alpha.
pub struct PairMasks<'a> {
    pub rendered: &'a [bool],
    pub profile: &'a [bool],
    pub hidden: &'a [bool],
    pub alpha: &'a [f64],
}

/// [`moving_vehicle_iou`], handing each scored pair and its masks to `sink` as well.
pub fn moving_vehicle_pairs<B: Backend>(
    backend: &B,
    model: &SceneModel,
    scene: &Scene,
    v: &View,
    sweep: Option<&Sweep>,
    sink: &mut dyn FnMut(&VehicleIou, &PairMasks),
) -> Pairs {
    let mut out = Pairs::default();
    for (ai, actor) in model.actors.iter().enumerate() {
        let Some(track) = scene.track(&actor.track_id) else { continue };
        if track.class != ObjectClass::Vehicle {
            continue;
        }
        let Some(state) = track.state_at(v.frame).filter(|s| moving(s)) else { continue };
        let Some(pose) = box_pose_at(scene, track, v.time) else { continue };
        let (Some(hull), Some(mut profile)) =
            (hull_px(v, &pose, &box_corners(state.size_lwh)), profile_mask(v, &pose, state.size_lwh))
        else {
            continue;
        };
        let (area, height) = area_and_height(&hull);
        let mut truth = filled(v, &hull);
        let hidden = nearer_boxes(v, scene, &track.id, camera_distance(v, pose.center));
        let visible = |m: &mut Vec<bool>| m.iter_mut().zip(&hidden).for_each(|(x, h)| *x &= !*h);
        visible(&mut truth);
        visible(&mut profile);
        let count = |m: &[bool]| m.iter().filter(|x| **x).count();
        let shown = count(&truth);
        if shown < MIN_PIXELS {
            out.too_small += usize::from(reaches_image(v, &hull));
            continue;
        }
        let stored_height = scene.camera(&v.camera).map_or(v.height() as f64, |c| c.height as f64);
        let alone = draw(backend, model, scene, &v.cam, v.time, Layers::ActorsOnly, &|i| (i != ai).then_some(None));
        let mut mask: Vec<bool> = alone.alpha.iter().map(|a| *a > 0.5).collect();
        visible(&mut mask);
        let on_car = sweep.and_then(|s| points_on(scene, track, state.size_lwh, s)).unwrap_or_default();
        let lidar_iou = lidar_mask(v, &pose, &on_car).and_then(|mut m| {
            visible(&mut m);
            (count(&m) >= MIN_PIXELS).then(|| iou(&mask, &m)).flatten()
        });
        // The profile's IoU from the pixel counts the pair keeps.
        let (rendered_px, profile_px) = (count(&mask), count(&profile));
        let profile_overlap_px = mask.iter().zip(&profile).filter(|(a, b)| **a && **b).count();
        let union = rendered_px + profile_px - profile_overlap_px;
        let profile_iou = (union > 0).then(|| profile_overlap_px as f64 / union as f64);
        if let (Some(b), Some(p)) = (iou(&mask, &truth), profile_iou) {
            let pair = VehicleIou {
                track: actor.track_id.clone(),
                box_iou: b,
                profile_iou: p,
                lidar_iou,
                lidar_points: on_car.len(),
                visible_fraction: (shown as f64 / area.max(1.0)).min(1.0),
                height_px: height * stored_height / v.height() as f64,
                rendered_px,
                profile_px,
                profile_overlap_px,
            };
            sink(&pair, &PairMasks { rendered: &mask, profile: &profile, hidden: &hidden, alpha: &alone.alpha });
            out.scored.push(pair);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let v = View {
            frame: 0,
            camera: "C".into(),
            time: 0.0,
            image_time: 0.0,
            cam,
            targets: Default::default(),
            held_out: true,
        };
        let s = TrackState {
            frame: 0,
            center: DVec3::new(10.0, 0.0, 0.0),
            heading: 0.0,
            size_lwh: [4.0, 2.0, 1.5],
            velocity: None,
            valid: true,
            motion: Some(LoggedMotion::Moving),
        };
        let pose = BoxPose { center: s.center.into(), heading: s.heading };
        let m = box_mask(&v, &pose, s.size_lwh).unwrap();
        // The rear face spans 2 m x 1.5 m at 8 m: 10 x 7.5 px; the hull (front face too) is
        // larger, the far face at 12 m smaller: between the two.
        let n = m.iter().filter(|x| **x).count();
        assert!((70..=90).contains(&n), "{n} pixels");
        assert!(m[24 * 64 + 32], "the box centre is inside");
        // The profile lies inside the hull and leaves out the air above the bonnet and boot.
        let p = profile_mask(&v, &pose, s.size_lwh).unwrap();
        let np = p.iter().filter(|x| **x).count();
        assert!(p.iter().zip(&m).all(|(a, b)| !a || *b) && np < n && np > n / 2, "{np} of {n}");
        assert!(moving(&s));
        // LiDAR points on the rear face (box frame x = -2): a silhouette inside the hull; too few, none.
        let face: Vec<DVec3> = (0..10)
            .flat_map(|i| (0..8).map(move |k| DVec3::new(-2.0, -0.9 + 0.2 * i as f64, -0.6 + 0.15 * k as f64)))
            .collect();
        let l = lidar_mask(&v, &pose, &face).unwrap();
        let nl = l.iter().filter(|x| **x).count();
        // 1.8 m x 1.05 m at 8 m: 9 x 5.25 px.
        assert!((35..=60).contains(&nl) && l.iter().zip(&m).all(|(a, b)| !a || *b), "{nl} pixels");
        assert!(lidar_mask(&v, &pose, &face[..MIN_POINTS - 1]).is_none());
        // Behind the camera: no mask.
        let behind = BoxPose { center: [-10.0, 0.0, 0.0], heading: 0.0 };
        assert!(box_mask(&v, &behind, s.size_lwh).is_none());
        assert!((camera_distance(&v, [10.0, 0.0, 0.0]) - 10.0).abs() < 1e-9);
        // The hull's unclipped area is its filled pixel count up to the edge pixels; its height is
        // the near face's (1.5 m at 8 m: 7.5 px).
        let (area, height) = area_and_height(&hull_px(&v, &pose, &box_corners(s.size_lwh)).unwrap());
        assert!((area - n as f64).abs() < 0.25 * n as f64, "{area} against {n}");
        assert!((height - 7.5).abs() < 1e-9, "{height}");
    }

    #[test]
    fn a_pair_is_clear_when_tall_and_mostly_visible_and_counts_its_pixels() {
        let pair = |visible_fraction, height_px| VehicleIou { visible_fraction, height_px, ..Default::default() };
        // Precision and recall from the pixel counts; none without pixels.
        let counted = VehicleIou { rendered_px: 80, profile_px: 100, profile_overlap_px: 60, ..Default::default() };
        assert_eq!((counted.profile_precision(), counted.profile_recall()), (Some(0.75), Some(0.6)));
        assert_eq!((pair(1.0, 30.0).profile_precision(), pair(1.0, 30.0).profile_recall()), (None, None));
        assert!(pair(0.5, 25.0).clear());
        assert!(!pair(0.49, 200.0).clear(), "more than half hidden or outside the image");
        assert!(!pair(1.0, 24.9).clear(), "too small to score");
        // A unit square's area and height, in either winding.
        let sq = [DVec2::ZERO, DVec2::X, DVec2::ONE, DVec2::Y];
        assert_eq!(area_and_height(&sq), (1.0, 1.0));
        let rev: Vec<DVec2> = sq.iter().rev().copied().collect();
        assert_eq!(area_and_height(&rev), (1.0, 1.0));
    }
}
