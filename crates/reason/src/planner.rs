//! The deterministic planner: a search over (vehicle, zone, TTC, collision target) for the
//! behaviour, scoring each candidate by kinematic feasibility and the centre TTC it would create
//! against the ego's logged motion, all computed in code. It is an agent on its own (`--agent
//! planner`) and the repair step for invalid LLM proposals.
//!
//! For a candidate, the adversary's trajectory is a quintic from its state at t0 (position,
//! velocity from real timestamps, zero acceleration) to the collision target at t0 + TTC with the
//! behaviour's end velocity (see [`end_velocity`]) and zero acceleration, sampled at dt. It is
//! feasible if speed <= 35 m/s, |acceleration| <= 7.5 m/s^2, |jerk| <= 30 m/s^3 (finite
//! differences at dt, inside validation's 40 m/s and 8 m/s^2), it never reverses or moves
//! backwards relative to the car's body, and its yaw rate (<= 1.2 rad/s), curvature
//! (<= 0.25 1/m) and curvature rate (<= 1.0 1/(m s), a loose bound against kinks) are ones a car can
//! track (curvature also measured on the path's geometry, at any speed); a car at rest leaves
//! along its body heading ([`crate::from_rest`]: path first, then a minimum-jerk speed profile
//! starting at [`START_ACCEL`]). Where the map has a lane near the adversary the trajectory
//! follows the lanes instead, with the same end conditions and limits ([`crate::lane_motion`]:
//! a cut-in is a lane change between centrelines), and a front or back target sits on its lane's
//! centre ([`crate::target::on_lane_centre`]); [`Candidate::path`] records which. Each
//! candidate is measured the way the metrics will measure its execution: the predicted centre
//! MinTTC and whether, at the closest approach to the ego, it is inside the target zone. Score
//! ([`score`]): predicted MinTTC >= 1 s ranks last, then lower MinTTC, then 0.02 per m/s^2 of
//! peak acceleration (smoother); a path that touches a logged bystander before the ego
//! ([`crate::clearance`]) ranks after every clear one. A candidate whose predicted closest
//! approach falls outside the target zone ranks after every predicted hit but is **kept**:
//! "no feasible vehicle" means that no vehicle can perform the behaviour (positioned for it, and a
//! trajectory within the limits above), decided before any metric is predicted; a predicted miss
//! is returned when nothing better exists and its miss is counted by the evaluation.

use crate::behavior::{candidate_zones, spec, EndPolicy};
use crate::early_lateral::EarlyLateral;
use crate::from_rest::FromRest;
use crate::lane_motion::LaneMotion;
pub use crate::planned::{
    center_ttc, end_velocity, Planned, AIM_TTC_S, PLAN_MAX_ACCEL, PLAN_MAX_CURVATURE, PLAN_MAX_CURVATURE_RATE,
    PLAN_MAX_JERK, PLAN_MAX_SPEED, PLAN_MAX_YAW_RATE, START_ACCEL,
};
use crate::quintic::{limits, trackability, End, Quintic};
pub use crate::sampling::{closing_ttcs, ttc_grid, ttc_grid_step, Breadth, Shape, MIN_EGO_SPEED_AHEAD};
use crate::target::{on_lane_centre, sample_target};
use crate::world::{Vehicle, World};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use scene::glam::DVec2;
use scene::zones::zone_rect;
use scene::{Behavior, PlanPath, Risk, Waypoint, Zone, ZoneLayout};

#[derive(Clone, Debug)]
pub struct Candidate {
    pub vehicle_id: String,
    pub behavior: Behavior,
    pub zone: Zone,
    pub ttc_s: f64,
    pub target: DVec2,
    pub waypoints: Vec<Waypoint>,
    pub predicted_min_ttc: f64,
    /// At the predicted closest approach the adversary is in the target zone.
    pub predicted_zone_hit: bool,
    pub peak_accel: f64,
    /// Predicted first contact with a logged actor other than the ego (id, time): ranked after
    /// every clear candidate ([`CONTACT_PENALTY`]).
    pub predicted_contact_with: Option<(String, f64)>,
    pub score: f64,
    /// Along the adversary's lane, or a straight-line quintic, and which lanes or why not.
    pub path: PlanPath,
    pub path_note: String,
}

/// Score added to a candidate whose path touches a bystander first (after zone misses).
pub const CONTACT_PENALTY: f64 = 20.0;

/// Lower is better: predicted misses of the zone and of TTC < 1 s rank after every hit, then the
/// predicted MinTTC, then peak acceleration.
pub fn score(min_ttc: f64, peak_accel: f64, zone_hit: bool) -> f64 {
    min_ttc + 0.02 * peak_accel + if zone_hit { 0.0 } else { 10.0 } + if min_ttc < 1.0 { 0.0 } else { 5.0 }
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

/// The behaviour's end policy, except that side-approach behaviours aiming behind the ego
/// close in from behind.
fn end_policy(b: Behavior, world: &World, target: DVec2, ttc: f64) -> EndPolicy {
    let p = spec(b).end_policy;
    let local = world.ego_pose(world.t0 + ttc).to_local(target);
    if p == EndPolicy::AlongsideClosing && local.x < -world.ego_length / 2.0 {
        EndPolicy::FasterBehind
    } else {
        p
    }
}

/// Builds and scores the trajectory of `v` to `target` at `t0 + ttc`; `None` if infeasible.
pub fn trajectory_to(world: &World, v: &Vehicle, b: Behavior, target: DVec2, ttc: f64, dt: f64) -> Option<Planned> {
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
) -> Option<Planned> {
    trajectory_shaped(world, v, b, target, ttc, dt, aim_ttc, Shape::Quintic)
}

/// [`trajectory_to_aim`] with a straight-line path of `shape`; `Shape::EarlyLateral` applies
/// only to a moving vehicle in a scene without lanes and an end velocity along the ego's
/// heading (`None` otherwise: the other shapes cover it).
#[allow(clippy::too_many_arguments)]
pub fn trajectory_shaped(
    world: &World,
    v: &Vehicle,
    b: Behavior,
    target: DVec2,
    ttc: f64,
    dt: f64,
    aim_ttc: f64,
    shape: Shape,
) -> Option<Planned> {
    if v.class != scene::ObjectClass::Vehicle {
        if shape != Shape::Quintic {
            return None;
        }
        // Pedestrians and cyclists: their own motion and limits.
        return crate::vru::trajectory_to(world, v, b, target, ttc, dt, aim_ttc);
    }
    let t_end = world.t0 + ttc;
    let ego_end = world.ego_kin(t_end);
    let v_end = end_velocity(end_policy(b, world, target, ttc), &ego_end, target, v, aim_ttc);
    let body = DVec2::new(v.now.heading.cos(), v.now.heading.sin());
    if shape == Shape::EarlyLateral && (world.lanes.is_some() || v.now.speed() < 1.0) {
        return None;
    }
    // Along the adversary's lane where the map has one near it; else a straight-line quintic.
    let lane = match &world.lanes {
        Some(lanes) => LaneMotion::new(lanes, v, target, v_end, ttc, START_ACCEL),
        None => Err("the scene has no lane map".to_string()),
    };
    let (motion, path, path_note) = match lane {
        Ok(m) => {
            let ids: Vec<String> = m.path.lane_ids.iter().map(|id| id.to_string()).collect();
            (Motion::Lane(Box::new(m)), PlanPath::LaneFollowing, format!("along lane(s) {}", ids.join(", ")))
        }
        // A car at rest can only start along its body heading (forward): path first, then speed.
        Err(why) if v.now.speed() < 1.0 => {
            let speed = v.now.v.dot(body).max(0.0);
            let m = FromRest::new(v.now.p, v.now.heading, speed, START_ACCEL, target, v_end, ttc)?;
            (Motion::FromRest(m), PlanPath::StraightLine, why)
        }
        Err(why) if shape == Shape::EarlyLateral => {
            let heading = world.ego_pose(t_end).heading;
            let m = EarlyLateral::new(v.now.p, v.now.v, target, v_end, ttc, heading)?;
            (Motion::Early(m), PlanPath::StraightLine, format!("{why}; sideways first"))
        }
        Err(why) => (
            Motion::Quintic(Quintic::new(
                End { p: v.now.p, v: v.now.v, a: DVec2::ZERO },
                End { p: target, v: v_end, a: DVec2::ZERO },
                ttc,
            )),
            PlanPath::StraightLine,
            why,
        ),
    };
    let waypoints = motion.waypoints(world.t0, dt);
    let l = limits(&waypoints);
    if l.max_speed > PLAN_MAX_SPEED || l.max_accel > PLAN_MAX_ACCEL || l.max_jerk > PLAN_MAX_JERK || l.reversal {
        return None;
    }
    let tr = trackability(&waypoints, v.now.heading);
    if tr.backward
        || tr.max_yaw_rate > PLAN_MAX_YAW_RATE
        || tr.max_curvature > PLAN_MAX_CURVATURE
        || tr.max_curvature_rate > PLAN_MAX_CURVATURE_RATE
    {
        return None;
    }
    let closest = waypoints
        .iter()
        .map(|w| (w, world.ego_pose(w.t)))
        .min_by(|(a, ea), (b, eb)| {
            ea.position().distance(DVec2::new(a.x, a.y)).total_cmp(&eb.position().distance(DVec2::new(b.x, b.y)))
        })
        .map(|(w, e)| e.to_local(DVec2::new(w.x, w.y)))
        .expect("non-empty");
    let min_ttc = waypoints
        .iter()
        .enumerate()
        .map(|(k, w)| {
            let s = (k as f64 * dt).min(ttc);
            let e = world.ego_kin(w.t);
            center_ttc(e.p, e.v, DVec2::new(w.x, w.y), motion.velocity(s))
        })
        .fold(f64::INFINITY, f64::min);
    let contact_with = world.bystanders().first_contact_near(&v.id, &waypoints, v.now.heading, v.length, v.width);
    Some(Planned { waypoints, min_ttc, peak_accel: l.max_accel, closest_local: closest, contact_with, path, path_note })
}

/// The adversary's motion from t0: along its lane, a per-axis quintic, or path-then-speed from rest.
enum Motion {
    Lane(Box<LaneMotion>),
    Quintic(Quintic),
    FromRest(FromRest),
    Early(EarlyLateral),
}

impl Motion {
    fn waypoints(&self, t0: f64, dt: f64) -> Vec<Waypoint> {
        match self {
            Motion::Lane(m) => m.waypoints(t0, dt),
            Motion::Quintic(q) => q.waypoints(t0, dt),
            Motion::FromRest(m) => m.waypoints(t0, dt),
            Motion::Early(m) => m.waypoints(t0, dt),
        }
    }

    fn velocity(&self, s: f64) -> DVec2 {
        match self {
            Motion::Lane(m) => m.velocity(s),
            Motion::Quintic(q) => q.velocity(s),
            Motion::FromRest(m) => m.velocity(s),
            Motion::Early(m) => m.velocity(s),
        }
    }
}

/// Every feasible candidate for behaviour `b`, best first. `Err` explains why there is none.
pub fn search(world: &World, b: Behavior, layout: ZoneLayout, dt: f64, seed: u64) -> Result<Vec<Candidate>, String> {
    search_with(world, b, layout, dt, seed, Breadth::DEFAULT)
}

/// [`search`] sampled as `breadth` says.
pub fn search_with(
    world: &World,
    b: Behavior,
    layout: ZoneLayout,
    dt: f64,
    seed: u64,
    breadth: Breadth,
) -> Result<Vec<Candidate>, String> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut out = Vec::new();
    let mut eligible = 0;
    let grid = ttc_grid_step(world, b, dt, breadth.ttc_step_s);
    if grid.is_empty() {
        return Err(format!(
            "the log ends {:.1} s after t0, shorter than {}'s shortest TTC {:.1} s",
            world.horizon(),
            b.as_str(),
            spec(b).ttc_min
        ));
    }
    let closing = closing_ttcs(world, b, &grid);
    for v in world.actors() {
        let Ok(zones) = candidate_zones(world, v, b) else { continue };
        eligible += 1;
        for zone in zones {
            out.extend(search_vehicle_zone_with(world, v, b, zone, layout, &closing, dt, &mut rng, breadth));
        }
    }
    if out.is_empty() {
        let who = crate::behavior::who_performs(b);
        return Err(if eligible == 0 {
            format!("no {who} within range is positioned for {} ({})", b.as_str(), spec(b).description)
        } else if closing.is_empty() {
            format!("{eligible} {who}(s) are positioned for {}, but the ego stands still (below {MIN_EGO_SPEED_AHEAD} m/s) at every target time: ending slower ahead of it, nothing closes in", b.as_str())
        } else {
            format!("{eligible} {who}(s) are positioned for {} but none can reach a target zone within the speed, acceleration, jerk, yaw-rate and curvature limits", b.as_str())
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
    search_vehicle_zone_with(world, v, b, zone, layout, grid, dt, rng, Breadth::DEFAULT)
}

/// [`search_vehicle_zone`] sampled as `breadth` says (the TTC grid is the caller's).
#[allow(clippy::too_many_arguments)]
pub fn search_vehicle_zone_with(
    world: &World,
    v: &Vehicle,
    b: Behavior,
    zone: Zone,
    layout: ZoneLayout,
    grid: &[f64],
    dt: f64,
    rng: &mut ChaCha8Rng,
    breadth: Breadth,
) -> Vec<Candidate> {
    let mut out = Vec::new();
    let pairs = grid.iter().flat_map(|&ttc| (0..breadth.targets).map(move |_| ttc));
    for ttc in pairs {
        let target = on_lane_centre(world, zone, layout, ttc, sample_target(world, zone, layout, ttc, rng));
        let shaped = breadth.aim_ttcs.iter().flat_map(|&aim| breadth.shapes.iter().map(move |&sh| (aim, sh)));
        for (aim, shape) in shaped {
            if let Some(p) = trajectory_shaped(world, v, b, target, ttc, dt, aim, shape) {
                // A predicted miss ranks last (see `score`) but stays: the metric decides, not the search.
                let hit = zone_rect(zone, layout, world.ego_length, world.ego_width).contains(p.closest_local);
                out.push(Candidate {
                    vehicle_id: v.id.clone(),
                    behavior: b,
                    zone,
                    ttc_s: ttc,
                    target,
                    score: score(p.min_ttc, p.peak_accel, hit)
                        + if p.contact_with.is_some() { CONTACT_PENALTY } else { 0.0 },
                    waypoints: p.waypoints,
                    predicted_min_ttc: p.min_ttc,
                    predicted_zone_hit: hit,
                    peak_accel: p.peak_accel,
                    predicted_contact_with: p.contact_with,
                    path: p.path,
                    path_note: p.path_note,
                });
            }
        }
    }
    out
}
