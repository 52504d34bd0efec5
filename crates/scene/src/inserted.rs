//! An adversary inserted where the log has none (`scenario.json`'s `inserted`): a road user the
//! Reason stage placed on a lane, with its size, class and the poses it had before the case (one
//! per scene frame it exists at, on the scene clock), so that every later stage can put it back
//! into the scene as if the log had seen it ([`with_inserted`]): the Execute stage checks its
//! contacts against the logged road users, the Re-render stage draws it from the asset library,
//! the exports write it as an entity.
//!
//! The plan carries the poses rather than the rule that made them: a plan file is checked on its
//! own ([`Inserted::validate`]) and means the same whichever version of the planner reads it.

use crate::plan::Plan;
use crate::{ObjectClass, Scene, Track, TrackState};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

/// Prefix of every inserted road user's id (never a logged track's: [`with_inserted`] refuses a
/// clash).
pub const INSERTED_PREFIX: &str = "inserted-";
/// Box sides an inserted road user may have (m): a bicycle to an articulated bus.
pub const SIZE_RANGE_M: [f64; 2] = [0.3, 25.0];

/// One pose of the inserted road user at a scene frame's time (world frame).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct InsertedPose {
    pub t: f64,
    /// Box centre (m).
    pub x: f64,
    pub y: f64,
    pub z: f64,
    /// Yaw of the box's length axis about world +z (rad).
    pub heading: f64,
}

/// How the inserted road user came to be where the case starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Entry {
    /// In traffic from the first frame of the log (ahead of, beside or behind the ego).
    InTraffic,
    /// Driving towards the ego from beyond the cameras' range.
    FromAfar,
    /// Parked at the roadside from the first frame.
    Parked,
}

/// The inserted adversary of a plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Inserted {
    pub class: ObjectClass,
    /// Box length, width, height (m).
    pub size_lwh: [f64; 3],
    pub entry: Entry,
    /// Which lane it was put on, in words (`the ego's lane`, `the lane to the left (map)`, ...).
    pub lane: String,
    /// One pose per scene frame from its first to its last, strictly increasing in time.
    pub poses: Vec<InsertedPose>,
}

impl Inserted {
    /// Checks it on its own: `(field, message)` of the first problem.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let [lo, hi] = SIZE_RANGE_M;
        if self.size_lwh.iter().any(|v| !(lo..=hi).contains(v)) {
            return Err(("inserted.size_lwh".into(), format!("sides must be {lo} to {hi} m, got {:?}", self.size_lwh)));
        }
        if self.poses.is_empty() {
            return Err(("inserted.poses".into(), "needs at least one pose".into()));
        }
        for (i, p) in self.poses.iter().enumerate() {
            if ![p.t, p.x, p.y, p.z, p.heading].iter().all(|v| v.is_finite()) {
                return Err((format!("inserted.poses[{i}]"), "t, x, y, z and heading must be finite".into()));
            }
            if i > 0 && p.t <= self.poses[i - 1].t {
                return Err((format!("inserted.poses[{i}].t"), "times must increase strictly".into()));
            }
        }
        Ok(())
    }
}

/// The scene the plan was made for: `scene` itself, or with the plan's inserted road user added
/// as a track (id `plan.adversary_track`; a state at every frame whose time matches one of its
/// poses within a microsecond). Refuses an inserted id that a logged track already has, a pose
/// at no frame's time, or a plan whose adversary is not marked inserted but named like one.
pub fn with_inserted<'a>(scene: &'a Scene, plan: &Plan) -> Result<Cow<'a, Scene>, (String, String)> {
    let Some(ins) = &plan.inserted else { return Ok(Cow::Borrowed(scene)) };
    ins.validate()?;
    if scene.tracks.iter().any(|t| t.id == plan.adversary_track) {
        return Err((
            "adversary_track".into(),
            format!("`{}` is marked inserted but the scene logs a track of that id", plan.adversary_track),
        ));
    }
    let mut states = Vec::with_capacity(ins.poses.len());
    let mut next = 0;
    for p in &ins.poses {
        // Frames are in time order: walk them once.
        while next < scene.frames.len() && scene.frames[next].timestamp_s < p.t - 1e-6 {
            next += 1;
        }
        let Some(_) = scene.frames.get(next).filter(|f| (f.timestamp_s - p.t).abs() <= 1e-6) else {
            return Err(("inserted.poses".into(), format!("t = {} s is no frame time of scene `{}`", p.t, scene.name)));
        };
        states.push(TrackState {
            frame: next,
            center: DVec3::new(p.x, p.y, p.z),
            heading: p.heading,
            size_lwh: ins.size_lwh,
            velocity: None,
            valid: true,
            motion: None,
        });
        next += 1;
    }
    let mut s = scene.clone();
    s.tracks.push(Track { id: plan.adversary_track.clone(), class: ins.class, states });
    Ok(Cow::Owned(s))
}
