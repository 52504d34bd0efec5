//! The close-up and turned protocols: how a vehicle's model holds up where a corner case takes it,
//! measured on the log's own pixels. A corner case brings a car closer than the log saw it, or
//! turns it to show a side the log saw little of; the held-out frames rarely hold such views, so
//! each protocol makes them: it leaves a vehicle's pixels out of training in the views that show
//! it the way a case would, and scores the model there.
//! - **close-up**: every vehicle the training views see both far (camera centre to box centre more
//!   than [`FAR_M`]) and near (less than [`NEAR_M`]): its pixels in the near views are left out.
//! - **turned**: every vehicle seen both end-on (the horizontal ray to its centre within
//!   [`END_ON_DEG`] of its long axis, either end) and from the side (more than [`SIDE_DEG`]): its
//!   pixels in the side views are left out.
//!
//! A vehicle is seen in a view when its box's projected hull (`vehicle_region`, at the image's own
//! time) covers at least [`MIN_AREA_PX`] of the image at the camera's stored size, whatever scale
//! the model trains at, so a CPU run at a quarter size and a GPU run at full size leave out the
//! same (view, vehicle) pairs. Left out means out of every loss term: the photometric term's
//! pixels, and every SSIM window that reaches one of them (so no left-out value enters through a
//! window's neighbourhood); the depth, normal and geometry targets are emptied there; the start's
//! colours are not taken from them (`init`). The rest of each image still trains the street.
//! `eval-recon` scores exactly those pixels (the hull masks) per vehicle and pooled.

use crate::data::View;
use crate::loss::Targets;
use crate::pose::box_pose_at;
use crate::vehicle_region::project_box;
use scene::{ObjectClass, Scene};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Farther than this (m) is far, nearer than [`NEAR_M`] near.
pub const FAR_M: f64 = 15.0;
pub const NEAR_M: f64 = 8.0;
/// End-on within this of the long axis (degrees), side view beyond [`SIDE_DEG`].
pub const END_ON_DEG: f64 = 30.0;
pub const SIDE_DEG: f64 = 60.0;
/// A vehicle is seen where its hull covers this many pixels at the camera's stored size.
pub const MIN_AREA_PX: f64 = 400.0;
/// The SSIM window's radius (`ssim`): a window centred this close to a left-out pixel is out too.
const SSIM_RADIUS: usize = 5;

/// Which pixels a training run leaves out.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Protocol {
    /// Every pixel trains.
    #[default]
    None,
    CloseUp,
    Turned,
}

impl Protocol {
    pub fn as_str(self) -> &'static str {
        match self {
            Protocol::None => "none",
            Protocol::CloseUp => "close-up",
            Protocol::Turned => "turned",
        }
    }
}

/// One vehicle as one view shows it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Sighting {
    pub frame: usize,
    pub camera: String,
    pub track: String,
    /// Camera centre to box centre (m).
    pub distance_m: f64,
    /// The horizontal ray to the box centre against the box's long axis, folded to [0, 90] degrees.
    pub angle_deg: f64,
    /// The hull's area inside the image at the camera's stored size (pixels).
    pub area_px: f64,
}

/// Every vehicle seen in a training view of `views` (see the module comment), in view order.
pub fn sightings(scene: &Scene, views: &[View]) -> Vec<Sighting> {
    let mut out = vec![];
    for v in views.iter().filter(|v| !v.held_out) {
        let stored = scene.camera(&v.camera).map_or(v.width() as f64, |c| c.width as f64);
        let to_stored = (stored / v.width() as f64).powi(2);
        let c = v.cam.center();
        for t in scene.tracks.iter().filter(|t| t.class == ObjectClass::Vehicle) {
            let Some(state) = t.state_at(v.frame) else { continue };
            let Some(pose) = box_pose_at(scene, t, v.image_time) else { continue };
            let Some(region) = project_box(&v.cam, &pose.world_from_box(), state.size_lwh) else { continue };
            let area_px = region.area_in_image(v.width() as f64, v.height() as f64) * to_stored;
            if area_px < MIN_AREA_PX {
                continue;
            }
            let d: [f64; 3] = std::array::from_fn(|k| pose.center[k] - c[k]);
            let distance_m = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let along = (d[0] * pose.heading.cos() + d[1] * pose.heading.sin()).abs();
            let across = (-d[0] * pose.heading.sin() + d[1] * pose.heading.cos()).abs();
            let angle_deg = across.atan2(along).to_degrees();
            out.push(Sighting {
                frame: v.frame,
                camera: v.camera.clone(),
                track: t.id.clone(),
                distance_m,
                angle_deg,
                area_px,
            });
        }
    }
    out
}

/// The (view, vehicle) pairs protocol `p` leaves out, from the `sightings`.
pub fn pairs(p: Protocol, seen: &[Sighting]) -> Vec<Sighting> {
    type Test = fn(&Sighting) -> bool;
    let (wide, held): (Test, Test) = match p {
        Protocol::None => return vec![],
        Protocol::CloseUp => (|s| s.distance_m > FAR_M, |s| s.distance_m < NEAR_M),
        Protocol::Turned => (|s| s.angle_deg <= END_ON_DEG, |s| s.angle_deg > SIDE_DEG),
    };
    let mut by_track: BTreeMap<&str, Vec<&Sighting>> = BTreeMap::new();
    seen.iter().for_each(|s| by_track.entry(&s.track).or_default().push(s));
    let qualifies: Vec<&str> = by_track
        .iter()
        .filter(|(_, ss)| ss.iter().any(|s| wide(s)) && ss.iter().any(|s| held(s)))
        .map(|(t, _)| *t)
        .collect();
    seen.iter().filter(|s| held(s) && qualifies.contains(&s.track.as_str())).cloned().collect()
}

/// The hull mask of pair `s`'s vehicle in view `v` (at the view's size), if it is in front.
pub fn pair_mask(scene: &Scene, v: &View, s: &Sighting) -> Option<Vec<bool>> {
    let t = scene.track(&s.track)?;
    let state = t.state_at(v.frame)?;
    let pose = box_pose_at(scene, t, v.image_time)?;
    Some(project_box(&v.cam, &pose.world_from_box(), state.size_lwh)?.hull_mask(v.width(), v.height()))
}

/// Leaves the pixels `out` (a `width x height` mask) of targets `t` out of every loss term.
pub fn leave_out(t: &mut Targets, out: &[bool], width: usize, height: usize) {
    let mut keep: Vec<f32> = t.keep.take().unwrap_or_else(|| vec![1.0; width * height]);
    keep.iter_mut().zip(out).for_each(|(k, o)| *k = if *o { 0.0 } else { *k });
    // A window centred within the radius of a left-out pixel (a square, as the window is) is out:
    // a separable dilation of the left-out pixels.
    let left: Vec<bool> = keep.iter().map(|k| *k == 0.0).collect();
    let r = SSIM_RADIUS;
    let mut rows = vec![false; width * height];
    for y in 0..height {
        for x in 0..width {
            rows[y * width + x] = (x.saturating_sub(r)..(x + r + 1).min(width)).any(|xx| left[y * width + xx]);
        }
    }
    let ssim_keep = (0..width * height)
        .map(|i| {
            let (x, y) = (i % width, i / width);
            let near = (y.saturating_sub(r)..(y + r + 1).min(height)).any(|yy| rows[yy * width + x]);
            if near {
                0.0
            } else {
                1.0
            }
        })
        .collect();
    for i in (0..width * height).filter(|&i| left[i]) {
        if let Some(d) = t.depth.as_mut() {
            d[i] = 0.0;
        }
        if let Some(n) = t.normal.as_mut() {
            n[i] = [0.0; 3];
        }
        if let Some(m) = t.mask.as_mut() {
            m[i] = false;
        }
        if let Some(g) = t.geo_weight.as_mut() {
            g[i] = 0.0;
        }
    }
    t.keep = Some(keep);
    t.ssim_keep = Some(ssim_keep);
}

/// Applies protocol `p` to the training views: leaves each pair's pixels out; returns the pairs.
pub fn apply(p: Protocol, scene: &Scene, views: &mut [View]) -> Vec<Sighting> {
    let chosen = pairs(p, &sightings(scene, views));
    for v in views.iter_mut().filter(|v| !v.held_out) {
        let (w, h) = (v.width(), v.height());
        let mut out = vec![false; w * h];
        let mut any = false;
        for s in chosen.iter().filter(|s| s.frame == v.frame && s.camera == v.camera) {
            if let Some(m) = pair_mask(scene, v, s) {
                out.iter_mut().zip(&m).for_each(|(o, b)| *o |= *b);
                any = true;
            }
        }
        if any {
            leave_out(&mut v.targets, &out, w, h);
        }
    }
    chosen
}

#[cfg(test)]
mod tests;
