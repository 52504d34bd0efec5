//! The executed trajectory (`executed.json`, format `carla-gs-executed/1`): what the physics
//! stage did with a plan. It is self-contained for measurement: it carries the plan, the actor
//! sizes, the adversary's state at every control step, the ego's logged path over the same steps,
//! the first contact, and resamplings at fixed rates (10 Hz for metrics, a video rate on request).

use crate::motion::Pose2;
use crate::plan::Plan;
use crate::track::ObjectClass;
use serde::{Deserialize, Serialize};

pub const EXECUTED_FORMAT: &str = "carla-gs-executed/1";

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
    pub resampled: Vec<ResampledSeries>,
}

impl Executed {
    /// The adversary's executed poses.
    pub fn adversary_path(&self) -> Vec<Pose2> {
        self.steps.iter().map(|s| Pose2 { t: s.t, x: s.x, y: s.y, heading: s.heading }).collect()
    }

    /// Validates what metrics rely on: version, equal-length finite series with increasing time.
    pub fn validate(&self) -> Result<(), (String, String)> {
        if self.format != EXECUTED_FORMAT {
            return Err(("format".into(), format!("expected \"{EXECUTED_FORMAT}\", got \"{}\"", self.format)));
        }
        self.plan.validate().map_err(|(f, m)| (format!("plan.{f}"), m))?;
        if self.steps.len() < 2 || self.steps.len() != self.ego_path.len() {
            return Err((
                "steps".into(),
                format!("need >= 2 steps and one ego pose per step ({} vs {})", self.steps.len(), self.ego_path.len()),
            ));
        }
        for (i, (s, e)) in self.steps.iter().zip(&self.ego_path).enumerate() {
            let v = [s.t, s.x, s.y, s.heading, s.speed, e.t, e.x, e.y, e.heading];
            if v.iter().any(|x| !x.is_finite()) {
                return Err((format!("steps[{i}]"), "must be finite numbers".into()));
            }
            if (s.t - e.t).abs() > 1e-6 {
                return Err((format!("ego_path[{i}].t"), format!("{} does not match steps[{i}].t {}", e.t, s.t)));
            }
            if i > 0 && s.t <= self.steps[i - 1].t {
                return Err((format!("steps[{i}].t"), "times must increase strictly".into()));
            }
        }
        Ok(())
    }
}

/// Loads and validates an executed file.
pub fn load_executed(path: &std::path::Path) -> Result<Executed, crate::SceneError> {
    let e: Executed = crate::format::read_json(path)?;
    e.validate().map_err(|(field, message)| crate::SceneError::Invalid { file: path.to_path_buf(), field, message })?;
    Ok(e)
}
