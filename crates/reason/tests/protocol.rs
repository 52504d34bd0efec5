//! The user's constraints (`--adversary`, `--zone`, `--ttc`), TTCs off the dt grid, and the
//! paper protocol (the Trajectory agent writes its own ego-frame waypoints; repair only when
//! asked). Scene: the shared stationary-ego WOMD scenario at t0 = 2 s, where vehicle 1588
//! (behind-left of the ego) can side-pass into the left zone.

use reason::backend::{Backend, BackendError, Capability, ChatRequest};
use reason::{reason, Agent, Outcome, Protocol, ReasonOptions, Repair, Validity};
use scene::{Behavior, Scene, Zone};

fn scene() -> Option<Scene> {
    Some(ingest::shared::womd_scenes()?.into_iter().find(|s| s.name == "637f20cafde22ff8").unwrap())
}

fn options(s: &Scene) -> ReasonOptions {
    ReasonOptions {
        t0: s.frames[0].timestamp_s + 2.0,
        behavior: Some(Behavior::SidePass),
        seed: 5,
        ..Default::default()
    }
}

fn no_plan(s: &Scene, o: &ReasonOptions) -> String {
    match reason(s, o, Agent::Planner).unwrap() {
        Outcome::NoFeasible { reason } => reason,
        other => panic!("expected no plan, got {other:?}"),
    }
}

#[test]
fn impossible_constraints_name_the_constraint() {
    let Some(s) = scene() else { return };
    let base = ReasonOptions { adversary: Some("1588".into()), ..options(&s) };
    let why =
        no_plan(&s, &ReasonOptions { behavior: Some(Behavior::SuddenCutIn), zone: Some(Zone::Left), ..base.clone() });
    assert!(why.starts_with("track 1588 cannot perform sudden_cut_in into zone left: "), "{why}");
    assert!(why.contains("never aims at zone left (it aims at front)"), "{why}");
    let why = no_plan(&s, &ReasonOptions { behavior: Some(Behavior::SuddenBraking), ..base.clone() });
    assert!(
        why.starts_with("track 1588 cannot perform sudden_braking: it is not ahead of the ego in its lane"),
        "{why}"
    );
    let why = no_plan(&s, &ReasonOptions { zone: Some(Zone::Right), ..base.clone() });
    assert!(
        why.contains("track 1588 cannot perform side_pass into zone right") && why.contains("only aim at zone left"),
        "{why}"
    );
    let why = no_plan(&s, &ReasonOptions { adversary: Some("nope".into()), ..base.clone() });
    assert!(why.contains("track nope cannot perform side_pass: there is no such track"), "{why}");
    let why = no_plan(&s, &ReasonOptions { ttc_s: Some(60.0), ..base.clone() });
    assert!(why.contains("--ttc 60 s is past the end of the log"), "{why}");
    let why = no_plan(&s, &ReasonOptions { radius: 5.0, ..base.clone() });
    assert!(why.contains("beyond the 5 m radius"), "{why}");
    if let Some(p) = s.tracks.iter().find(|t| t.class == scene::ObjectClass::Pedestrian) {
        let why = no_plan(&s, &ReasonOptions { adversary: Some(p.id.clone()), ..base });
        assert!(why.contains("it is a pedestrian, and pedestrians can perform step_out only"), "{why}");
    }
}

#[test]
fn constraints_are_honoured_and_an_off_grid_ttc_goes_on_the_grid() {
    let Some(s) = scene() else { return };
    let o = ReasonOptions { adversary: Some("1588".into()), zone: Some(Zone::Left), ttc_s: Some(3.04), ..options(&s) };
    let Outcome::Plan { plan, .. } = reason(&s, &o, Agent::Planner).unwrap() else { panic!("expected a plan") };
    assert_eq!((plan.adversary_track.as_str(), plan.target_zone), ("1588", Zone::Left));
    assert!((plan.ttc_s - 3.0).abs() < 1e-9, "TTC {} is not on the 0.1 s grid", plan.ttc_s);
    assert!((plan.waypoints.last().unwrap().t - (o.t0 + 3.0)).abs() < 1e-9);
    plan.validate().unwrap();
}

/// Numbers after `label`: "label (x, y)" -> (x, y).
fn pair_after(text: &str, label: &str) -> (f64, f64) {
    let rest = &text[text.find(label).unwrap_or_else(|| panic!("no `{label}` in {text}")) + label.len()..];
    let inner = &rest[rest.find('(').unwrap() + 1..rest.find(')').unwrap()];
    let mut it = inner.split(',').map(|s| s.trim().parse::<f64>().unwrap());
    (it.next().unwrap(), it.next().unwrap())
}

fn number_after(text: &str, label: &str) -> f64 {
    let rest = &text[text.find(label).unwrap() + label.len()..];
    rest.split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
        .find(|s| !s.is_empty())
        .unwrap()
        .parse()
        .unwrap()
}

/// A model that answers the Zone agent with `zone` and the Trajectory agent with a constant-speed
/// line from the vehicle to the target stated in the prompt (either protocol's frame), or with
/// `bad` when set. Records every request.
struct LineModel {
    zone: String,
    bad: Option<String>,
    requests: Vec<ChatRequest>,
}

impl Backend for LineModel {
    fn name(&self) -> String {
        "line".into()
    }
    fn capability(&self) -> Capability {
        Capability::Numbers
    }
    fn complete(&mut self, r: &ChatRequest) -> Result<String, BackendError> {
        self.requests.push(r.clone());
        if r.schema_name == "zone" {
            return Ok(self.zone.clone());
        }
        if let Some(b) = &self.bad {
            return Ok(b.clone());
        }
        let user = &r.messages[1].content;
        let paper = user.contains("Vehicle start (x0, y0)");
        let (p0, pt, t_start) = if paper {
            (pair_after(user, "(x0, y0) ="), pair_after(user, "Collision target (x, y) ="), 0.0)
        } else {
            (
                pair_after(user, "position"),
                pair_after(user, "Collision target (world):"),
                number_after(user, "waypoints from t ="),
            )
        };
        let n = number_after(user, "write exactly") as usize;
        let w: Vec<String> = (0..n)
            .map(|k| {
                let s = k as f64 / (n - 1) as f64;
                let (x, y) = (p0.0 + (pt.0 - p0.0) * s, p0.1 + (pt.1 - p0.1) * s);
                format!(r#"{{"t":{:.4},"x":{x:.4},"y":{y:.4}}}"#, t_start + 0.1 * k as f64)
            })
            .collect();
        Ok(format!(r#"{{"waypoints":[{}]}}"#, w.join(",")))
    }
}

fn zone_reply(ttc: &str) -> String {
    format!(
        r#"{{"analysis":"a","vehicle_id":"1588","zone":"left","behavior":"side_pass","ttc_s":{ttc},"risk":"high","reasoning":"r"}}"#
    )
}

fn run(s: &Scene, o: &ReasonOptions, m: &mut LineModel) -> Outcome {
    reason(s, o, Agent::Llm(m)).unwrap()
}

#[test]
fn an_llm_ttc_off_the_dt_grid_can_pass_the_trajectory_check() {
    let Some(s) = scene() else { return };
    let mut m = LineModel { zone: zone_reply("3.97"), bad: None, requests: vec![] };
    let Outcome::Plan { plan, stats } = run(&s, &options(&s), &mut m) else { panic!("expected a plan") };
    let stats = stats.unwrap();
    assert_eq!(stats.trajectory, Validity::RawValid, "{:?}", stats.trajectory);
    assert!((plan.ttc_s - 4.0).abs() < 1e-9, "{}", plan.ttc_s);
    assert!(m.requests[1].messages[1].content.contains("write exactly 41 waypoints"));
}

#[test]
fn paper_protocol_uses_the_models_own_ego_frame_waypoints() {
    let Some(s) = scene() else { return };
    let o = ReasonOptions { protocol: Protocol::Paper, repair: Repair::None, ..options(&s) };
    let mut m = LineModel { zone: zone_reply("3.0"), bad: None, requests: vec![] };
    let Outcome::Plan { plan, stats } = run(&s, &o, &mut m) else { panic!("expected a plan") };
    let stats = stats.unwrap();
    assert_eq!((stats.zone.clone(), stats.trajectory.clone()), (Validity::RawValid, Validity::RawValid));
    let traj = &m.requests[1];
    assert!(traj.messages[0].content.contains("EGO frame at t0"));
    assert!(traj.messages[1].content.contains("Ego logged future:"));
    // The plan is the model's line, converted to the world frame on the scene clock.
    let w = &plan.waypoints;
    assert_eq!(w.len(), 31);
    assert!((w[0].t - o.t0).abs() < 1e-9 && (w[30].t - (o.t0 + 3.0)).abs() < 1e-6);
    let world = reason::world::World::new(&s, o.t0, 60.0).unwrap();
    let start = world.vehicle("1588").unwrap().now.p;
    assert!(scene::glam::DVec2::new(w[0].x, w[0].y).distance(start) < 0.02);
    let mid = scene::glam::DVec2::new(w[15].x, w[15].y);
    let ends = (scene::glam::DVec2::new(w[0].x, w[0].y) + scene::glam::DVec2::new(w[30].x, w[30].y)) / 2.0;
    assert!(mid.distance(ends) < 0.02, "a straight line stays straight in the world frame");
}

#[test]
fn paper_protocol_rejects_or_repairs_as_asked() {
    let Some(s) = scene() else { return };
    let bad = r#"{"waypoints":[{"t":0,"x":50,"y":50},{"t":0.1,"x":51,"y":50}]}"#.to_string();
    let o = ReasonOptions { protocol: Protocol::Paper, repair: Repair::None, ..options(&s) };
    let mut m = LineModel { zone: zone_reply("3.0"), bad: Some(bad.clone()), requests: vec![] };
    let Outcome::Rejected { stats, reason } = run(&s, &o, &mut m) else { panic!("expected a rejection") };
    assert_eq!(stats.zone, Validity::RawValid);
    let Validity::Invalid { violations } = &stats.trajectory else { panic!("{:?}", stats.trajectory) };
    assert!(violations.iter().any(|v| v.contains("from the collision target")), "{violations:?}");
    assert!(reason.contains("Trajectory agent's reply stayed invalid after 2 re-prompt(s)"), "{reason}");
    assert_eq!(m.requests.len(), 4, "1 zone request + 3 trajectory attempts");
    // The re-prompt quotes the target in the frame the model writes (ego frame: metres from the ego).
    let reprompt = &m.requests[2].messages.last().unwrap().content;
    assert!(reprompt.contains("`waypoints[0]`: starts"), "{reprompt}");

    let o = ReasonOptions { repair: Repair::Planner, ..o };
    let mut m = LineModel { zone: zone_reply("3.0"), bad: Some(bad), requests: vec![] };
    let Outcome::Plan { plan, stats } = run(&s, &o, &mut m) else { panic!("expected a repaired plan") };
    assert!(matches!(stats.unwrap().trajectory, Validity::Repaired { .. }));
    plan.validate().unwrap();
}

#[test]
fn a_description_is_read_checked_and_shown() {
    let Some(s) = scene() else { return };
    let o = ReasonOptions { behavior: None, ..options(&s) };
    let impossible =
        r#"{"behavior":"sudden_braking","vehicle_id":"1588","zone":"front","ttc_s":0,"explanation":"it brakes"}"#;
    let good = r#"{"behavior":"side_pass","vehicle_id":"1588","zone":"left","ttc_s":3,"explanation":"the car behind-left overtakes close"}"#;
    let mut b = reason::backend::scripted::Scripted::new([impossible, good], Capability::LabelsOnly);
    let sentence = "the car behind me on the left overtakes and squeezes in";
    let (intent, summary) = reason::intent::describe(&s, &o, sentence, &mut b).unwrap().unwrap();
    assert_eq!(intent.behavior, Behavior::SidePass);
    assert_eq!((intent.adversary.as_deref(), intent.zone, intent.ttc_s), (Some("1588"), Some(Zone::Left), Some(3.0)));
    assert_eq!(intent.validity, Validity::ValidAfterRetry { retries: 1 });
    assert!(
        summary.starts_with("behaviour side_pass, adversary track 1588 (") && summary.contains("behind"),
        "{summary}"
    );
    let prompt = &b.requests[0].messages[1].content;
    assert!(prompt.contains(sentence) && prompt.contains("- id 1588: "), "{prompt}");
    let reprompt = &b.requests[1].messages.last().unwrap().content;
    assert!(reprompt.contains("track 1588 cannot perform sudden_braking"), "{reprompt}");
    // The reading plans like the flags would.
    let Outcome::Plan { plan, .. } = reason(&s, &intent.apply(&o), Agent::Planner).unwrap() else { panic!() };
    assert_eq!((plan.adversary_track.as_str(), plan.behavior), ("1588", Behavior::SidePass));
}
