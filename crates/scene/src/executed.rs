//! The executed trajectory (`executed.json`, format `carla-gs-executed/2`): what the physics
//! stage did with a plan. It is self-contained for measurement: it carries the plan, the actor
//! sizes, the adversary's state at every control step, the ego's logged path over the same steps,
//! the first contact, the rollout's physical validity (and why not), and resamplings at fixed
//! rates (10 Hz for metrics, a video rate on request). Version 2 added `validity`.

use crate::motion::Pose2;
use crate::plan::Plan;
use crate::track::ObjectClass;
use serde::{Deserialize, Serialize};

pub const EXECUTED_FORMAT: &str = "carla-gs-executed/2";

/// The adversary's state after one control step. SI units, world frame, scene clock.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ExecutedStep {
    pub t: f64,
    pub x: f64,
    pub y: f64,
    /// Yaw of the vehicle body (rad).
    pub heading: f64,
    /// Speed of the reference point (m/s).
    pub speed: f64,
    pub yaw_rate: f64,
    /// Longitudinal acceleration applied by the model (m/s^2).
    pub accel_long: f64,
    /// Lateral acceleration `v * (yaw_rate + slip_rate)` (m/s^2).
    pub accel_lat: f64,
    /// Front-wheel steering angle (rad, positive = left).
    pub steering_angle: f64,
    /// The controller's commands, CARLA convention: steer in [-1, 1] with positive = right.
    pub steer: f64,
    pub throttle: f64,
    pub brake: f64,
    /// The reference position the controller aimed for at `t` (world frame).
    pub ref_x: f64,
    pub ref_y: f64,
}

/// The first overlap of the adversary's box with another actor's box.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Contact {
    pub t: f64,
    /// `ego` or the other track's id.
    pub other: String,
    pub class: ObjectClass,
}

/// Why a rollout is not a physically valid corner case.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "reason")]
pub enum InvalidReason {
    /// The executed path left its reference by more than `limit_m` (first at `t`).
    TrackingDiverged { t: f64, error_m: f64, limit_m: f64 },
    /// The tyres were at the friction limit for `time_s` in all (more than `limit_s`), first at
    /// `t_first`.
    FrictionLimit { t_first: f64, time_s: f64, limit_s: f64 },
    /// The adversary touched another actor than the ego first.
    ContactWithOther { t: f64, other: String, class: ObjectClass },
    /// The adversary's box crossed a road edge (map polyline `edge_id`) it did not touch at t0.
    LeftRoad { t: f64, edge_id: i64 },
}

impl InvalidReason {
    /// Every reason's key, in table order.
    pub const KEYS: [&'static str; 4] = ["tracking_diverged", "friction_limit", "contact_with_other", "left_road"];

    pub fn key(&self) -> &'static str {
        match self {
            InvalidReason::TrackingDiverged { .. } => Self::KEYS[0],
            InvalidReason::FrictionLimit { .. } => Self::KEYS[1],
            InvalidReason::ContactWithOther { .. } => Self::KEYS[2],
            InvalidReason::LeftRoad { .. } => Self::KEYS[3],
        }
    }
}

/// The physical validity of a rollout: `valid` exactly when `reasons` is empty.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Validity {
    pub valid: bool,
    pub reasons: Vec<InvalidReason>,
    /// Largest distance between the executed position and the reference at a control step (m).
    pub max_tracking_error_m: f64,
    /// Total time the tyres spent at the friction limit (s).
    pub friction_limit_s: f64,
    /// Largest |lateral acceleration| at any control step (m/s^2).
    pub max_abs_accel_lat: f64,
    /// Whether the scene had road edges to test `left_road` against.
    pub road_checked: bool,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ActorInfo {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub track_id: Option<String>,
    pub size_lwh: [f64; 3],
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ResampledSeries {
    pub rate_hz: f64,
    pub adversary: Vec<Pose2>,
    pub ego: Vec<Pose2>,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Executed {
    pub format: String,
    pub scene: String,
    /// What executed the plan (model and controller), for provenance.
    pub backend: String,
    pub plan: Plan,
    pub control_dt_s: f64,
    pub physics_dt_s: f64,
    pub ego: ActorInfo,
    pub adversary: ActorInfo,
    /// One entry per control step, from the rollout start (the adversary's first logged state).
    pub steps: Vec<ExecutedStep>,
    /// The ego's logged pose at each step time.
    pub ego_path: Vec<Pose2>,
    pub first_contact: Option<Contact>,
    pub validity: Validity,
    pub resampled: Vec<ResampledSeries>,
}

impl Executed {
    /// The adversary's executed poses.
    pub fn adversary_path(&self) -> Vec<Pose2> {
        self.steps.iter().map(|s| Pose2 { t: s.t, x: s.x, y: s.y, heading: s.heading }).collect()
    }
}

/// Loads and validates an executed file (a regular file of at most
/// [`crate::input::MAX_EXECUTED_BYTES`]; `Executed::validate` is in `executed_check`).
pub fn load_executed(path: &std::path::Path) -> Result<Executed, crate::SceneError> {
    let e: Executed = crate::format::read_json_within(path, crate::input::MAX_EXECUTED_BYTES, "an executed file")?;
    e.validate().map_err(|(field, message)| crate::SceneError::Invalid { file: path.to_path_buf(), field, message })?;
    Ok(e)
}
