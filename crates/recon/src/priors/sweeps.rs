//! The LiDAR points a camera image's depth prior is made of, in the ego frame at the image's own
//! time.
//!
//! * A frame with its own sweep uses that sweep; a frame without one (PandaSet 002 has sweeps on
//!   9 of 80 frames) borrows the [`BORROWED_SWEEPS`] sweeps nearest in time. Either way the sweep
//!   is carried through the world frame to the image's ego pose (`Scene::world_from_ego_of_image`).
//! * The points on an object that moves during the log (a `Moving` label on any state, or its box
//!   centre travelling more than [`MOVED_M`]) are taken out at the sweep's frame (inside its box
//!   grown by [`BOX_MARGIN`], its length also by what the object covers in a sweep, [`SWEEP_S`],
//!   above the road band `init::ACTOR_FLOOR_M`), kept in the object's box frame and put back
//!   where the box is at the image's time (`pose::box_pose_at`); an object that is not there then
//!   loses them. Without this, a car at an image of a frame without a sweep had no points of its
//!   own, and the static points behind it, seen from the nearest sweeps while it was elsewhere,
//!   gave its pixels the depth of the street behind: the depth loss then made the car's model
//!   transparent (on PandaSet 002, passing cars' median opacity fell to 0.02).
//!
//! Points behind what the camera sees from its new position are left to the depth prior's
//! occlusion filter (`lidar_depth`), as for the frame's own sweep.

use super::PriorError;
use crate::init::ACTOR_FLOOR_M;
use crate::pose::box_pose_at;
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

    /// The sweeps frame `f`'s images are made of: its own, else the nearest few.
    pub fn sources(&self, f: usize) -> Vec<usize> {
        if self.scene.frames[f].lidar.is_some() {
            return vec![f];
        }
        let t = self.scene.frames[f].timestamp_s;
        let mut near = self.with_lidar.clone();
        near.sort_by(|a, b| {
            let d = |k: &usize| (self.scene.frames[*k].timestamp_s - t).abs();
            d(a).total_cmp(&d(b)).then(a.cmp(b))
        });
        near.truncate(BORROWED_SWEEPS);
        near
    }

    /// The sweep of frame `k`: its static points in its own ego frame, and each moving object's
    /// points in that object's box frame.
    pub fn load(&self, k: usize) -> Result<Loaded<'a>, PriorError> {
        let frame = &self.scene.frames[k];
        let mut out = Loaded { world_from_ego: frame.world_from_ego, still: Vec::new(), movers: Vec::new() };
        let Some(l) = &frame.lidar else { return Ok(out) };
        let pts = scene::format::read_lidar(&self.scene_dir.join(&l.path))?;
        let boxes: Vec<(&Track, Transform3, [f64; 3], f64)> = self
            .moving
            .iter()
            .filter_map(|t| t.state_at(k).map(|s| (*t, s)))
            .map(|(t, s)| {
                let box_from_ego = world_from_box(s.center, s.heading).inverse() * frame.world_from_ego;
                let mut half = s.size_lwh.map(|v| v * BOX_MARGIN / 2.0);
                half[0] += s.velocity.map_or(0.0, |v| v.truncate().length() * SWEEP_S);
                (t, box_from_ego, half, -s.size_lwh[2] / 2.0 + ACTOR_FLOOR_M)
            })
            .collect();
        let mut movers: Vec<Vec<[f32; 4]>> = vec![Vec::new(); boxes.len()];
        for p in pts {
            let e = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            let on = boxes.iter().enumerate().find_map(|(i, (_, box_from_ego, half, floor))| {
                let b = box_from_ego.transform_point(e);
                (b.x.abs() <= half[0] && b.y.abs() <= half[1] && b.z.abs() <= half[2] && b.z >= *floor)
                    .then_some((i, b))
            });
            match on {
                Some((i, b)) => movers[i].push([b.x as f32, b.y as f32, b.z as f32, p[3]]),
                None => out.still.push(p),
            }
        }
        out.movers = boxes.into_iter().zip(movers).filter(|(_, m)| !m.is_empty()).map(|((t, ..), m)| (t, m)).collect();
        Ok(out)
    }

    /// Loaded sweeps' points in the ego frame `image` of `frame` was taken from, the moving
    /// objects' where their boxes are at the image's time (f64 chains, so a global world frame's
    /// large coordinates cost no precision).
    pub fn in_image_ego(&self, frame: &Frame, image: &ImageRef, loaded: &[Loaded]) -> Vec<[f32; 4]> {
        let ego_from_world = self.scene.world_from_ego_of_image(frame, image).inverse();
        let t = image.timestamp_s.unwrap_or(frame.timestamp_s);
        let mut out = Vec::with_capacity(loaded.iter().map(|l| l.len()).sum());
        let mut carry = |from: Transform3, pts: &[[f32; 4]]| {
            out.extend(pts.iter().map(|p| {
                let q = from.transform_point(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
                [q.x as f32, q.y as f32, q.z as f32, p[3]]
            }));
        };
        for l in loaded {
            carry(ego_from_world * l.world_from_ego, &l.still);
            for (track, pts) in &l.movers {
                if let Some(pose) = box_pose_at(self.scene, track, t) {
                    carry(ego_from_world * pose.world_from_box(), pts);
                }
            }
        }
        out
    }
}

/// One loaded sweep (`Sweeps::load`).
pub struct Loaded<'a> {
    pub world_from_ego: Transform3,
    /// The points of everything that does not move, in the sweep frame's ego frame.
    pub still: Vec<[f32; 4]>,
    /// Each moving object's points, in its box frame at the sweep's frame.
    pub movers: Vec<(&'a Track, Vec<[f32; 4]>)>,
}

impl Loaded<'_> {
    /// How many points in all.
    pub fn len(&self) -> usize {
        self.still.len() + self.movers.iter().map(|m| m.1.len()).sum::<usize>()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}
