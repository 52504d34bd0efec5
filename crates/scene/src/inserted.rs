//! An adversary inserted where the log has none (`scenario.json`'s `inserted`): a road user the
//! Reason stage placed on a lane, with its size, class and the poses it had before the case (one
//! per scene frame it exists at, on the scene clock), so that every later stage can put it back
//! into the scene as if the log had seen it ([`crate::plan::with_inserted`]): the Execute stage checks its
//! contacts against the logged road users, the Re-render stage draws it from the asset library,
//! the exports write it as an entity.
//!
//! The plan carries the poses rather than the rule that made them: a plan file is checked on its
//! own ([`Inserted::validate`]) and means the same whichever version of the planner reads it.

use crate::ObjectClass;
use serde::{Deserialize, Serialize};

/// Prefix of every inserted road user's id (never a logged track's: [`crate::plan::with_inserted`]
/// refuses a clash).
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
