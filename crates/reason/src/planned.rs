//! The planner's limits (speed, acceleration, jerk, yaw rate, curvature and its rate, the
//! closing rate it aims at) and what a planned trajectory predicts ([`Planned`]), with the two
//! rules every trajectory builder shares: the paper's centre TTC and the adversary's velocity
//! at its target ([`end_velocity`]). Below the planner (`planner`), its sampling grid
//! (`sampling`) and the pedestrians' and cyclists' trajectories (`vru`).

use crate::behavior::EndPolicy;
use crate::world::{Kin, Vehicle};
use scene::glam::DVec2;
use scene::{PlanPath, Waypoint};

pub const PLAN_MAX_SPEED: f64 = 35.0;
pub const PLAN_MAX_ACCEL: f64 = 7.5;
pub const PLAN_MAX_JERK: f64 = 30.0;
/// Trackability bounds: yaw rate (rad/s) and curvature (1/m) of the planned path.
pub const PLAN_MAX_YAW_RATE: f64 = 1.2;
pub const PLAN_MAX_CURVATURE: f64 = 0.25;
/// Curvature-rate bound (1/(m s)). A 0.4 rad/s steering-rate limit on a 2.6 m wheelbase gives
/// about 0.15, but finite differences at 0.1 s are noisy and the tracker's look-ahead cuts
/// corners: on the shared logs, bounds of 0.3 and 0.5 dropped plans that executed well, 1.0 kept
/// them (see BENCHMARKS.md). It only rejects clearly untrackable kinks.
pub const PLAN_MAX_CURVATURE_RATE: f64 = 1.0;
/// A vehicle slower than this starts along its body heading at this acceleration (m/s^2).
pub const START_ACCEL: f64 = 2.0;
/// Aimed centre TTC at the target (s): the end velocity is chosen to close in at this rate.
pub const AIM_TTC_S: f64 = 0.6;
/// A planned trajectory and what it predicts, measured like the metrics (0.1 s grid from t0).
#[derive(Clone, Debug)]
pub struct Planned {
    pub waypoints: Vec<Waypoint>,
    /// Predicted centre MinTTC against the ego's logged motion (s).
    pub min_ttc: f64,
    pub peak_accel: f64,
    /// Adversary centre in the ego frame at the instant of minimum centre distance.
    pub closest_local: DVec2,
    /// The first logged actor other than the ego the path touches (id, time), if any.
    pub contact_with: Option<(String, f64)>,
    /// Along the adversary's lane, or a straight-line quintic ([`crate::lane_motion`]).
    pub path: PlanPath,
    /// Which lanes it follows, or why it does not.
    pub path_note: String,
}

/// Paper centre TTC (capped at 5 s) for one instant.
pub fn center_ttc(p_ego: DVec2, v_ego: DVec2, p_adv: DVec2, v_adv: DVec2) -> f64 {
    scene::motion::center_ttc(p_ego, v_ego, p_adv, v_adv, 5.0)
}

/// The adversary's velocity when it reaches `target`, from the behaviour's end policy and the
/// ego's logged state `ego` at that time: close in on the ego at `|target - ego| / AIM_TTC_S`.
pub fn end_velocity(policy: EndPolicy, ego: &Kin, target: DVec2, adversary: &Vehicle, aim_ttc: f64) -> DVec2 {
    let h = DVec2::new(ego.heading.cos(), ego.heading.sin());
    let v_e = ego.v.dot(h).max(0.0);
    let gap = target.distance(ego.p);
    let closing = (gap / aim_ttc).clamp(2.0, 15.0);
    match policy {
        EndPolicy::SlowerAhead => h * (v_e - closing).max(0.0),
        EndPolicy::FasterBehind => h * (v_e + closing),
        EndPolicy::AlongsideClosing => {
            let toward = (ego.p - target).dot(h.perp()).signum() * h.perp();
            h * (v_e + 2.0) + toward * (closing * 0.5).min(3.0)
        }
        EndPolicy::Oncoming => -h * adversary.now.speed().max(6.0),
        // On foot, heading for the target (`vru` tries faster paces too).
        EndPolicy::Crossing => (target - adversary.now.p).normalize_or_zero() * scene::mobility::WALKING_SPEED,
    }
}
