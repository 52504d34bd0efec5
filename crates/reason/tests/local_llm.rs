//! The embedded LLM backend on the real WOMD scenes. Needs the default model
//! (`tools/setup-model.sh`); skips with a message without it.
//!
//! * `local_agent_plans_or_says_why_not`: every behaviour on the stationary-ego scene at t0 = 2 s
//!   (runs in CI, about a minute).
//! * `local_agent_full_sweep`: the acceptance sweep, every behaviour and t0 = 1..6 s on both
//!   scenes, with validity counts (about 6 minutes on 2 cores; `cargo test --release -p reason
//!   --test local_llm -- --ignored --nocapture`; the counts are in BENCHMARKS.md).
#![cfg(feature = "local-llm")]

use reason::backend::local::Local;
use reason::{reason, Agent, Outcome, ReasonOptions, Validity};
use scene::Behavior;

fn model() -> Option<Local> {
    let path = reason::backend::default_model_path();
    if !path.is_file() {
        eprintln!("SKIP: local model {} not installed (run tools/setup-model.sh)", path.display());
        return None;
    }
    Some(Local::load(&path, 2).unwrap())
}

#[derive(Default, Debug)]
struct Counts {
    plans: usize,
    no_feasible: usize,
    zone: [usize; 3],
    trajectory: [usize; 3],
}

fn slot(v: &Validity) -> usize {
    match v {
        Validity::RawValid => 0,
        Validity::ValidAfterRetry { .. } => 1,
        Validity::Repaired { .. } | Validity::Invalid { .. } => 2,
    }
}

/// llama.cpp runs on every core: tests take turns.
static LLM: std::sync::Mutex<()> = std::sync::Mutex::new(());

fn sweep(times: &[f64], only: Option<&str>) -> Option<Counts> {
    let _turn = LLM.lock().unwrap_or_else(|e| e.into_inner());
    let mut local = model()?;
    let scenes: Vec<_> =
        ingest::shared::womd_scenes()?.into_iter().filter(|s| only.is_none_or(|n| s.name == n)).collect();
    let mut c = Counts::default();
    for scene in &scenes {
        for b in Behavior::ALL {
            for t in times {
                let o = ReasonOptions {
                    t0: scene.frames[0].timestamp_s + t,
                    behavior: Some(b),
                    seed: 11,
                    ..Default::default()
                };
                match reason(scene, &o, Agent::Llm(&mut local)).unwrap() {
                    Outcome::Plan { plan, stats } => {
                        plan.validate().unwrap();
                        assert_eq!(plan.behavior, b);
                        let s = stats.unwrap();
                        c.zone[slot(&s.zone)] += 1;
                        c.trajectory[slot(&s.trajectory)] += 1;
                        c.plans += 1;
                    }
                    Outcome::NoFeasible { reason } => {
                        assert!(!reason.is_empty());
                        c.no_feasible += 1;
                    }
                    Outcome::Rejected { reason, .. } => panic!("repair is on: {reason}"),
                }
            }
        }
    }
    println!(
        "local: {} plans, {} no-feasible; zone raw-valid {} / valid after retry {} / repaired {}; trajectory {} / {} / {}",
        c.plans, c.no_feasible, c.zone[0], c.zone[1], c.zone[2], c.trajectory[0], c.trajectory[1], c.trajectory[2]
    );
    Some(c)
}

#[test]
fn local_agent_plans_or_says_why_not() {
    let Some(c) = sweep(&[2.0], Some("637f20cafde22ff8")) else { return };
    assert_eq!(c.plans + c.no_feasible, 8);
    assert!(c.plans > 0);
}

#[test]
fn local_agent_is_deterministic_given_the_seed() {
    let _turn = LLM.lock().unwrap_or_else(|e| e.into_inner());
    let Some(mut local) = model() else { return };
    let Some(scenes) = ingest::shared::womd_scenes() else { return };
    let s = scenes.iter().find(|s| s.name == "637f20cafde22ff8").unwrap();
    let o = ReasonOptions {
        t0: s.frames[0].timestamp_s + 2.0,
        behavior: Some(Behavior::SidePass),
        seed: 3,
        ..Default::default()
    };
    let run = |l: &mut Local| match reason(s, &o, Agent::Llm(l)).unwrap() {
        Outcome::Plan { plan, .. } => plan,
        Outcome::NoFeasible { reason } | Outcome::Rejected { reason, .. } => panic!("{reason}"),
    };
    let (a, b) = (run(&mut local), run(&mut local));
    assert_eq!(a, b);
}

#[test]
#[ignore = "acceptance sweep, about 6 minutes; run with --ignored"]
fn local_agent_full_sweep() {
    let Some(c) = sweep(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0], None) else { return };
    assert_eq!(c.plans + c.no_feasible, 96);
}
