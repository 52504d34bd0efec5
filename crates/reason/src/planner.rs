//! The deterministic planner: a search over (vehicle, zone, TTC, collision target) for the
//! behaviour, scoring each candidate by kinematic feasibility and the centre TTC it would create
//! against the ego's logged motion, all computed in code. It is an agent on its own (`--agent
//! planner`) and the repair step for invalid LLM proposals.
//!
//! For a candidate, the adversary's trajectory is a quintic from its state at t0 (position,
//! velocity from real timestamps, zero acceleration) to the collision target at t0 + TTC with the
//! behaviour's end velocity (see [`end_velocity`]) and zero acceleration, sampled at dt. It is
//! feasible if speed <= 35 m/s, |acceleration| <= 7.5 m/s^2, |jerk| <= 30 m/s^3 (finite
//! differences at dt, inside validation's 40 m/s and 8 m/s^2) and it never reverses. Score: the
//! predicted centre MinTTC over the interval (lower is more critical), plus 0.02 per m/s^2 of
//! peak acceleration as a tie-breaker for smoother plans.

use crate::behavior::{candidate_zones, spec, EndPolicy};
use crate::quintic::{limits, End, Quintic};
use crate::target::sample_target;
use crate::world::{Kin, Vehicle, World};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use scene::glam::DVec2;
use scene::{Behavior, Risk, Waypoint, Zone, ZoneLayout};

pub const PLAN_MAX_SPEED: f64 = 35.0;
pub const PLAN_MAX_ACCEL: f64 = 7.5;
pub const PLAN_MAX_JERK: f64 = 30.0;
/// Aimed centre TTC at the target (s): the end velocity is chosen to close in at this rate.
pub const AIM_TTC_S: f64 = 0.6;
const TTC_STEP_S: f64 = 0.5;
const TARGETS_PER_CANDIDATE: usize = 3;

#[derive(Clone, Debug)]
pub struct Candidate {
    pub vehicle_id: String,
    pub behavior: Behavior,
    pub zone: Zone,
    pub ttc_s: f64,
    pub target: DVec2,
    pub waypoints: Vec<Waypoint>,
    pub predicted_min_ttc: f64,
    pub peak_accel: f64,
    pub score: f64,
}

impl Candidate {
    pub fn risk(&self) -> Risk {
        match self.predicted_min_ttc {
            t if t < 0.5 => Risk::Critical,
            t if t < 1.0 => Risk::High,
            t if t < 2.0 => Risk::Medium,
            _ => Risk::Low,
        }
    }
}

/// Paper centre TTC (capped at 5 s) for one instant.
pub fn center_ttc(p_ego: DVec2, v_ego: DVec2, p_adv: DVec2, v_adv: DVec2) -> f64 {
    let r = p_adv - p_ego;
    let d = r.length();
    if d == 0.0 {
        return 0.0;
    }
    let closing = -r.dot(v_adv - v_ego) / d;
    if closing > 0.0 {
        (d / closing).min(5.0)
    } else {
        5.0
    }
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
    }
}

/// Builds and scores the trajectory of `v` to `target` at `t0 + ttc`; `None` if infeasible.
pub fn trajectory_to(
    world: &World,
    v: &Vehicle,
    b: Behavior,
    target: DVec2,
    ttc: f64,
    dt: f64,
) -> Option<(Vec<Waypoint>, f64, f64)> {
    trajectory_to_aim(world, v, b, target, ttc, dt, AIM_TTC_S)
}

/// [`trajectory_to`] with the closing rate aimed at centre TTC `aim_ttc` at the target.
pub fn trajectory_to_aim(
    world: &World,
    v: &Vehicle,
    b: Behavior,
    target: DVec2,
    ttc: f64,
    dt: f64,
    aim_ttc: f64,
) -> Option<(Vec<Waypoint>, f64, f64)> {
    let t_end = world.t0 + ttc;
    let ego_end = world.ego_kin(t_end);
    let v_end = end_velocity(spec(b).end_policy, &ego_end, target, v, aim_ttc);
    let q =
        Quintic::new(End { p: v.now.p, v: v.now.v, a: DVec2::ZERO }, End { p: target, v: v_end, a: DVec2::ZERO }, ttc);
    let waypoints = q.waypoints(world.t0, dt);
    let l = limits(&waypoints);
    if l.max_speed > PLAN_MAX_SPEED || l.max_accel > PLAN_MAX_ACCEL || l.max_jerk > PLAN_MAX_JERK || l.reversal {
        return None;
    }
    let min_ttc = waypoints
        .iter()
        .enumerate()
        .map(|(k, w)| {
            let s = (k as f64 * dt).min(ttc);
            let e = world.ego_kin(w.t);
            center_ttc(e.p, e.v, DVec2::new(w.x, w.y), q.velocity(s))
        })
        .fold(f64::INFINITY, f64::min);
    Some((waypoints, min_ttc, l.max_accel))
}

/// TTC values the search tries for a behaviour within the log's horizon.
pub fn ttc_grid(world: &World, b: Behavior, dt: f64) -> Vec<f64> {
    let s = spec(b);
    let max = s.ttc_max.min(world.horizon());
    let mut out = Vec::new();
    let mut t = s.ttc_min;
    while t <= max + 1e-9 {
        out.push((t / dt).round() * dt);
        t += TTC_STEP_S;
    }
    out
}

/// Every feasible candidate for behaviour `b`, best first. `Err` explains why there is none.
pub fn search(world: &World, b: Behavior, layout: ZoneLayout, dt: f64, seed: u64) -> Result<Vec<Candidate>, String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    let mut eligible = 0;
    let grid = ttc_grid(world, b, dt);
    if grid.is_empty() {
        return Err(format!(
            "the log ends {:.1} s after t0, shorter than {}'s shortest TTC {:.1} s",
            world.horizon(),
            b.as_str(),
            spec(b).ttc_min
        ));
    }
    for v in &world.vehicles {
        let Ok(zones) = candidate_zones(world, v, b) else { continue };
        eligible += 1;
        for zone in zones {
            out.extend(search_vehicle_zone(world, v, b, zone, layout, &grid, dt, &mut rng));
        }
    }
    if out.is_empty() {
        return Err(if eligible == 0 {
            format!("no vehicle within range is positioned for {} ({})", b.as_str(), spec(b).description)
        } else {
            format!("{eligible} vehicle(s) are positioned for {} but none can reach a target zone within the speed, acceleration and jerk limits", b.as_str())
        });
    }
    out.sort_by(|a, b| a.score.total_cmp(&b.score));
    Ok(out)
}

/// Candidates of one vehicle and zone over the TTC grid (seeded targets).
#[allow(clippy::too_many_arguments)]
pub fn search_vehicle_zone(
    world: &World,
    v: &Vehicle,
    b: Behavior,
    zone: Zone,
    layout: ZoneLayout,
    grid: &[f64],
    dt: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<Candidate> {
    let mut out = Vec::new();
    for &ttc in grid {
        for _ in 0..TARGETS_PER_CANDIDATE {
            let target = sample_target(world, zone, layout, ttc, rng);
            if let Some((waypoints, predicted_min_ttc, peak_accel)) = trajectory_to(world, v, b, target, ttc, dt) {
                out.push(Candidate {
                    vehicle_id: v.id.clone(),
                    behavior: b,
                    zone,
                    ttc_s: ttc,
                    target,
                    waypoints,
                    predicted_min_ttc,
                    peak_accel,
                    score: predicted_min_ttc + 0.02 * peak_accel,
                });
            }
        }
    }
    out
}
