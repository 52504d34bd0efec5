//! `eval-cases --describe`: a sentence read per scene (scripted LLM) replaces the behaviour list
//! and the adversary of that scene's attempts, and a pedestrian it names is planned and executed
//! as a pedestrian. Scene: the shared stationary-ego WOMD scenario, where pedestrian 2313 crosses
//! 8 m ahead of the ego at t0 = 1 s.

use cases::describe::read_scenes;
use cases::runner::{CaseConfig, Status};
use cases::spec::{AgentName, T0Spec};
use cases::window::Window;
use cases::{run_eval, EvalConfig};
use indicatif::ProgressBar;
use reason::backend::scripted::Scripted;
use reason::backend::Capability;
use reason::ReasonOptions;
use scene::Behavior;

#[test]
fn a_described_pedestrian_steps_out_in_that_scene_only() {
    let Some(scenes) = ingest::shared::womd_scenes() else { return };
    let scenes: Vec<_> = scenes.into_iter().filter(|s| s.name == "637f20cafde22ff8").collect();
    let t0 = T0Spec::List(vec![1.0]);
    let reply = r#"{"behavior":"step_out","vehicle_id":"2313","zone":"front","ttc_s":0,"explanation":"the pedestrian ahead steps out"}"#;
    let mut b = Scripted::new([reply], Capability::LabelsOnly);
    let sentence = "the pedestrian just ahead walks out in front of me";
    let read = read_scenes(&scenes, &t0, &ReasonOptions::default(), sentence, &mut b).unwrap();
    let r = &read["637f20cafde22ff8"];
    assert_eq!((r.request.behavior, r.request.adversary.as_deref()), (Behavior::StepOut, Some("2313")));
    assert!(r.summary.contains("pedestrian"), "{}", r.summary);
    assert!(b.requests[0].messages[1].content.contains(sentence));

    let tmp = tempfile::tempdir().unwrap();
    let cfg = EvalConfig {
        agents: vec![AgentName::Planner],
        // What `eval-cases --describe` passes: the behaviours the readings named.
        behaviors: vec![Behavior::SuddenBraking, Behavior::StepOut],
        t0,
        seed: 1,
        out: tmp.path().to_path_buf(),
        plots: false,
        case: CaseConfig {
            reason: ReasonOptions::default(),
            rollout: sim::RolloutConfig::default(),
            refine_rounds: 0,
            simulate: Box::new(sim::simulate),
            window: Window::default(),
            requests: read.into_iter().map(|(k, v)| (k, v.request)).collect(),
            check_rollouts: true,
            streets: Default::default(),
        },
        shard: None,
        cli_settings: Default::default(),
    };
    let no_backend = |_: AgentName| -> Result<Box<dyn reason::backend::Backend>, String> { Err("none".into()) };
    let report = run_eval(&scenes, &cfg, &no_backend, &ProgressBar::hidden()).unwrap();
    assert_eq!(report.attempts, 1, "only the described behaviour is attempted");
    let c = &report.cases[0];
    assert_eq!(c.spec.behavior, Behavior::StepOut);
    let Status::Done { rounds, best } = &c.status else { panic!("expected a plan: {:?}", c.status) };
    let round = &rounds[*best];
    assert_eq!(round.plan.adversary_track, "2313");
    assert_eq!(round.plan.behavior, Behavior::StepOut);
}
