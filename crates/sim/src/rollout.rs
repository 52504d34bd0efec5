//! Executes a plan in a scene: "PID from frame 0". The adversary starts on its logged pose at
//! the beginning of its logged run that contains the plan's start time, follows its logged path
//! up to the start time and the plan's waypoints after it, all through PID + vehicle model. The
//! ego and every other actor replay their logged poses. After every physics sub-step from the
//! start time on, the adversary's box is tested against every other box; the first contact is
//! recorded (the rollout continues to the plan's end: the trajectory is what gets rendered).
//!
//! The reference is the logged path and the plan's waypoints **smoothed** together (`smooth.rs`):
//! perception jitter in the log neither sets the initial speed and heading nor reaches the
//! steering. The rollout's physical validity (`validity.rs`) is written into the output.
//! Pedestrians and cyclists are prepared the same way but move by their own model (`vru.rs`).

pub use crate::prepare::{finish, prepare, with_inserted, Prepared, MAX_START_OFFSET_M};
pub use crate::rollout_config::RolloutConfig;

use crate::collision::{cuboid, first_overlap};
use crate::error::SimError;
use crate::tracker::Tracker;
use scene::executed::Contact;
use scene::motion::Pose2;
use scene::{Executed, Plan, Scene};

pub const BACKEND: &str =
    "carla-gs physics: CommonRoad ST (vehicle2, friction-limited tyres, 1 rad/s steering) + CARLA-like actuation + CARLA VehiclePIDController on a smoothed reference";

/// Runs the plan with the built-in physics. Checks the plan against the scene first; an
/// inserted adversary ([`scene::inserted`]) joins the scene as a track first.
pub fn simulate(scene: &Scene, plan: &Plan, cfg: &RolloutConfig) -> Result<Executed, SimError> {
    let scene = &*with_inserted(scene, plan)?;
    let prep = prepare(scene, plan, cfg)?;
    if let Some(limits) = prep.adversary.class.motion_limits() {
        // A pedestrian or cyclist: its own motion model (`vru`), not a car's.
        return crate::vru::simulate(scene, plan, cfg, &prep, limits);
    }
    let (adv_box, adv_radius) = cuboid(prep.size[0], prep.size[1]);
    let mut contact: Option<Contact> = None;
    let tracker = Tracker { config: &cfg.tracker, vehicle: &cfg.vehicle, actuation: &cfg.actuation };
    let t0 = prep.t0;
    let records = tracker.run(&prep.reference, prep.initial, prep.t_start, prep.t_end, |t, x| {
        if contact.is_some() || t < t0 - 1e-9 {
            return;
        }
        let pose = Pose2 { t, x: x[0], y: x[1], heading: x[4] };
        if let Some(a) = first_overlap(&prep.actors, &pose, &adv_box, adv_radius) {
            contact = Some(Contact { t, other: a.id.clone(), class: a.class });
        }
    })?;
    let physics_dt = cfg.tracker.max_physics_dt_s;
    Ok(finish(scene, plan, cfg, &prep, &records, contact, BACKEND.to_string(), physics_dt))
}
