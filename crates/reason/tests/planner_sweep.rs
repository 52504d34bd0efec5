//! Acceptance sweep for the planner: both shared WOMD scenes, every behaviour, t0 = 1..6 s. Every
//! run gives a plan that passes validation or a "no feasible vehicle" result with a reason, and
//! every plan is a path a car can drive: its geometric curvature stays within the planner's bound
//! at any speed, and an adversary at rest leaves along its body (parked WOMD cars 654 and 1588
//! used to be sent off sideways).

use reason::planner::PLAN_MAX_CURVATURE;
use reason::quintic::path_curvature;
use reason::world::World;
use reason::{reason, Agent, Outcome, ReasonOptions};
use scene::Behavior;

#[test]
fn planner_always_plans_or_says_why_not() {
    let Some(scenes) = ingest::shared::womd_scenes() else { return };
    let (mut plans, mut none) = (0, 0);
    for scene in &scenes {
        for b in Behavior::ALL {
            let mut row = String::new();
            for t in 1..=6 {
                let o = ReasonOptions {
                    t0: scene.frames[0].timestamp_s + t as f64,
                    behavior: Some(b),
                    seed: 7,
                    ..Default::default()
                };
                match reason(scene, &o, Agent::Planner).unwrap() {
                    Outcome::Plan { plan, .. } => {
                        plan.validate().unwrap();
                        assert_eq!(plan.behavior, b);
                        assert_eq!(plan.waypoints.last().map(|w| w.t), Some(plan.start_time_s + plan.ttc_s));
                        let with = scene::plan::with_inserted(scene, &plan).unwrap();
                        let world = World::new(&with, o.t0, o.radius).unwrap();
                        let adversary = world.vehicle(&plan.adversary_track).unwrap();
                        let at_rest = (adversary.now.speed() < 1.0).then_some(adversary.now.heading);
                        let k = path_curvature(&plan.waypoints, at_rest);
                        assert!(
                            k <= PLAN_MAX_CURVATURE + 1e-9,
                            "{} {} t0 {t}: curvature {k:.2} 1/m (at rest: {})",
                            plan.adversary_track,
                            b.as_str(),
                            at_rest.is_some()
                        );
                        plans += 1;
                        row.push_str(&format!(" {}:{:.1}s", plan.adversary_track, plan.ttc_s));
                    }
                    Outcome::NoFeasible { reason } => {
                        assert!(!reason.is_empty());
                        none += 1;
                        row.push_str(" -");
                    }
                    Outcome::Rejected { reason, .. } => panic!("the planner's plans are never rejected: {reason}"),
                }
            }
            println!("{} {:<22}{row}", &scene.name[..4], b.as_str());
        }
    }
    println!("planner: {plans} plans, {none} no-feasible results of {}", plans + none);
    assert_eq!(plans + none, 96);
    assert!(plans > 0);
}
