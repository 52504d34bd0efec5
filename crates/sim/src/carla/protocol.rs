//! The JSON-lines protocol between carla-gs and the bridge (`tools/carla_bridge.py`): one JSON
//! object per line, `type` says which. carla-gs sends `setup`, then one `step` per control period,
//! then `close`; the bridge answers `ready`, one `state` per step and `closed`, or `error` at any
//! point (after which it exits). Every pose, vector and angle is in **CARLA's frame and units**
//! (left-handed, metres, degrees, m/s; see `frame.rs`), so the bridge converts nothing.

use super::frame::CarlaTransform;
use crate::actuation::Control;
use serde::{Deserialize, Serialize};

/// The protocol version both sides check.
pub const PROTOCOL: u32 = 1;

/// carla-gs -> bridge.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Request {
    Setup(Setup),
    Step(Step),
    Close,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Setup {
    pub protocol: u32,
    pub host: String,
    pub port: u16,
    /// CARLA client timeout for connecting and for every call (s).
    pub timeout_s: f64,
    /// Client timeout while the server builds the OpenDRIVE world (s).
    pub load_timeout_s: f64,
    /// The OpenDRIVE map, whole.
    pub xodr: String,
    /// Fixed simulation step = carla-gs's control period (s).
    pub step_s: f64,
    pub adversary: Adversary,
    /// Every actor that may be replayed (`id`, class, box), whether present now or later.
    pub actors: Vec<ActorSpec>,
    /// Wheelbase of carla-gs's vehicle model (m), for the fake server's bicycle.
    pub wheelbase_m: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Adversary {
    pub blueprint: String,
    pub transform: CarlaTransform,
    /// Initial speed along the yaw (m/s).
    pub speed_mps: f64,
    pub size_lwh: [f64; 3],
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ActorSpec {
    pub id: String,
    /// carla-gs object class (`vehicle`, `pedestrian`, `cyclist`, `sign`, `other`).
    pub class: String,
    pub size_lwh: [f64; 3],
}

/// One control period: the PID's command and where every replayed actor is at the end of it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Step {
    /// Log time at the start of the period (s), for the bridge's logs.
    pub t: f64,
    pub control: Control,
    pub actors: Vec<ActorPose>,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ActorPose {
    pub id: String,
    pub transform: CarlaTransform,
}

/// bridge -> carla-gs.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Reply {
    Ready { protocol: u32, server_version: String, map: String, frame: u64 },
    State(State),
    Error { kind: String, message: String },
    Closed,
}

/// The adversary after one tick.
#[derive(Clone, Debug, PartialEq, Deserialize)]
pub struct State {
    pub frame: u64,
    pub transform: CarlaTransform,
    /// m/s.
    pub velocity: [f64; 3],
    /// m/s^2.
    pub acceleration: [f64; 3],
    /// deg/s.
    pub angular_velocity: [f64; 3],
    /// Front-left wheel steer angle (deg, positive = right).
    pub steer_angle: f64,
    /// Collision-sensor events since the last state.
    #[serde(default)]
    pub collisions: Vec<Collision>,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
pub struct Collision {
    pub frame: u64,
    /// The replayed actor's id (`ego` or a track id), or `carla:<type id>` for anything else.
    pub other: String,
    #[serde(default)]
    pub other_type: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_have_the_documented_shape() {
        let step = Request::Step(Step {
            t: 1.5,
            control: Control { throttle: 0.5, brake: 0.0, steer: -0.1 },
            actors: vec![ActorPose {
                id: "ego".into(),
                transform: CarlaTransform { x: 1.0, y: -2.0, z: 0.0, yaw_deg: 90.0 },
            }],
        });
        let v = serde_json::to_value(&step).unwrap();
        assert_eq!(v["type"], "step");
        assert_eq!(v["control"]["steer"], -0.1);
        assert_eq!(v["actors"][0]["transform"]["yaw"], 90.0);
        assert_eq!(serde_json::to_value(Request::Close).unwrap()["type"], "close");
        let line = r#"{"type":"state","frame":7,"transform":{"x":1,"y":2,"z":0,"yaw":-45},"velocity":[1,0,0],"acceleration":[0,0,0],"angular_velocity":[0,0,3],"steer_angle":2.5,"collisions":[{"frame":7,"other":"ego","other_type":"vehicle.x"}]}"#;
        let Reply::State(s) = serde_json::from_str(line).unwrap() else { panic!("not a state") };
        assert_eq!((s.frame, s.transform.yaw_deg, s.collisions[0].other.as_str()), (7, -45.0, "ego"));
        let e: Reply = serde_json::from_str(r#"{"type":"error","kind":"no_server","message":"m"}"#).unwrap();
        assert_eq!(e, Reply::Error { kind: "no_server".into(), message: "m".into() });
        assert!(serde_json::from_str::<Reply>(r#"{"type":"state","frame":1}"#).is_err());
    }
}
