//! Errors of the physics stage: each names the plan field or track and what was expected.

use crate::tracker::TrackError;

#[derive(Debug, thiserror::Error)]
pub enum SimError {
    #[error("plan: `{field}`: {message}")]
    Plan { field: String, message: String },
    #[error("plan: `adversary_track`: track `{0}` is not in the scene")]
    UnknownTrack(String),
    #[error(
        "plan: `adversary_track`: track `{id}` is not present at the start time {t:.3} s (no logged state around it)"
    )]
    NotPresent { id: String, t: f64 },
    #[error("plan: `{field}`: {t:.3} s is outside the scene's time span [{first:.3}, {last:.3}] s")]
    OutsideScene { field: &'static str, t: f64, first: f64, last: f64 },
    #[error("plan: `scene`: made for scene `{plan}`, not `{scene}`")]
    WrongScene { plan: String, scene: String },
    #[error(
        "plan: `waypoints[0]`: starts {distance:.2} m from track `{id}`'s logged position at t0 (at most {max} m)"
    )]
    FarFromLog { id: String, distance: f64, max: f64 },
    #[error("rollout configuration: `{field}`: {message}")]
    Config { field: String, message: String },
    #[error("rollout: {0}")]
    Track(#[from] TrackError),
    #[error("rollout: {0}")]
    Reference(String),
    #[error("plan: `adversary_track`: track `{id}` is a {class}; {backend} drives vehicles only (the built-in physics moves pedestrians and cyclists)")]
    VehicleOnly { id: String, class: &'static str, backend: &'static str },
    /// Its messages say they are about CARLA (and are not repeated as a source).
    #[error(transparent)]
    Carla(#[from] CarlaError),
}

/// Errors of the CARLA backend; each says what was being waited for and what to check.
#[derive(Debug, thiserror::Error)]
pub enum CarlaError {
    #[error("no CARLA server answered at {host}:{port} within the {timeout_s} s timeout ({message}); start the server (CarlaUnreal.sh / CarlaUE4.sh) or fix --carla-host/--carla-port, or raise --carla-timeout")]
    NoServer { host: String, port: u16, timeout_s: f64, message: String },
    #[error("cannot start the CARLA bridge `{program}`: {message} (set CARLA_GS_PYTHON to a Python with `carla==0.9.16`, or run tools/setup.sh)")]
    Start { program: String, message: String },
    #[error("the CARLA bridge exited while {waiting_for}; its last output:\n{stderr}")]
    Exited { waiting_for: String, stderr: String },
    #[error("the CARLA bridge sent nothing for {seconds} s while waiting for {waiting_for}; stopped it. Its last output:\n{stderr}")]
    Silent { waiting_for: String, seconds: f64, stderr: String },
    #[error("the CARLA bridge reported `{kind}`: {message}")]
    Bridge { kind: String, message: String },
    #[error("CARLA bridge protocol: {0}")]
    Protocol(String),
    #[error("CARLA backend option `{field}`: {message}")]
    Option { field: &'static str, message: String },
    #[error("writing the OpenDRIVE map for CARLA: {0}")]
    Map(String),
}
