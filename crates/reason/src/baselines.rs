//! The paper's baselines, written in the same plan format. Both honour the requested behaviour,
//! so that every agent is judged on the same (scene, behaviour, t0) attempt.
//!
//! * **Rule-based**: the vehicle nearest to the ego that is positioned for the behaviour
//!   ([`candidate_zones`], the same test the planner uses) performs a fixed manoeuvre, in the
//!   ego's frame at t0, aimed at the behaviour's first zone: braking -> brake at -3 m/s^2;
//!   lead swerve -> a 1.5 m S-shape over 2 s, then brake at -3 m/s^2; cut-in -> a smooth 2 s
//!   lateral move onto the ego's lane line at constant speed; tailgating -> +2 m/s^2; side pass and
//!   blind-spot appearance -> +2 m/s^2 and a 2 s lateral move to the middle of the side zone;
//!   sudden start -> +2 m/s^2 from rest and a 3 s move onto the ego's lane line; opposing drift ->
//!   constant speed and a 2 s move onto the zone's centre line. No vehicle positioned for the
//!   behaviour -> "no feasible" with the planner's wording. With no behaviour requested it picks
//!   the first behaviour (library order) that the nearest positioned vehicle can perform.
//! * **Random**: draws, in this order from one seeded generator, the target zone (uniform over the
//!   behaviour's zones, all four when none is requested), a collision target in it, the vehicle
//!   (uniform among those in range), then piecewise-constant perturbations of acceleration
//!   (|a| <= 3 m/s^2) and yaw rate (|w| <= 0.3 rad/s), each held 0.5 s, from the vehicle's state at
//!   t0 (unicycle, speed kept in [0, 35] m/s). The zone never depends on where the motion ends.
//!
//! Both plan for `BASELINE_TTC_S` (3 s) or what is left of the log; the evaluation then runs every
//! agent's plan over one common horizon (`cases`).

use crate::behavior::{candidate_zones, class_can, spec, who_performs};
use crate::target::sample_target;
use crate::validate::{parse_risk, ZoneDecision};
use crate::world::{Vehicle, World};
use crate::{make_plan, Outcome, ReasonOptions};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use scene::glam::DVec2;
use scene::zones::zone_rect;
use scene::{Behavior, ObjectClass, Waypoint, Zone};

pub const BASELINE_TTC_S: f64 = 3.0;

fn duration(world: &World, dt: f64) -> Option<f64> {
    let d = BASELINE_TTC_S.min(world.horizon());
    let d = (d / dt).floor() * dt;
    (d >= 2.0 * dt).then_some(d)
}

/// Integrates a unicycle from the vehicle's state: `accel(t)`, `yaw_rate(t)` (held per step).
fn unicycle(
    world: &World,
    v: &Vehicle,
    dur: f64,
    dt: f64,
    top_speed: f64,
    mut input: impl FnMut(f64) -> (f64, f64),
) -> Vec<Waypoint> {
    let n = (dur / dt).round() as usize;
    let (mut p, mut speed) = (v.now.p, v.now.speed());
    let mut heading = if speed > 0.5 { v.now.v.y.atan2(v.now.v.x) } else { v.now.heading };
    let mut out = vec![Waypoint { t: world.t0, x: p.x, y: p.y }];
    for k in 0..n {
        let (a, w) = input(k as f64 * dt);
        let s_next = (speed + a * dt).clamp(0.0, top_speed);
        let avg = (speed + s_next) / 2.0;
        heading += w * dt;
        p += DVec2::new(heading.cos(), heading.sin()) * avg * dt;
        speed = s_next;
        out.push(Waypoint { t: world.t0 + (k + 1) as f64 * dt, x: p.x, y: p.y });
    }
    out
}

fn decision(v: &Vehicle, zone: Zone, behavior: Behavior, ttc: f64, reasoning: String) -> ZoneDecision {
    ZoneDecision {
        vehicle_id: v.id.clone(),
        zone,
        behavior,
        ttc_s: ttc,
        risk: parse_risk("medium").expect("valid"),
        analysis: String::new(),
        reasoning,
    }
}

/// A rule manoeuvre in the ego's frame at t0: acceleration along the ego's heading (m/s^2, as a
/// function of time) and the lateral offset (m, ego frame, y left) as a function of time.
type Lateral = Box<dyn Fn(f64) -> f64>;

struct Manoeuvre {
    accel: fn(f64) -> f64,
    lateral: Lateral,
    what: String,
}

/// Smooth 0 -> 1 over `span` seconds (half a cosine).
fn ease(t: f64, span: f64) -> f64 {
    0.5 - 0.5 * (std::f64::consts::PI * (t / span).clamp(0.0, 1.0)).cos()
}

fn manoeuvre(b: Behavior, y0: f64, zone_y: f64) -> Manoeuvre {
    use Behavior::*;
    let shift = move |to: f64, span: f64| -> Lateral { Box::new(move |t| y0 + (to - y0) * ease(t, span)) };
    let hold: Lateral = Box::new(move |_| y0);
    let (accel, lateral, what): (fn(f64) -> f64, Lateral, &str) = match b {
        SuddenBraking => (|_| -3.0, hold, "brake at -3 m/s^2"),
        LeadSwerve => (
            |t| if t < 2.0 { 0.0 } else { -3.0 },
            Box::new(move |t| y0 + if t < 2.0 { 1.5 * (std::f64::consts::PI * t).sin() } else { 0.0 }),
            "1.5 m S-shape over 2 s, then brake at -3 m/s^2",
        ),
        SuddenCutIn => (|_| 0.0, shift(0.0, 2.0), "cut onto the ego's lane line over 2 s"),
        RearTailgating => (|_| 2.0, hold, "close in at +2 m/s^2"),
        SidePass | BlindSpotAppearance => {
            (|_| 2.0, shift(zone_y, 2.0), "accelerate at +2 m/s^2 and move to the side zone's middle over 2 s")
        }
        SuddenStart => (|_| 2.0, shift(0.0, 3.0), "pull away at +2 m/s^2 onto the ego's lane line over 3 s"),
        OpposingDrift => (|_| 0.0, shift(zone_y, 2.0), "drift onto the zone's centre line over 2 s"),
        // Half a cosine peaks at pi/2 times its mean speed: walking pace on average.
        StepOut => (
            |_| 0.0,
            shift(0.0, (y0.abs() / scene::mobility::WALKING_SPEED).max(1.0)),
            "step out onto the ego's lane line at walking pace",
        ),
    };
    Manoeuvre { accel, lateral, what: what.to_string() }
}

/// Waypoints of a manoeuvre: along the ego's heading the vehicle keeps its sign of motion (a
/// forward-moving car brakes to rest, never reverses; an oncoming one keeps its speed), capped at
/// 35 m/s; across it follows the manoeuvre's lateral offset.
fn follow(world: &World, v: &Vehicle, m: &Manoeuvre, dur: f64, dt: f64) -> Vec<Waypoint> {
    let h = DVec2::new(world.ego_now.heading.cos(), world.ego_now.heading.sin());
    let n = h.perp();
    let y0 = world.to_ego_now(v.now.p).y;
    let mut along = v.now.v.dot(h);
    let mut s = 0.0;
    let steps = (dur / dt).round() as usize;
    let mut out = Vec::with_capacity(steps + 1);
    for k in 0..=steps {
        let t = k as f64 * dt;
        let p = v.now.p + h * s + n * ((m.lateral)(t) - y0);
        out.push(Waypoint { t: world.t0 + t, x: p.x, y: p.y });
        let next = if along >= 0.0 { (along + (m.accel)(t) * dt).clamp(0.0, 35.0) } else { along };
        s += 0.5 * (along + next) * dt;
        along = next;
    }
    out
}

pub fn rule_based(world: &World, o: &ReasonOptions) -> Outcome {
    let Some(dur) = duration(world, o.dt) else {
        return Outcome::NoFeasible { reason: "the log ends too soon after t0".into() };
    };
    let behaviours: Vec<Behavior> = o.behavior.map_or(Behavior::EVERY.to_vec(), |b| vec![b]);
    // Vehicles are nearest first; the first one positioned for a behaviour performs it. The
    // paper's behaviours are performed by vehicles, as in the original; `step_out` by the nearest
    // positioned pedestrian (pedestrians come after every vehicle and can only step out).
    let pedestrians = world.vulnerable.iter().filter(|v| v.class == ObjectClass::Pedestrian);
    let chosen = world
        .vehicles
        .iter()
        .chain(pedestrians)
        .find_map(|v| behaviours.iter().find_map(|b| candidate_zones(world, v, *b).ok().map(|z| (v, *b, z[0]))));
    let Some((v, behavior, zone)) = chosen else {
        return Outcome::NoFeasible {
            reason: match o.behavior {
                Some(b) => {
                    format!(
                        "no {} within range is positioned for {} ({})",
                        who_performs(b),
                        b.as_str(),
                        spec(b).description
                    )
                }
                None => "no vehicle within range is positioned for any behaviour".into(),
            },
        };
    };
    let zone_y = zone_rect(zone, o.layout, world.ego_length, world.ego_width).center().y;
    let m = manoeuvre(behavior, world.to_ego_now(v.now.p).y, zone_y);
    let waypoints = follow(world, v, &m, dur, o.dt);
    let end = waypoints.last().map(|w| DVec2::new(w.x, w.y)).expect("non-empty");
    let why = format!(
        "rule-based baseline: {} {} is the nearest positioned for {}; {}",
        v.class.as_str(),
        v.id,
        behavior.as_str(),
        m.what
    );
    let d = decision(v, zone, behavior, dur, why);
    Outcome::Plan { plan: make_plan(world, o, &d, waypoints, end, "rule"), stats: None }
}

pub fn random(world: &World, o: &ReasonOptions) -> Outcome {
    let Some(dur) = duration(world, o.dt) else {
        return Outcome::NoFeasible { reason: "the log ends too soon after t0".into() };
    };
    // Vehicles, as in the original; pedestrians for `step_out`, which no vehicle performs.
    let pool: Vec<&Vehicle> = match o.behavior {
        Some(b) if !class_can(ObjectClass::Vehicle, b) => world.actors().filter(|v| class_can(v.class, b)).collect(),
        _ => world.vehicles.iter().collect(),
    };
    if pool.is_empty() {
        return Outcome::NoFeasible {
            reason: match o.behavior {
                Some(b) if !class_can(ObjectClass::Vehicle, b) => {
                    format!("no {} within range", who_performs(b))
                }
                _ => "no vehicle within range".into(),
            },
        };
    }
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed);
    // The target first: it never depends on the motion drawn after it.
    let zones: &[Zone] = o.behavior.map_or(&Zone::ALL[..], |b| spec(b).zones);
    let zone = zones[rng.random_range(0..zones.len())];
    let target = sample_target(world, zone, o.layout, dur, &mut rng);
    let v = pool[rng.random_range(0..pool.len())];
    let holds = (dur / 0.5).ceil() as usize + 1;
    let inputs: Vec<(f64, f64)> =
        (0..holds).map(|_| (rng.random_range(-3.0..=3.0), rng.random_range(-0.3..=0.3))).collect();
    let top = v.class.motion_limits().map_or(35.0, |l| l.max_speed);
    let waypoints = unicycle(world, v, dur, o.dt, top, |t| inputs[((t + 1e-9) / 0.5) as usize]);
    let behavior = o.behavior.unwrap_or(match zone {
        Zone::Front => Behavior::SuddenBraking,
        Zone::Back => Behavior::RearTailgating,
        Zone::Left | Zone::Right => Behavior::SidePass,
    });
    let d = decision(
        v,
        zone,
        behavior,
        dur,
        format!("random baseline: seeded perturbations of {} {}", v.class.as_str(), v.id),
    );
    Outcome::Plan { plan: make_plan(world, o, &d, waypoints, target, "random"), stats: None }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ease_and_manoeuvres() {
        assert_eq!(ease(0.0, 2.0), 0.0);
        assert!((ease(1.0, 2.0) - 0.5).abs() < 1e-12);
        assert_eq!(ease(5.0, 2.0), 1.0);
        let cut = manoeuvre(Behavior::SuddenCutIn, 3.6, 0.0);
        assert!(((cut.lateral)(0.0) - 3.6).abs() < 1e-12 && (cut.lateral)(2.5).abs() < 1e-12);
        let swerve = manoeuvre(Behavior::LeadSwerve, 0.0, 0.0);
        assert!(((swerve.lateral)(0.5) - 1.5).abs() < 1e-12 && (swerve.accel)(2.5) < 0.0);
        assert_eq!((manoeuvre(Behavior::RearTailgating, 0.0, 0.0).accel)(1.0), 2.0);
    }
}
