//! The closed-loop refinement's plans: the planner's next strategy after a miss (the target
//! pre-compensated by the executed end-point error, then the next-ranked candidates) and the
//! feedback sentence an LLM agent is asked again with.

use metrics::CaseMetrics;
use reason::constraints::search;
use reason::planner::trajectory_to_aim;
use reason::world::World;
use reason::ReasonOptions;
use scene::glam::DVec2;
use scene::zones::zone_rect;
use scene::{Executed, Plan, Scene, Zone};

/// The zone (if any) containing a point of the ego frame.
pub fn zone_of(local: DVec2, plan: &Plan, l: f64, w: f64) -> Option<Zone> {
    Zone::ALL.into_iter().find(|z| zone_rect(*z, plan.zone_layout, l, w).contains(local))
}

pub(crate) fn feedback(plan: &Plan, e: &Executed, m: &CaseMetrics) -> String {
    let [l, w, _] = e.ego.size_lwh;
    let local = DVec2::new(m.adversary_in_ego_frame[0], m.adversary_in_ego_frame[1]);
    let reached = zone_of(local, plan, l, w).map_or("no zone".to_string(), |z| format!("the {} zone", z.as_str()));
    format!(
        "vehicle {} aiming at the {} zone with TTC {:.1} s came closest to the ego ({:.1} m) at t0 + {:.1} s, at ({:.1}, {:.1}) m in the ego frame, i.e. in {reached}; the minimum time to collision was {:.2} s.",
        plan.adversary_track,
        plan.target_zone.as_str(),
        plan.ttc_s,
        m.min_distance_m,
        m.t_min_distance_s - plan.start_time_s,
        local.x,
        local.y,
        m.min_ttc_center_s
    )
}

/// Planner refinement strategies: 1 = pre-compensated target, k >= 2 = the k-th ranked candidate.
pub(crate) const MAX_PLANNER_STRATEGY: usize = 8;

/// The planner's refinement strategy `r` (1-based); `None` if it has nothing to offer.
pub(crate) fn refine_planner(
    scene: &Scene,
    o: &ReasonOptions,
    r: usize,
    last: &Plan,
    e: &Executed,
) -> Option<(Plan, String)> {
    // An inserted adversary is a candidate like a logged one in the scene it was inserted into.
    let scene = &*scene::plan::with_inserted(scene, last).ok()?;
    // `--insert always`: the next candidates are the inserted car's own, never a logged car.
    let only_inserted = o.insert == reason::insert::InsertMode::Always && last.inserted.is_some();
    let adversary = if only_inserted { Some(last.adversary_track.clone()) } else { o.adversary.clone() };
    let o = &ReasonOptions { adversary, ..o.clone() };
    let world = World::for_options(scene, &ReasonOptions { t0: last.start_time_s, ..o.clone() })?;
    if r == 1 {
        let target = DVec2::from(last.target?);
        // Where the adversary was when its plan ended (the window may run on after it).
        let t_end = last.end_time_s();
        let end = e.steps.iter().min_by(|a, b| (a.t - t_end).abs().total_cmp(&(b.t - t_end).abs()))?;
        let aim = target + (target - DVec2::new(end.x, end.y));
        let v = world.vehicle(&last.adversary_track)?;
        let planned = trajectory_to_aim(&world, v, last.behavior, aim, last.ttc_s, o.dt, 0.3)?;
        let plan = Plan {
            waypoints: planned.waypoints,
            path: Some(planned.path),
            reasoning: format!("{} (refined: target pre-compensated by the executed end-point error)", last.reasoning),
            ..last.clone()
        };
        return Some((plan, "pre-compensated target".into()));
    }
    let ranked = search(&world, last.behavior, o).ok()?;
    let c = ranked.get(r - 1)?;
    let plan = Plan {
        adversary_track: c.vehicle_id.clone(),
        target_zone: c.zone,
        ttc_s: c.ttc_s,
        risk: c.risk(),
        waypoints: c.waypoints.clone(),
        target: Some([c.target.x, c.target.y]),
        path: Some(c.path),
        reasoning: format!("refined: candidate ranked {r} by the planner"),
        inserted: last.inserted.clone().filter(|_| c.vehicle_id == last.adversary_track),
        ..last.clone()
    };
    Some((plan, format!("candidate ranked {r}")))
}
