//! Executing a pedestrian's or cyclist's plan. Neither is a car: no PID on pedals and steering,
//! no tyres. Both track the same smoothed reference as a vehicle ([`crate::prepare::prepare`]:
//! the logged run up to t0, then the plan's waypoints, "from frame 0") with a feedback law that
//! asks for an acceleration, and a motion model that grants only what the class can do
//! ([`scene::mobility`]):
//!
//! * **pedestrian**: a point mass; |acceleration| <= `max_accel`, speed <= `max_speed`, turning
//!   on the spot allowed; its heading is its direction of motion (kept while it stands).
//! * **cyclist**: a kinematic single track, curvature-controlled (a bicycle's `tan(delta) / L`):
//!   it moves along its heading, never backwards; acceleration along it in [-`max_decel`,
//!   `max_accel`], speed <= `max_speed`, curvature <= `max_curvature` and `v^2 kappa <=
//!   max_lat_accel`.
//!
//! Demanded acceleration: `a = a_ref + KP (p_ref - p) + KD (v_ref - v)` with `KP = 4 1/s^2`,
//! `KD = 4 1/s` (critically damped at 2 rad/s), recomputed every control period and held over
//! the physics sub-steps (semi-implicit Euler). The records are the vehicle's ([`StepRecord`]:
//! state `[x, y, 0, speed, heading, yaw rate, 0]`, no pedals), so validity and the output are
//! the same code; a pedestrian is not held to road edges (stepping off the kerb is the point), and
//! touching another pedestrian's box is not a contact (groups walk closer than their boxes).

use crate::actuation::Control;
use crate::collision::{cuboid, first_overlap, Replayed};
use crate::error::SimError;
use crate::prepare::{finish, Prepared};
use crate::rollout_config::RolloutConfig;
use crate::tracker::{control_steps, StepRecord, TrackError};
use scene::executed::Contact;
use scene::glam::DVec2;
use scene::mobility::MotionLimits;
use scene::motion::Pose2;
use scene::{Executed, ObjectClass, Plan, Scene};

/// Position and velocity gains of the feedback law (1/s^2, 1/s).
pub const KP: f64 = 4.0;
pub const KD: f64 = 4.0;
/// Half-window of the reference's acceleration by central differences (s).
const ACCEL_HALF_WINDOW_S: f64 = 0.05;

/// The backend line written into the output.
pub fn backend(class: ObjectClass, l: &MotionLimits) -> String {
    match l.max_curvature {
        None => format!(
            "carla-gs physics: {} point mass (v <= {} m/s, |a| <= {} m/s^2) tracking a smoothed reference",
            class.as_str(),
            l.max_speed,
            l.max_accel
        ),
        Some(k) => format!(
            "carla-gs physics: {} kinematic single track (v <= {} m/s, a in [-{}, {}] m/s^2, a_lat <= {} m/s^2, curvature <= {k} 1/m) tracking a smoothed reference",
            class.as_str(),
            l.max_speed,
            l.max_decel,
            l.max_accel,
            l.max_lat_accel
        ),
    }
}

/// The motion state: position, heading, speed (>= 0) along the heading or, for a point mass,
/// its velocity.
#[derive(Clone, Copy, Debug)]
struct Body {
    p: DVec2,
    v: DVec2,
    heading: f64,
}

/// Applies demanded acceleration `a` for `h` seconds within `l`; returns the granted
/// (along, lateral) acceleration and the yaw rate.
fn step(b: &mut Body, a: DVec2, l: &MotionLimits, h: f64) -> (f64, f64, f64) {
    let dir = DVec2::new(b.heading.cos(), b.heading.sin());
    match l.max_curvature {
        None => {
            let a = a.clamp_length_max(l.max_accel);
            b.v = (b.v + a * h).clamp_length_max(l.max_speed);
            b.p += b.v * h;
            let before = b.heading;
            if b.v.length() > 0.2 {
                b.heading = b.v.y.atan2(b.v.x);
            }
            let yaw = scene::frames::wrap_angle(b.heading - before) / h;
            (a.dot(dir), a.perp_dot(dir).abs(), yaw)
        }
        Some(k_max) => {
            let speed = b.v.length();
            let along = a.dot(dir).clamp(-l.max_decel, l.max_accel);
            let s = (speed + along * h).clamp(0.0, l.max_speed);
            let k_lat = if s > 1e-3 { l.max_lat_accel / (s * s) } else { k_max };
            let kappa = (dir.perp_dot(a) / (s * s).max(1e-6)).clamp(-k_max.min(k_lat), k_max.min(k_lat));
            let yaw = s * kappa;
            b.heading += yaw * h;
            let d = DVec2::new(b.heading.cos(), b.heading.sin());
            b.p += d * s * h;
            b.v = d * s;
            ((s - speed) / h, s * s * kappa, yaw)
        }
    }
}

/// Runs a prepared plan of a pedestrian or cyclist (`l`: its class's limits).
pub fn simulate(
    scene: &Scene,
    plan: &Plan,
    cfg: &RolloutConfig,
    prep: &Prepared,
    l: MotionLimits,
) -> Result<Executed, SimError> {
    let c = &cfg.tracker;
    if !(c.control_dt_s > 0.0 && c.max_physics_dt_s > 0.0 && c.max_physics_dt_s <= c.control_dt_s) {
        return Err(TrackError::Config(format!(
            "need 0 < max_physics_dt_s ({}) <= control_dt_s ({})",
            c.max_physics_dt_s, c.control_dt_s
        ))
        .into());
    }
    let r = &prep.reference;
    let x0 = prep.initial;
    let heading0 = x0[4];
    let mut b = Body {
        p: DVec2::new(x0[0], x0[1]),
        v: DVec2::new(heading0.cos(), heading0.sin()) * x0[3].clamp(0.0, l.max_speed),
        heading: heading0,
    };
    let (adv_box, adv_radius) = cuboid(prep.size[0], prep.size[1]);
    // People walk in groups, closer than their boxes: a pedestrian's contacts are with vehicles,
    // cyclists and the ego only.
    let pedestrian = prep.adversary.class == ObjectClass::Pedestrian;
    let actors: Vec<Replayed> =
        prep.actors.iter().filter(|a| !(pedestrian && a.class == ObjectClass::Pedestrian)).cloned().collect();
    let mut contact: Option<Contact> = None;
    let record = |t: f64, b: &Body, along: f64, lat: f64, yaw: f64| StepRecord {
        t,
        state: [b.p.x, b.p.y, 0.0, b.v.length(), b.heading, yaw, 0.0],
        control: Control::default(),
        accel_long: along,
        accel_lat: lat,
        reference: r.position(t),
        friction_limit_s: 0.0,
    };
    let mut records = vec![record(prep.t_start, &b, 0.0, 0.0, 0.0)];
    let n = control_steps(prep.t_start, prep.t_end, c.control_dt_s);
    for k in 0..n {
        let t = prep.t_start + k as f64 * c.control_dt_s;
        let period = c.control_dt_s.min(prep.t_end - t);
        let h = ACCEL_HALF_WINDOW_S;
        let a_ref = (r.velocity(t + h) - r.velocity(t - h)) / (2.0 * h);
        let a = a_ref + (r.position(t) - b.p) * KP + (r.velocity(t) - b.v) * KD;
        let (mut elapsed, mut granted) = (0.0, (0.0, 0.0, 0.0));
        while elapsed < period - 1e-12 {
            let dt = (period - elapsed).min(c.max_physics_dt_s);
            granted = step(&mut b, a, &l, dt);
            elapsed += dt;
            if !(b.p.is_finite() && b.v.is_finite()) {
                return Err(TrackError::Diverged { t: t + elapsed }.into());
            }
            let ts = t + elapsed;
            if contact.is_none() && ts >= prep.t0 - 1e-9 {
                let pose = Pose2 { t: ts, x: b.p.x, y: b.p.y, heading: b.heading };
                if let Some(o) = first_overlap(&actors, &pose, &adv_box, adv_radius) {
                    contact = Some(Contact { t: ts, other: o.id.clone(), class: o.class });
                }
            }
        }
        records.push(record(t + period, &b, granted.0, granted.1, granted.2));
    }
    let physics_dt = c.max_physics_dt_s;
    Ok(finish(scene, plan, cfg, prep, &records, contact, backend(prep.adversary.class, &l), physics_dt))
}

#[cfg(test)]
mod tests {
    use super::*;
    use scene::mobility::{CYCLIST, PEDESTRIAN};

    #[test]
    fn a_point_mass_never_exceeds_its_limits_and_a_cyclist_cannot_turn_on_the_spot() {
        let mut p = Body { p: DVec2::ZERO, v: DVec2::ZERO, heading: 0.0 };
        for _ in 0..300 {
            let (along, lat, _) = step(&mut p, DVec2::new(50.0, 50.0), &PEDESTRIAN, 0.01);
            assert!(along.hypot(lat) <= PEDESTRIAN.max_accel + 1e-9 && p.v.length() <= PEDESTRIAN.max_speed + 1e-9);
        }
        assert!((p.v.length() - PEDESTRIAN.max_speed).abs() < 1e-9, "reaches its top speed: {:?}", p.v);
        // A cyclist at rest asked to go sideways cannot: it has no speed to turn with.
        let mut c = Body { p: DVec2::ZERO, v: DVec2::ZERO, heading: 0.0 };
        let _ = step(&mut c, DVec2::new(0.0, 5.0), &CYCLIST, 0.01);
        assert_eq!(c.p, DVec2::ZERO);
        // Riding at 8 m/s and asked for 20 m/s^2 sideways, it turns at the lateral limit.
        let mut c = Body { p: DVec2::ZERO, v: DVec2::new(8.0, 0.0), heading: 0.0 };
        let (_, lat, yaw) = step(&mut c, DVec2::new(0.0, 20.0), &CYCLIST, 0.01);
        assert!((lat - CYCLIST.max_lat_accel).abs() < 1e-9 && yaw > 0.0, "{lat} {yaw}");
        // Asked to brake at 10 m/s^2, it brakes at its limit.
        let mut c = Body { p: DVec2::ZERO, v: DVec2::new(8.0, 0.0), heading: 0.0 };
        let (along, _, _) = step(&mut c, DVec2::new(-10.0, 0.0), &CYCLIST, 0.01);
        assert!((along + CYCLIST.max_decel).abs() < 1e-9, "{along}");
    }
}
