//! The user's constraints on a run (`--adversary <track>`, `--zone <z>`, `--ttc <s>`, with
//! `--behavior`): checked up front so that an impossible request is answered with the constraint
//! that rules it out ("track 1584 cannot perform sudden_cut_in into zone left: ..."), and a
//! constrained planner search ([`search`]) that only tries that vehicle, zone and TTC. The Zone
//! agent's reply is held to the same constraints by [`crate::validate::validate_zone`].
//! A pedestrian or cyclist is refused first for its class ("track 12 cannot perform
//! sudden_braking: it is a pedestrian, and pedestrians can perform step_out only").

use crate::behavior::{candidate_zones, class_can, class_refusal, spec, who_performs};
use crate::planner::{search_vehicle_zone_with, ttc_grid_step, Breadth, Candidate};
use crate::validate::snap_ttc;
use crate::world::World;
use crate::ReasonOptions;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use scene::{Behavior, Scene};

/// Why the constraints cannot be met at t0 before any search (`Err` names the constraint).
pub fn check(scene: &Scene, world: &World, o: &ReasonOptions) -> Result<(), String> {
    let what = match (o.behavior, o.zone) {
        (Some(b), Some(z)) => format!("perform {} into zone {}", b.as_str(), z.as_str()),
        (Some(b), None) => format!("perform {}", b.as_str()),
        (None, Some(z)) => format!("reach zone {}", z.as_str()),
        (None, None) => "be the adversary".into(),
    };
    // Every message names the constraint; with --adversary it names the track first.
    let cannot = |why: String| {
        Err(match o.adversary.as_deref() {
            Some(id) => format!("track {id} cannot {what}: {why}"),
            None => why,
        })
    };
    if let Some(t) = o.ttc_s {
        let h = world.horizon();
        if snap_ttc(t, o.dt, h).is_none() || t > h + o.dt / 2.0 {
            return cannot(format!(
                "--ttc {t} s is past the end of the log ({h:.2} s after t0 = {:.2} s), where the ego's motion is unknown",
                o.t0
            ));
        }
    }
    if let (Some(b), Some(z)) = (o.behavior, o.zone) {
        if !spec(b).zones.contains(&z) {
            let zs: Vec<&str> = spec(b).zones.iter().map(|z| z.as_str()).collect();
            return cannot(format!(
                "{} never aims at zone {} (it aims at {})",
                b.as_str(),
                z.as_str(),
                zs.join(" or ")
            ));
        }
    }
    let Some(id) = o.adversary.as_deref() else { return Ok(()) };
    let Some(track) = scene.tracks.iter().find(|t| t.id == id) else {
        return cannot("there is no such track in the scene".into());
    };
    if scene.ego.track_id.as_deref() == Some(id) {
        return cannot("it is the ego".into());
    }
    // The class first: a pedestrian asked to brake is refused for being a pedestrian.
    let class_behaviours: Vec<Behavior> = Behavior::EVERY.into_iter().filter(|b| class_can(track.class, *b)).collect();
    if let Some(why) = o.behavior.and_then(|b| class_refusal(track.class, b)) {
        return cannot(format!("it is {why}"));
    }
    if class_behaviours.is_empty() {
        return cannot(format!("it is a {0}, and a {0} cannot be an adversary", track.class.as_str()));
    }
    let Some(v) = world.vehicle(id) else {
        let full = World::new(scene, o.t0, f64::INFINITY);
        return cannot(match full.as_ref().and_then(|w| w.vehicle(id)) {
            Some(v) => format!(
                "it is {:.0} m from the ego at t0 = {:.2} s, beyond the {:.0} m radius",
                v.now.p.distance(world.ego_now.p),
                o.t0,
                o.radius
            ),
            None => format!("it is not logged at t0 = {:.2} s", o.t0),
        });
    };
    let behaviours: Vec<Behavior> = o.behavior.map_or(class_behaviours, |b| vec![b]);
    let mut why = Vec::new();
    for b in behaviours {
        match candidate_zones(world, v, b) {
            Err(e) if o.behavior.is_some() => why.push(format!("it is {e}")),
            Err(e) => why.push(format!("{}: it is {e}", b.as_str())),
            Ok(zs) if o.zone.is_some_and(|z| !zs.contains(&z)) => {
                let names: Vec<&str> = zs.iter().map(|z| z.as_str()).collect();
                why.push(format!(
                    "performing {} from where it is, it can only aim at zone {}",
                    b.as_str(),
                    names.join(" or ")
                ));
            }
            Ok(_) => return Ok(()),
        }
    }
    cannot(why.join("; "))
}

/// Every feasible candidate for `b` under the constraints, best first (the planner's
/// [`crate::planner::search`] when there are none). `Err` names what failed.
pub fn search(world: &World, b: Behavior, o: &ReasonOptions) -> Result<Vec<Candidate>, String> {
    search_with(world, b, o, Breadth::DEFAULT)
}

/// [`search`] sampled as `breadth` says (the rollout check's wider pass).
pub fn search_with(world: &World, b: Behavior, o: &ReasonOptions, breadth: Breadth) -> Result<Vec<Candidate>, String> {
    if o.zone.is_none() && o.ttc_s.is_none() {
        return crate::planner::search_with(world, b, o.layout, o.dt, o.seed, breadth);
    }
    let grid = match o.ttc_s {
        Some(t) => snap_ttc(t, o.dt, world.horizon()).into_iter().collect(),
        None => ttc_grid_step(world, b, o.dt, breadth.ttc_step_s),
    };
    if grid.is_empty() {
        return Err(format!("the log ends {:.1} s after t0, before any TTC {} allows", world.horizon(), b.as_str()));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed);
    let mut out = Vec::new();
    let mut eligible = 0;
    for v in world.actors() {
        let Ok(zones) = candidate_zones(world, v, b) else { continue };
        for zone in zones.into_iter().filter(|z| o.zone.is_none_or(|q| q == *z)) {
            eligible += 1;
            out.extend(search_vehicle_zone_with(world, v, b, zone, o.layout, &grid, o.dt, &mut rng, breadth));
        }
    }
    if out.is_empty() {
        let zone = o.zone.map_or(String::new(), |z| format!(" into zone {}", z.as_str()));
        let ttc = o.ttc_s.map_or(String::new(), |t| format!(" with TTC {t} s"));
        return Err(if eligible == 0 {
            format!("no {} within range is positioned for {}{zone}", who_performs(b), b.as_str())
        } else {
            format!(
                "{eligible} {}/zone pair(s) fit {}{zone}, but no trajectory{ttc} stays within the speed, acceleration, jerk, yaw-rate and curvature limits",
                who_performs(b),
                b.as_str()
            )
        });
    }
    out.sort_by(|a, b| a.score.total_cmp(&b.score));
    Ok(out)
}
