//! `sim`: the Execute stage. A plan's waypoints become a physically feasible trajectory:
//! CARLA's `VehiclePIDController` (`pid`) drives a CARLA-like actuation layer (`actuation`) on
//! CommonRoad's single-track model (`model`, parameters in `params`), tracking a timed
//! reference (`reference`, smoothed from noisy logs by `smooth`, tracked by `tracker`) with
//! friction-limited tyres (`tyre`); `rollout` runs a whole plan in a scene with oriented-box
//! collision checks against the replayed log (`collision`) and judges the rollout's physical
//! validity (`validity`). No CARLA server is needed; users who have one can run the same plans in
//! CARLA 0.9.16 through a bridge process (`carla`), with the same control law and output. One
//! control period of the vehicle under any held command is `plant` (the tracker's and a
//! closed-loop driver's physics alike).
//! Pedestrians and cyclists are not cars: they move by their class's model and limits (`vru`).
//! Step counts and rates are checked against `budget` before a rollout starts, every field of
//! the configuration against a plausible range (`config_check`) when it is read and again then.

pub mod actuation;
pub mod budget;
pub mod carla;
pub mod collision;
pub mod config_check;
pub mod error;
pub mod model;
pub mod params;
pub mod pid;
pub mod plant;
pub mod prepare;
pub mod reference;
pub mod rollout;
pub mod rollout_config;
pub mod smooth;
pub mod tracker;
pub mod tyre;
pub mod validity;
pub mod vru;

pub use error::SimError;
pub use rollout::{simulate, RolloutConfig};
