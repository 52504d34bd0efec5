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
    Carla(#[from] crate::carla::CarlaError),
}
