//! Tracked objects: a stable id, a class, and per-frame box states in the world frame.

use glam::DVec3;
use serde::{Deserialize, Serialize};

/// Object class, merged across Waymo's label types and WOMD's object types.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ObjectClass {
    Vehicle,
    Pedestrian,
    Cyclist,
    Sign,
    Other,
}

impl ObjectClass {
    pub const ALL: [ObjectClass; 5] = [Self::Vehicle, Self::Pedestrian, Self::Cyclist, Self::Sign, Self::Other];

    pub fn as_str(self) -> &'static str {
        match self {
            Self::Vehicle => "vehicle",
            Self::Pedestrian => "pedestrian",
            Self::Cyclist => "cyclist",
            Self::Sign => "sign",
            Self::Other => "other",
        }
    }
}

/// How the log's annotators labelled an object's motion at one frame (PandaSet's
/// `attributes.object_motion`): distinct from a speed threshold, since a car stopped at a light
/// and a car parked at the kerb are both still.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LoggedMotion {
    Moving,
    /// Stopped in traffic (will move on).
    Stopped,
    /// Parked (at the kerb, in a bay).
    Parked,
}

/// The state of one track at one frame. Positions and velocities are world-frame SI values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrackState {
    /// Index into `Scene::frames`.
    pub frame: usize,
    /// Box centre in the world frame (m).
    pub center: DVec3,
    /// Yaw of the box's +x (length) axis about world +z (rad).
    pub heading: f64,
    /// Box length (along heading), width, height (m).
    pub size_lwh: [f64; 3],
    /// World-frame velocity (m/s) when the source provides one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<DVec3>,
    /// False where the source marks the state as padding (WOMD `valid = false`).
    pub valid: bool,
    /// The source's own motion label at this frame, where it has one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<LoggedMotion>,
}

/// One tracked object across the scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Track {
    /// The source's id as a string (Waymo label id, WOMD track id), stable across frames.
    pub id: String,
    pub class: ObjectClass,
    /// States sorted by strictly increasing `frame`.
    pub states: Vec<TrackState>,
}

impl Track {
    /// The valid state at `frame`, if any.
    pub fn state_at(&self, frame: usize) -> Option<&TrackState> {
        self.states.binary_search_by_key(&frame, |s| s.frame).ok().map(|i| &self.states[i]).filter(|s| s.valid)
    }

    pub fn valid_states(&self) -> impl Iterator<Item = &TrackState> {
        self.states.iter().filter(|s| s.valid)
    }

    /// Median length, width and height over the valid states (each dimension separately;
    /// zeros without valid states): one box size for the whole track, robust to label jitter.
    pub fn median_size_lwh(&self) -> [f64; 3] {
        std::array::from_fn(|k| {
            let mut v: Vec<f64> = self.valid_states().map(|s| s.size_lwh[k]).collect();
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 2).copied().unwrap_or(0.0)
        })
    }
}
