//! The paper's baselines, written in the same plan format.
//!
//! * **Rule-based**: takes the vehicle nearest to the ego and picks from its position at t0
//!   (ego frame): ahead with |y| < 2 m -> brake at -3 m/s^2 (front zone); behind -> tailgate at
//!   +2 m/s^2 (back zone); otherwise -> cut in with a smooth 2 s lateral move onto the ego's lane
//!   line (front zone), keeping its speed. (The original jumped the whole lateral offset every step.)
//! * **Random**: a seeded random vehicle in range follows seeded piecewise-constant perturbations
//!   of acceleration (|a| <= 3 m/s^2) and yaw rate (|w| <= 0.3 rad/s), each held 0.5 s, from its
//!   state at t0 (unicycle model, speed kept in [0, 35] m/s). Its zone is the zone its end point is
//!   nearest to. (The original was unseeded.)
//!
//! Both run for `BASELINE_TTC_S` (3 s) or what is left of the log, and ignore the requested
//! behaviour like the originals; the plan records the behaviour they actually perform (random:
//! the requested one, else the one matching its zone).

use crate::validate::{parse_risk, ZoneDecision};
use crate::world::{Vehicle, World};
use crate::{make_plan, Outcome, ReasonOptions};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use scene::glam::DVec2;
use scene::zones::zone_rect;
use scene::{Behavior, Waypoint, Zone};

pub const BASELINE_TTC_S: f64 = 3.0;

fn duration(world: &World, dt: f64) -> Option<f64> {
    let d = BASELINE_TTC_S.min(world.horizon());
    let d = (d / dt).floor() * dt;
    (d >= 2.0 * dt).then_some(d)
}

/// Integrates a unicycle from the vehicle's state: `accel(t)`, `yaw_rate(t)` (held per step).
fn unicycle(world: &World, v: &Vehicle, dur: f64, dt: f64, mut input: impl FnMut(f64) -> (f64, f64)) -> Vec<Waypoint> {
    let n = (dur / dt).round() as usize;
    let (mut p, mut speed) = (v.now.p, v.now.speed());
    let mut heading = if speed > 0.5 { v.now.v.y.atan2(v.now.v.x) } else { v.now.heading };
    let mut out = vec![Waypoint { t: world.t0, x: p.x, y: p.y }];
    for k in 0..n {
        let (a, w) = input(k as f64 * dt);
        let s_next = (speed + a * dt).clamp(0.0, 35.0);
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

pub fn rule_based(world: &World, o: &ReasonOptions) -> Outcome {
    let Some(dur) = duration(world, o.dt) else {
        return Outcome::NoFeasible { reason: "the log ends too soon after t0".into() };
    };
    let Some(v) = world.vehicles.first() else {
        return Outcome::NoFeasible { reason: "no vehicle within range".into() };
    };
    let local = world.to_ego_now(v.now.p);
    let (zone, behavior, waypoints, why) = if local.x > 0.0 && local.y.abs() < 2.0 {
        (
            Zone::Front,
            Behavior::SuddenBraking,
            unicycle(world, v, dur, o.dt, |_| (-3.0, 0.0)),
            "ahead in the ego lane: brake at -3 m/s^2",
        )
    } else if local.x < 0.0 {
        (
            Zone::Back,
            Behavior::RearTailgating,
            unicycle(world, v, dur, o.dt, |_| (2.0, 0.0)),
            "behind: tailgate at +2 m/s^2",
        )
    } else {
        // Smooth 2 s lateral move onto the ego's lane line, constant speed along the ego's heading.
        let h = DVec2::new(world.ego_now.heading.cos(), world.ego_now.heading.sin());
        let n = h.perp();
        let along = v.now.v.dot(h);
        let lateral = -local.y;
        let n_steps = (dur / o.dt).round() as usize;
        let w = (0..=n_steps)
            .map(|k| {
                let t = k as f64 * o.dt;
                let s = (t / 2.0).min(1.0);
                let shift = lateral * (0.5 - 0.5 * (std::f64::consts::PI * s).cos());
                let p = v.now.p + h * along * t + n * shift;
                Waypoint { t: world.t0 + t, x: p.x, y: p.y }
            })
            .collect();
        (Zone::Front, Behavior::SuddenCutIn, w, "beside the ego: cut in over 2 s")
    };
    let end = waypoints.last().map(|w| DVec2::new(w.x, w.y)).expect("non-empty");
    let d = decision(v, zone, behavior, dur, format!("rule-based baseline: vehicle {} is nearest; {why}", v.id));
    Outcome::Plan { plan: make_plan(world, o, &d, waypoints, end, "rule"), stats: None }
}

pub fn random(world: &World, o: &ReasonOptions) -> Outcome {
    let Some(dur) = duration(world, o.dt) else {
        return Outcome::NoFeasible { reason: "the log ends too soon after t0".into() };
    };
    if world.vehicles.is_empty() {
        return Outcome::NoFeasible { reason: "no vehicle within range".into() };
    }
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed);
    let v = &world.vehicles[rng.random_range(0..world.vehicles.len())];
    let holds = (dur / 0.5).ceil() as usize + 1;
    let inputs: Vec<(f64, f64)> =
        (0..holds).map(|_| (rng.random_range(-3.0..=3.0), rng.random_range(-0.3..=0.3))).collect();
    let waypoints = unicycle(world, v, dur, o.dt, |t| inputs[((t + 1e-9) / 0.5) as usize]);
    let end = waypoints.last().map(|w| DVec2::new(w.x, w.y)).expect("non-empty");
    let local = world.ego_pose(world.t0 + dur).to_local(end);
    let zone = Zone::ALL
        .into_iter()
        .min_by(|a, b| {
            let da = zone_rect(*a, o.layout, world.ego_length, world.ego_width).center().distance(local);
            let db = zone_rect(*b, o.layout, world.ego_length, world.ego_width).center().distance(local);
            da.total_cmp(&db)
        })
        .expect("four zones");
    let behavior = o.behavior.unwrap_or(match zone {
        Zone::Front => Behavior::SuddenBraking,
        Zone::Back => Behavior::RearTailgating,
        Zone::Left | Zone::Right => Behavior::SidePass,
    });
    let d = decision(v, zone, behavior, dur, format!("random baseline: seeded perturbations of vehicle {}", v.id));
    Outcome::Plan { plan: make_plan(world, o, &d, waypoints, end, "random"), stats: None }
}
