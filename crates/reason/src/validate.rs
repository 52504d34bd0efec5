//! Validation of every agent reply (LLMs propose, code checks). Zone decisions: the behaviour is
//! the requested one, the vehicle exists and is present at t0, the zone is one of four and one
//! the vehicle can reach for that behaviour, TTC in (0, horizon]. Trajectories: finite, strictly
//! increasing times at exactly the requested dt from t0 to t0 + TTC, start within 0.5 m of the
//! vehicle, end within 0.5 m of the collision target, speed <= 40 m/s, |acceleration| <= 8 m/s^2.

use crate::behavior::candidate_zones;
use crate::quintic::limits;
use crate::reply::{Violation, WaypointReply, ZoneReply};
use crate::world::World;
use scene::glam::DVec2;
use scene::{Behavior, Risk, Waypoint, Zone};

pub const START_TOLERANCE_M: f64 = 0.5;
pub const END_TOLERANCE_M: f64 = 0.5;
pub const MAX_SPEED: f64 = 40.0;
pub const MAX_ACCEL: f64 = 8.0;
const TIME_TOLERANCE: f64 = 1e-6;

/// A validated Zone agent decision.
#[derive(Clone, Debug, PartialEq)]
pub struct ZoneDecision {
    pub vehicle_id: String,
    pub zone: Zone,
    pub behavior: Behavior,
    pub ttc_s: f64,
    pub risk: Risk,
    pub analysis: String,
    pub reasoning: String,
}

pub fn parse_risk(s: &str) -> Option<Risk> {
    match s {
        "low" => Some(Risk::Low),
        "medium" => Some(Risk::Medium),
        "high" => Some(Risk::High),
        "critical" => Some(Risk::Critical),
        _ => None,
    }
}

/// Checks a Zone reply; `requested` is the user's behaviour (`None` = auto).
pub fn validate_zone(
    world: &World,
    r: &ZoneReply,
    requested: Option<Behavior>,
) -> Result<ZoneDecision, Vec<Violation>> {
    let mut v = Vec::new();
    let behavior = match r.behavior.parse::<Behavior>() {
        Ok(b) if requested.is_some_and(|q| q != b) => {
            v.push(Violation::new(
                "behavior",
                format!("must be `{}` (the requested behaviour), got `{b:?}`", requested.map_or("", |q| q.as_str())),
            ));
            None
        }
        Ok(b) => Some(b),
        Err(e) => {
            v.push(Violation::new("behavior", e));
            None
        }
    };
    let zone = match r.zone.parse::<Zone>() {
        Ok(z) => Some(z),
        Err(e) => {
            v.push(Violation::new("zone", e));
            None
        }
    };
    let risk = parse_risk(&r.risk);
    if risk.is_none() {
        v.push(Violation::new("risk", format!("`{}` is not one of low, medium, high, critical", r.risk)));
    }
    let horizon = world.horizon();
    if !(r.ttc_s.is_finite() && r.ttc_s > 0.0 && r.ttc_s <= horizon + 1e-9) {
        v.push(Violation::new(
            "ttc_s",
            format!("{} is not in (0, {horizon:.2}] s (the log ends {horizon:.2} s after t0)", r.ttc_s),
        ));
    }
    match world.vehicle(&r.vehicle_id) {
        None => {
            let ids: Vec<&str> = world.vehicles.iter().take(12).map(|v| v.id.as_str()).collect();
            v.push(Violation::new(
                "vehicle_id",
                format!(
                    "vehicle `{}` does not exist or is not present at t0 (present: {})",
                    r.vehicle_id,
                    ids.join(", ")
                ),
            ));
        }
        Some(veh) => {
            if let (Some(b), Some(z)) = (behavior, zone) {
                match candidate_zones(world, veh, b) {
                    Err(why) => v.push(Violation::new(
                        "vehicle_id",
                        format!("vehicle `{}` cannot perform {}: {why}", veh.id, b.as_str()),
                    )),
                    Ok(zs) if !zs.contains(&z) => {
                        let names: Vec<&str> = zs.iter().map(|z| z.as_str()).collect();
                        v.push(Violation::new(
                            "zone",
                            format!(
                                "vehicle `{}` performing {} can aim at {} only",
                                veh.id,
                                b.as_str(),
                                names.join(" or ")
                            ),
                        ));
                    }
                    Ok(_) => {}
                }
            }
        }
    }
    if !v.is_empty() {
        return Err(v);
    }
    Ok(ZoneDecision {
        vehicle_id: r.vehicle_id.clone(),
        zone: zone.expect("checked"),
        behavior: behavior.expect("checked"),
        ttc_s: r.ttc_s,
        risk: risk.expect("checked"),
        analysis: r.analysis.clone(),
        reasoning: r.reasoning.clone(),
    })
}

/// Checks trajectory waypoints against the decision and the collision target.
pub fn validate_trajectory(
    world: &World,
    d: &ZoneDecision,
    target: DVec2,
    w: &[WaypointReply],
    dt: f64,
) -> Result<Vec<Waypoint>, Vec<Violation>> {
    let mut v = Vec::new();
    let n = (d.ttc_s / dt).round() as usize + 1;
    if w.len() < 2 {
        return Err(vec![Violation::new(
            "waypoints",
            format!("need {n} waypoints from t0 to t0 + TTC at dt {dt} s, got {}", w.len()),
        )]);
    }
    if let Some(i) = w.iter().position(|p| !(p.t.is_finite() && p.x.is_finite() && p.y.is_finite())) {
        return Err(vec![Violation::new(format!("waypoints[{i}]"), "t, x and y must be finite numbers")]);
    }
    for (i, p) in w.windows(2).enumerate() {
        let step = p[1].t - p[0].t;
        if step <= 0.0 {
            v.push(Violation::new(
                format!("waypoints[{}].t", i + 1),
                format!("times must increase strictly ({} after {})", p[1].t, p[0].t),
            ));
            break;
        }
        if (step - dt).abs() > TIME_TOLERANCE {
            v.push(Violation::new(
                format!("waypoints[{}].t", i + 1),
                format!("spacing {step:.4} s, expected dt = {dt} s"),
            ));
            break;
        }
    }
    if (w[0].t - world.t0).abs() > TIME_TOLERANCE {
        v.push(Violation::new("waypoints[0].t", format!("must be t0 = {:.3} s, got {:.3}", world.t0, w[0].t)));
    }
    let t_end = world.t0 + d.ttc_s;
    let last = w[w.len() - 1];
    if (last.t - t_end).abs() > TIME_TOLERANCE {
        v.push(Violation::new(
            format!("waypoints[{}].t", w.len() - 1),
            format!("the last waypoint must be at t0 + TTC = {t_end:.3} s, got {:.3}", last.t),
        ));
    }
    if let Some(veh) = world.vehicle(&d.vehicle_id) {
        let off = DVec2::new(w[0].x, w[0].y).distance(veh.now.p);
        if off > START_TOLERANCE_M {
            v.push(Violation::new(
                "waypoints[0]",
                format!(
                    "starts {off:.2} m from vehicle `{}` at ({:.2}, {:.2}); must be within {START_TOLERANCE_M} m",
                    veh.id, veh.now.p.x, veh.now.p.y
                ),
            ));
        }
    }
    let miss = DVec2::new(last.x, last.y).distance(target);
    if miss > END_TOLERANCE_M {
        v.push(Violation::new(
            format!("waypoints[{}]", w.len() - 1),
            format!(
                "ends {miss:.2} m from the collision target ({:.2}, {:.2}); must be within {END_TOLERANCE_M} m",
                target.x, target.y
            ),
        ));
    }
    let waypoints: Vec<Waypoint> = w.iter().map(|p| Waypoint { t: p.t, x: p.x, y: p.y }).collect();
    if v.is_empty() {
        let l = limits(&waypoints);
        if l.max_speed > MAX_SPEED {
            v.push(Violation::new("waypoints", format!("speed reaches {:.1} m/s (at most {MAX_SPEED})", l.max_speed)));
        }
        if l.max_accel > MAX_ACCEL {
            v.push(Violation::new(
                "waypoints",
                format!("acceleration reaches {:.1} m/s^2 (at most {MAX_ACCEL})", l.max_accel),
            ));
        }
    }
    if v.is_empty() {
        Ok(waypoints)
    } else {
        Err(v)
    }
}
