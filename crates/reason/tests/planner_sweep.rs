//! Acceptance sweep for the planner: both shared WOMD scenes, every behaviour, t0 = 1..6 s. Every
//! run gives a plan that passes validation or a "no feasible vehicle" result with a reason.

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
                        plans += 1;
                        row.push_str(&format!(" {}:{:.1}s", plan.adversary_track, plan.ttc_s));
                    }
                    Outcome::NoFeasible { reason } => {
                        assert!(!reason.is_empty());
                        none += 1;
                        row.push_str(" -");
                    }
                }
            }
            println!("{} {:<22}{row}", &scene.name[..4], b.as_str());
        }
    }
    println!("planner: {plans} plans, {none} no-feasible results of {}", plans + none);
    assert_eq!(plans + none, 96);
    assert!(plans > 0);
}
