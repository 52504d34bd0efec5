//! The LiDAR points a camera image's depth prior is made of, in the ego frame at the image's own
//! time.
//!
//! * A frame with its own sweep uses that sweep whole (moving objects included: same instant),
//!   carried from the frame's ego pose to the image's (`Scene::world_from_ego_of_image`; the
//!   identity where images have no time of their own).
//! * A frame without one (PandaSet 002 has sweeps on 9 of 80 frames) borrows the static part of
//!   the [`BORROWED_SWEEPS`] sweeps nearest in time, carried through the world frame: the points
//!   inside the box of any object that moves during the log (a `Moving` label on any state, or
//!   its box centre travelling more than [`MOVED_M`]) at the sweep's frame are dropped, since
//!   that object is elsewhere at the image's time; the box is lengthened by what the object
//!   covers in a sweep ([`SWEEP_S`]), as the sweep saw it up to that long before or after the
//!   frame's time. Parked cars and the street stay.
//!
//! Points behind what the camera sees from its new position are left to the depth prior's
//! occlusion filter (`lidar_depth`), as for the frame's own sweep.

use super::PriorError;
use scene::frames::world_from_box;
use scene::glam::DVec3;
use scene::{Frame, ImageRef, LoggedMotion, ObjectClass, Scene, Track, Transform3};
use std::path::Path;

/// How many sweeps a frame without its own borrows (the nearest in time).
pub const BORROWED_SWEEPS: usize = 3;
/// A track whose box centre travels more than this (m) over the log counts as moving.
pub const MOVED_M: f64 = 1.0;
/// Boxes are grown by this factor when points inside them are dropped (label slack).
pub const BOX_MARGIN: f64 = 1.1;
/// A sweep's points are taken over this long (s, one turn at 10 Hz) while its frame's boxes
/// hold one instant: a box's length is grown by the distance its object covers in that time.
pub const SWEEP_S: f64 = 0.1;

fn moves(t: &Track) -> bool {
    if !matches!(t.class, ObjectClass::Vehicle | ObjectClass::Pedestrian | ObjectClass::Cyclist) {
        return false;
    }
    let labelled = t.states.iter().any(|s| s.motion == Some(LoggedMotion::Moving));
    let mut states = t.valid_states();
    let travelled = match states.next() {
        Some(first) => states.any(|s| (s.center - first.center).length() > MOVED_M),
        None => false,
    };
    labelled || travelled
}

/// Frames with a sweep, and which tracks move.
pub struct Sweeps<'a> {
    scene: &'a Scene,
    scene_dir: &'a Path,
    with_lidar: Vec<usize>,
    moving: Vec<&'a Track>,
}

impl<'a> Sweeps<'a> {
    pub fn new(scene_dir: &'a Path, scene: &'a Scene) -> Self {
        let with_lidar = scene.frames.iter().filter(|f| f.lidar.is_some()).map(|f| f.index).collect();
        Self { scene, scene_dir, with_lidar, moving: scene.tracks.iter().filter(|t| moves(t)).collect() }
    }

    /// True when the scene has any sweep at all.
    pub fn any(&self) -> bool {
        !self.with_lidar.is_empty()
    }

    /// The sweeps frame `f`'s images are made of: its own, else the nearest few (with the
    /// moving objects' points to drop).
    pub fn sources(&self, f: usize) -> Vec<(usize, bool)> {
        if self.scene.frames[f].lidar.is_some() {
            return vec![(f, false)];
        }
        let t = self.scene.frames[f].timestamp_s;
        let mut near = self.with_lidar.clone();
        near.sort_by(|a, b| {
            let d = |k: &usize| (self.scene.frames[*k].timestamp_s - t).abs();
            d(a).total_cmp(&d(b)).then(a.cmp(b))
        });
        near.truncate(BORROWED_SWEEPS);
        near.into_iter().map(|k| (k, true)).collect()
    }

    /// The sweep of frame `k` in its own ego frame (moving objects' points dropped when
    /// `static_only`), with that frame's `world_from_ego`.
    pub fn load(&self, k: usize, static_only: bool) -> Result<(Transform3, Vec<[f32; 4]>), PriorError> {
        let frame = &self.scene.frames[k];
        let Some(l) = &frame.lidar else { return Ok((frame.world_from_ego, Vec::new())) };
        let pts = scene::format::read_lidar(&self.scene_dir.join(&l.path))?;
        if !static_only {
            return Ok((frame.world_from_ego, pts));
        }
        let boxes: Vec<(Transform3, [f64; 3])> = self
            .moving
            .iter()
            .filter_map(|t| t.state_at(k))
            .map(|s| {
                let box_from_ego = world_from_box(s.center, s.heading).inverse() * frame.world_from_ego;
                let mut half = s.size_lwh.map(|v| v * BOX_MARGIN / 2.0);
                half[0] += s.velocity.map_or(0.0, |v| v.truncate().length() * SWEEP_S);
                (box_from_ego, half)
            })
            .collect();
        let kept = pts
            .into_iter()
            .filter(|p| {
                let e = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
                !boxes.iter().any(|(box_from_ego, half)| {
                    let b = box_from_ego.transform_point(e);
                    b.x.abs() <= half[0] && b.y.abs() <= half[1] && b.z.abs() <= half[2]
                })
            })
            .collect();
        Ok((frame.world_from_ego, kept))
    }

    /// Loaded sweeps' points in the ego frame `image` of `frame` was taken from (f64 chains, so
    /// a global world frame's large coordinates cost no precision).
    pub fn in_image_ego(
        &self,
        frame: &Frame,
        image: &ImageRef,
        loaded: &[(Transform3, Vec<[f32; 4]>)],
    ) -> Vec<[f32; 4]> {
        let ego_from_world = self.scene.world_from_ego_of_image(frame, image).inverse();
        let mut out = Vec::with_capacity(loaded.iter().map(|l| l.1.len()).sum());
        for (world_from_sweep_ego, pts) in loaded {
            let img_from_sweep = ego_from_world * *world_from_sweep_ego;
            out.extend(pts.iter().map(|p| {
                let q = img_from_sweep.transform_point(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
                [q.x as f32, q.y as f32, q.z as f32, p[3]]
            }));
        }
        out
    }
}
