//! The ego standing still: on the shared WOMD scenes (one waits in a queue at a light), a
//! behaviour that ends slower ahead of the ego (sudden braking, sudden cut-in, lead swerve) is
//! refused with "the ego stands still" exactly where a road user is positioned for it and the
//! ego is below 1 m/s at every TTC of the behaviour's grid; where the ego moves at some TTC, the
//! reason never says so, and a plan's TTC is always one at which the ego moves.

use reason::planner::{ttc_grid, MIN_EGO_SPEED_AHEAD};
use reason::world::World;
use reason::{reason, Agent, Outcome, ReasonOptions};
use scene::Behavior;

#[test]
fn slower_ahead_behaviours_are_refused_only_where_the_ego_stands_still() {
    let Some(scenes) = ingest::shared::womd_scenes() else { return };
    let mut still_refusals = 0;
    for scene in &scenes {
        for b in [Behavior::SuddenBraking, Behavior::SuddenCutIn, Behavior::LeadSwerve] {
            for t in 1..=6 {
                let o = ReasonOptions {
                    t0: scene.frames[0].timestamp_s + t as f64,
                    behavior: Some(b),
                    seed: 3,
                    ..Default::default()
                };
                let world = World::new(scene, o.t0, o.radius).unwrap();
                let speed_at = |ttc: f64| world.ego_kin(o.t0 + ttc).speed();
                let grid = ttc_grid(&world, b, o.dt);
                let still = !grid.is_empty() && grid.iter().all(|&ttc| speed_at(ttc) < MIN_EGO_SPEED_AHEAD);
                match reason(scene, &o, Agent::Planner).unwrap() {
                    Outcome::Plan { plan, .. } => {
                        assert!(!still, "{} {} t0 {t}: planned while the ego stands still", scene.name, b.as_str());
                        assert!(speed_at(plan.ttc_s) >= MIN_EGO_SPEED_AHEAD, "{} t0 {t}", b.as_str());
                    }
                    Outcome::NoFeasible { reason } => {
                        let says = reason.contains("the ego stands still");
                        assert!(!says || still, "{} t0 {t}: {reason}", b.as_str());
                        if still && reason.contains("positioned for") && !reason.starts_with("no ") {
                            assert!(says, "{} t0 {t}: {reason}", b.as_str());
                        }
                        still_refusals += usize::from(says);
                    }
                    Outcome::Rejected { reason, .. } => panic!("{reason}"),
                }
            }
        }
    }
    // The queue at the light: at least one cut-in with a car beside the waiting ego.
    assert!(still_refusals >= 1, "no attempt refused for a standing ego");
}
