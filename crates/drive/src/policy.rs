//! The driver in the loop. A [`Policy`] is told about the episode once ([`EpisodeInfo`]: the
//! clock, the cameras' calibration, the route) and then, each tick, gets an [`Observation`] (the
//! ego's state, each camera's image and calibration at the ego's simulated pose, and the
//! ground-truth objects only if it asked for them, flagged as such) and answers an
//! [`Action`]. The same types are the subprocess protocol's messages (`protocol`), so what a
//! built-in policy sees is what an external stack sees. Built-ins: [`crate::builtin`].

use crate::action::Action;
use crate::error::DriveError;
use crate::world::Object;
use serde::{Deserialize, Serialize};

/// The ego's simulated state at a tick (world frame, scene clock, SI units).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct EgoState {
    pub t: f64,
    /// Box centre (m) and heading (rad).
    pub x: f64,
    pub y: f64,
    pub heading: f64,
    /// Speed (m/s) and yaw rate (rad/s).
    pub speed: f64,
    pub yaw_rate: f64,
    /// Longitudinal and lateral acceleration over the last control period (m/s^2).
    pub accel_long: f64,
    pub accel_lat: f64,
    /// Front wheel angle (rad, + = left).
    pub steering_angle: f64,
}

/// A camera's calibration: pinhole intrinsics at the rendered size, and its mounting.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraInfo {
    pub name: String,
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    /// The camera in the ego frame, OpenCV axes (x right, y down, z forward), row-major 4x4.
    pub ego_from_camera: [[f64; 4]; 4],
}

/// One camera's picture at a tick.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CameraFrame {
    pub name: String,
    /// The PNG file (absolute path) when the policy takes images; `None` for built-ins.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image: Option<String>,
    /// The camera in the world at this tick, OpenCV axes, row-major 4x4.
    pub world_from_camera: [[f64; 4]; 4],
}

/// The ground truth, only for a policy that asked for it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GroundTruth {
    /// Always `true`: these objects come from the log and the plan, not from perception.
    pub ground_truth: bool,
    pub objects: Vec<Object>,
}

/// What a policy is told once, before the first tick.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct EpisodeInfo {
    pub protocol: String,
    pub scene: String,
    /// First and last tick times (s) and the tick period (s).
    pub t_start: f64,
    pub t_end: f64,
    pub dt: f64,
    pub cameras: Vec<CameraInfo>,
    /// The ego's box (length, width, height; m).
    pub ego_size_lwh: [f64; 3],
    /// The lane to keep: the logged ego path (world positions about a metre apart), extended
    /// 200 m straight past its end. It is what a navigation route would give, nothing more.
    pub route: Vec<[f64; 2]>,
    /// The logged ego's mean and highest speed over the episode (m/s): the speed the road and
    /// the traffic allowed, the stand-in for a speed limit.
    pub logged_speed_mean: f64,
    pub logged_speed_max: f64,
}

/// What a policy sees at one tick.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Observation {
    pub tick: usize,
    pub t: f64,
    pub dt: f64,
    pub ego: EgoState,
    pub cameras: Vec<CameraFrame>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ground_truth: Option<GroundTruth>,
}

/// How a policy starts: its name and whether it wants the ground-truth objects.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Ready {
    pub name: String,
    pub ground_truth: bool,
}

pub trait Policy {
    /// The policy's name as the tables show it.
    fn name(&self) -> String;
    /// Whether the policy looks at the cameras' images (they are then written as PNG files).
    fn needs_images(&self) -> bool;
    /// Called once before the first tick.
    fn start(&mut self, info: &EpisodeInfo) -> Result<Ready, DriveError>;
    /// The action for one tick.
    fn act(&mut self, obs: &Observation) -> Result<Action, DriveError>;
    /// Called once after the last tick (or when the episode ends early), with the reason.
    fn finish(&mut self, _reason: &str) {}
}
