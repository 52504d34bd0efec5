//! Malformed agent replies are caught, each with its reason, re-prompted with that reason, and
//! repaired by the planner when retries run out. Scene: the shared stationary-ego WOMD scenario,
//! behaviour side_pass at t0 = 2 s (vehicle 1588, behind-left of the ego, can perform it).

use reason::backend::scripted::Scripted;
use reason::backend::{Capability, Role};
use reason::{reason, Agent, Outcome, ReasonOptions, Validity};
use scene::{Behavior, Scene};

const GOOD_ZONE: &str = r#"{"analysis":"1588 is behind-left","vehicle_id":"1588","zone":"left","behavior":"side_pass","ttc_s":4.0,"risk":"high","reasoning":"passes close"}"#;

fn scene() -> Option<Scene> {
    Some(ingest::shared::womd_scenes()?.into_iter().find(|s| s.name == "637f20cafde22ff8").unwrap())
}

fn options(s: &Scene) -> ReasonOptions {
    ReasonOptions {
        t0: s.frames[0].timestamp_s + 2.0,
        behavior: Some(Behavior::SidePass),
        seed: 5,
        max_retries: 2,
        ..Default::default()
    }
}

/// Runs the chain with scripted replies; returns the validity stats and the backend.
fn run(s: &Scene, replies: Vec<String>) -> (reason::ValidityStats, scene::Plan, Scripted) {
    let mut b = Scripted::new(replies, Capability::Numbers);
    let out = reason(s, &options(s), Agent::Llm(&mut b)).unwrap();
    let Outcome::Plan { plan, stats } = out else { panic!("expected a plan") };
    plan.validate().unwrap();
    (stats.unwrap(), plan, b)
}

/// A trajectory reply of `n` waypoints at times `t(k)` and positions `p(k)`.
fn traj(n: usize, t: impl Fn(usize) -> String, p: impl Fn(usize) -> (f64, f64)) -> String {
    let w: Vec<String> = (0..n).map(|k| format!(r#"{{"t":{},"x":{},"y":{}}}"#, t(k), p(k).0, p(k).1)).collect();
    format!(r#"{{"waypoints":[{}]}}"#, w.join(","))
}

#[test]
fn bad_zone_replies_are_caught_with_their_reason() {
    let Some(s) = scene() else { return };
    let cases = [
        ("broken JSON", r#"{"vehicle_id": "1588", "zone": "left""#.to_string(), "not valid JSON"),
        ("wrong type", GOOD_ZONE.replace("4.0", "\"4.0\""), "`ttc_s`: expected a number"),
        ("missing keys", r#"{"vehicle_id":"1588","zone":"left"}"#.to_string(), "`analysis`: missing"),
        ("hallucinated vehicle", GOOD_ZONE.replace("1588", "99999"), "vehicle `99999` does not exist"),
        ("NaN", GOOD_ZONE.replace("4.0", "NaN"), "not valid JSON"),
        ("zone outside the behaviour", GOOD_ZONE.replace("\"left\"", "\"right\""), "can aim at left only"),
        ("other behaviour", GOOD_ZONE.replace("side_pass", "sudden_cut_in"), "must be `side_pass`"),
        ("TTC past the log", GOOD_ZONE.replace("4.0", "30"), "`ttc_s`: 30 is not in (0,"),
    ];
    for (what, bad, reason_text) in cases {
        // Bad zone reply, then a good one; the trajectory agent then fails three times (repaired).
        let (stats, plan, b) = run(&s, vec![bad, GOOD_ZONE.into(), "{}".into(), "{}".into(), "{}".into()]);
        assert_eq!(stats.zone, Validity::ValidAfterRetry { retries: 1 }, "{what}");
        let reprompt = b.requests[1].messages.last().unwrap();
        assert_eq!(reprompt.role, Role::User);
        assert!(
            reprompt.content.contains(reason_text),
            "{what}: re-prompt lacks `{reason_text}`:\n{}",
            reprompt.content
        );
        assert_eq!(plan.adversary_track, "1588");
        assert!(matches!(stats.trajectory, Validity::Repaired { .. }), "{what}");
    }
}

#[test]
fn fenced_reply_is_accepted_first_time() {
    let Some(s) = scene() else { return };
    let (stats, _, _) = run(&s, vec![format!("```json\n{GOOD_ZONE}\n```"), "{}".into(), "{}".into(), "{}".into()]);
    assert_eq!(stats.zone, Validity::RawValid);
}

#[test]
fn bad_trajectories_are_caught_and_repaired() {
    let Some(s) = scene() else { return };
    let t0 = options(&s).t0;
    let world = reason::world::World::new(&s, t0, 60.0).unwrap();
    let p0 = world.vehicle("1588").unwrap().now.p;
    let time = |k: usize| format!("{}", t0 + 0.1 * k as f64);
    let cases = [
        (
            "non-monotone time",
            traj(41, |k| if k == 3 { time(1) } else { time(k) }, |_| (p0.x, p0.y)),
            "times must increase strictly",
        ),
        ("wrong endpoint", traj(41, time, |_| (p0.x, p0.y)), "from the collision target"),
        ("wrong start", traj(41, time, |_| (p0.x + 5.0, p0.y)), "`waypoints[0]`: starts 5.00 m from vehicle `1588`"),
        ("too few", traj(1, time, |_| (p0.x, p0.y)), "need 41 waypoints"),
        ("NaN", traj(41, time, |_| (p0.x, p0.y)).replacen(&format!("{}", p0.y), "NaN", 1), "not valid JSON"),
        ("wrong dt", traj(41, |k| format!("{}", t0 + 0.2 * k as f64), |_| (p0.x, p0.y)), "expected dt = 0.1 s"),
    ];
    for (what, bad, reason_text) in cases {
        let (stats, plan, b) = run(&s, vec![GOOD_ZONE.into(), bad.clone(), bad.clone(), bad]);
        let Validity::Repaired { violations } = &stats.trajectory else { panic!("{what}: {:?}", stats.trajectory) };
        assert!(violations.iter().any(|v| v.contains(reason_text)), "{what}: {violations:?}");
        assert_eq!(b.requests.len(), 4, "{what}: 1 zone request + 3 trajectory attempts");
        // The planner's repair ends exactly at t0 + TTC (the proposed 4 s where a car parked
        // there can reach the target, else the best candidate's).
        assert!((plan.waypoints.last().unwrap().t - (t0 + plan.ttc_s)).abs() < 1e-9, "{what}");
    }
}

#[test]
fn the_requested_behaviour_conditions_the_prompts() {
    let Some(s) = scene() else { return };
    let (_, _, b) = run(&s, vec![GOOD_ZONE.into(), "{}".into(), "{}".into(), "{}".into()]);
    let zone_prompt = &b.requests[0].messages[1].content;
    assert!(zone_prompt.contains("side_pass: a vehicle in an adjacent lane overtakes the ego"));
    assert!(!zone_prompt.contains("rear_tailgating"), "other behaviours leak into the prompt");
    let traj_prompt = &b.requests[1].messages[1].content;
    assert!(traj_prompt.contains("Behaviour: side_pass"));
    // The schema sent to the server restricts the behaviour too.
    assert_eq!(b.requests[0].schema["properties"]["behavior"]["enum"], serde_json::json!(["side_pass"]));
}
