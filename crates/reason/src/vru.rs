//! Plans for pedestrians and cyclists ("vulnerable road users"), with their own motion limits
//! ([`scene::mobility`]) instead of a car's: the planner ([`crate::planner::trajectory_to`])
//! hands them here.
//!
//! * A **pedestrian** is a point mass: a quintic from its position and velocity at t0 to the
//!   collision target, heading for it (`step_out`). It tries to arrive at walking pace
//!   ([`scene::mobility::WALKING_SPEED`]), then jogging and running pace, and keeps the feasible
//!   one with the smallest peak acceleration. Feasible: speed <= `max_speed`, |acceleration| <=
//!   `max_accel` (finite differences at dt, as validation measures).
//! * A **cyclist** moves like a car, along its heading with bounded curvature, but with a
//!   cyclist's limits: the behaviour's end velocity (capped at `max_speed`, or 70 % of it, or its
//!   own speed along the ego's heading with the behaviour's drift across), a
//!   quintic from its state at t0 (path first from below 1 m/s, [`crate::from_rest`], starting at
//!   [`CYCLIST_START_ACCEL`]); feasible if speed <= `max_speed`, acceleration along the motion in
//!   [-`max_decel`, `max_accel`], across it <= `max_lat_accel`, curvature <= `max_curvature`, and
//!   it never rides backwards.
//!
//! Each plan is measured as the planner measures a car's (predicted centre MinTTC against the
//! ego's logged motion, closest approach in the ego frame, first contact with a logged bystander;
//! for a pedestrian, other pedestrians are not bystanders it can crash into).

use crate::behavior::{spec, EndPolicy};
use crate::clearance::Bystanders;
use crate::from_rest::FromRest;
use crate::planned::{center_ttc, end_velocity, Planned, PLAN_MAX_JERK};
use crate::quintic::{limits, trackability, End, Quintic};
use crate::world::{Vehicle, World};
use scene::glam::DVec2;
use scene::mobility::{MotionLimits, WALKING_SPEED};
use scene::{Behavior, ObjectClass, Waypoint};

/// A cyclist slower than 1 m/s pulls away along its heading at this acceleration (m/s^2).
pub const CYCLIST_START_ACCEL: f64 = 1.0;
/// Paces a pedestrian may arrive at (m/s), slowest first; capped at its top speed.
const PEDESTRIAN_PACES: [f64; 3] = [WALKING_SPEED, 2.5, 3.5];
const TOL: f64 = 1e-6;

/// Extremes of waypoints against a class's limits (finite differences at the waypoints' dt).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VruPeaks {
    pub max_speed: f64,
    /// Largest |acceleration|.
    pub max_accel: f64,
    /// Largest acceleration and deceleration along the motion, largest across it (m/s^2).
    pub max_along: f64,
    pub max_decel: f64,
    pub max_lateral: f64,
}

/// Measures `w` the way [`check_limits`] judges it.
pub fn peaks(w: &[Waypoint]) -> VruPeaks {
    let v: Vec<DVec2> =
        w.windows(2).map(|p| DVec2::new(p[1].x - p[0].x, p[1].y - p[0].y) / (p[1].t - p[0].t)).collect();
    let mut out = VruPeaks { max_speed: v.iter().map(|x| x.length()).fold(0.0, f64::max), ..VruPeaks::default() };
    for (pair, p) in v.windows(2).zip(w.windows(3)) {
        let a = (pair[1] - pair[0]) / ((p[2].t - p[0].t) / 2.0);
        out.max_accel = out.max_accel.max(a.length());
        let mean = (pair[0] + pair[1]) / 2.0;
        if let Some(dir) = mean.try_normalize().filter(|_| mean.length() > 0.3) {
            let along = a.dot(dir);
            out.max_along = out.max_along.max(along);
            out.max_decel = out.max_decel.max(-along);
            out.max_lateral = out.max_lateral.max(a.perp_dot(dir).abs());
        } else {
            // Nearly at rest: all of it counts both ways.
            out.max_along = out.max_along.max(a.length());
        }
    }
    out
}

/// Whether waypoints of a road user of `class` (body heading `heading0` at the start) stay within
/// its limits; `Err` lists every limit exceeded, with the numbers.
pub fn check_limits(w: &[Waypoint], class: ObjectClass, heading0: f64) -> Result<VruPeaks, Vec<String>> {
    let Some(l) = class.motion_limits() else { return Err(vec![format!("a {} has no motion limits", class.as_str())]) };
    let p = peaks(w);
    let name = class.as_str();
    let mut why = Vec::new();
    if p.max_speed > l.max_speed + TOL {
        why.push(format!("speed reaches {:.1} m/s (a {name} at most {})", p.max_speed, l.max_speed));
    }
    match l.max_curvature {
        None => {
            if p.max_accel > l.max_accel + TOL {
                why.push(format!("acceleration reaches {:.1} m/s^2 (a {name} at most {})", p.max_accel, l.max_accel));
            }
        }
        Some(k_max) => {
            if p.max_along > l.max_accel + TOL {
                why.push(format!("accelerates at {:.1} m/s^2 (a {name} at most {})", p.max_along, l.max_accel));
            }
            if p.max_decel > l.max_decel + TOL {
                why.push(format!("brakes at {:.1} m/s^2 (a {name} at most {})", p.max_decel, l.max_decel));
            }
            if p.max_lateral > l.max_lat_accel + TOL {
                why.push(format!(
                    "lateral acceleration reaches {:.1} m/s^2 (a {name} at most {})",
                    p.max_lateral, l.max_lat_accel
                ));
            }
            let tr = trackability(w, heading0);
            if tr.backward {
                why.push(format!("it moves backwards (a {name} rides along its heading)"));
            }
            if tr.max_curvature > k_max + TOL {
                why.push(format!("curvature reaches {:.2} 1/m (a {name} at most {k_max})", tr.max_curvature));
            }
        }
    }
    if why.is_empty() {
        Ok(p)
    } else {
        Err(why)
    }
}

/// End velocities to try, in order of preference.
fn end_velocities(
    world: &World,
    v: &Vehicle,
    b: Behavior,
    target: DVec2,
    ttc: f64,
    aim_ttc: f64,
    l: &MotionLimits,
) -> Vec<DVec2> {
    let ego_end = world.ego_kin(world.t0 + ttc);
    let policy = spec(b).end_policy;
    let base = end_velocity(policy, &ego_end, target, v, aim_ttc);
    if policy == EndPolicy::Crossing {
        let dir = base.normalize_or_zero();
        return PEDESTRIAN_PACES.iter().map(|s| dir * s.min(l.max_speed)).collect();
    }
    let capped = base.clamp_length_max(l.max_speed);
    // Or keep pedalling at its own pace along the ego's heading (a cyclist slower than the ego
    // closes in by being slower), with the policy's drift across.
    let h = DVec2::new(ego_end.heading.cos(), ego_end.heading.sin());
    let own = h * v.now.speed().min(l.max_speed) + h.perp() * capped.dot(h.perp());
    vec![capped, capped * 0.7, own.clamp_length_max(l.max_speed)]
}

/// The trajectory of pedestrian or cyclist `v` to `target` at `t0 + ttc`; `None` if no end
/// velocity gives one within its limits.
pub fn trajectory_to(
    world: &World,
    v: &Vehicle,
    b: Behavior,
    target: DVec2,
    ttc: f64,
    dt: f64,
    aim_ttc: f64,
) -> Option<Planned> {
    let l = v.class.motion_limits()?;
    let body = DVec2::new(v.now.heading.cos(), v.now.heading.sin());
    let mut best: Option<(Vec<Waypoint>, VruPeaks)> = None;
    for v_end in end_velocities(world, v, b, target, ttc, aim_ttc, &l) {
        let waypoints = if l.max_curvature.is_some() && v.now.speed() < 1.0 {
            let speed = v.now.v.dot(body).max(0.0);
            let Some(m) = FromRest::new(v.now.p, v.now.heading, speed, CYCLIST_START_ACCEL, target, v_end, ttc) else {
                continue;
            };
            m.waypoints(world.t0, dt)
        } else {
            let start = End { p: v.now.p, v: v.now.v.clamp_length_max(l.max_speed), a: DVec2::ZERO };
            Quintic::new(start, End { p: target, v: v_end, a: DVec2::ZERO }, ttc).waypoints(world.t0, dt)
        };
        let lim = limits(&waypoints);
        if lim.max_jerk > PLAN_MAX_JERK || (l.max_curvature.is_some() && lim.reversal) {
            continue;
        }
        let Ok(p) = check_limits(&waypoints, v.class, v.now.heading) else { continue };
        if best.as_ref().is_none_or(|(_, q)| p.max_accel < q.max_accel) {
            best = Some((waypoints, p));
        }
    }
    let (waypoints, p) = best?;
    Some(measure(world, v, waypoints, dt, p.max_accel))
}

/// What a plan predicts, measured like the planner's (0.1 s grid from t0).
fn measure(world: &World, v: &Vehicle, waypoints: Vec<Waypoint>, dt: f64, peak_accel: f64) -> Planned {
    let pos = |w: &Waypoint| DVec2::new(w.x, w.y);
    let closest = waypoints
        .iter()
        .map(|w| (w, world.ego_pose(w.t)))
        .min_by(|(a, ea), (b, eb)| ea.position().distance(pos(a)).total_cmp(&eb.position().distance(pos(b))))
        .map(|(w, e)| e.to_local(pos(w)))
        .expect("non-empty");
    let n = waypoints.len();
    let min_ttc = (0..n)
        .map(|k| {
            // Central differences inside, one-sided at the ends.
            let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
            let vel = (pos(&waypoints[b]) - pos(&waypoints[a])) / ((b - a) as f64 * dt);
            let e = world.ego_kin(waypoints[k].t);
            center_ttc(e.p, e.v, pos(&waypoints[k]), vel)
        })
        .fold(f64::INFINITY, f64::min);
    let mut near = Bystanders::near(world.scene, &v.id, &waypoints);
    if v.class == ObjectClass::Pedestrian {
        // People walk in groups, closer than their boxes: only vehicles and cyclists count.
        near = near.ignoring(ObjectClass::Pedestrian);
    }
    let contact_with = near.first_contact(&waypoints, v.now.heading, v.length, v.width);
    // Pedestrians and cyclists move in free space here: their paths are never lane-aware.
    let path_note = format!("{:?}: free path (lanes are for vehicles)", v.class).to_lowercase();
    Planned {
        waypoints,
        min_ttc,
        peak_accel,
        closest_local: closest,
        contact_with,
        path: scene::PlanPath::StraightLine,
        path_note,
    }
}
