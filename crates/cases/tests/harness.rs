//! The evaluation harness end to end on the shared WOMD scenes with the code agents (the LLM
//! agent's eval is a benchmark run, see BENCHMARKS.md): files written, deterministic, a case
//! whose simulation fails is listed with its reason without changing any other case, and
//! refinement never reports a worse case than the first attempt.

use cases::runner::{CaseConfig, Status};
use cases::spec::{AgentName, T0Spec};
use cases::{run_eval, EvalConfig, Report};
use indicatif::ProgressBar;
use reason::ReasonOptions;
use std::path::Path;

fn config(out: &Path, simulate: Box<cases::runner::SimulateFn>, plots: bool) -> EvalConfig {
    EvalConfig {
        agents: vec![AgentName::Planner, AgentName::Rule, AgentName::Random],
        behaviors: scene::Behavior::ALL.to_vec(),
        t0: T0Spec::List(vec![2.0, 4.0]),
        seed: 9,
        out: out.to_path_buf(),
        plots,
        case: CaseConfig {
            reason: ReasonOptions::default(),
            rollout: sim::RolloutConfig::default(),
            refine_rounds: 3,
            simulate,
            window: cases::window::Window::default(),
            requests: Default::default(),
            check_rollouts: true,
            streets: Default::default(),
        },
        shard: None,
        cli_settings: Default::default(),
    }
}

fn no_backend(_: AgentName) -> Result<Box<dyn reason::backend::Backend>, String> {
    Err("no LLM in this test".into())
}

fn run(scenes: &[scene::Scene], out: &Path, simulate: Box<cases::runner::SimulateFn>, plots: bool) -> Report {
    run_eval(scenes, &config(out, simulate, plots), &no_backend, &ProgressBar::hidden()).unwrap()
}

fn case_json(r: &Report, id: &str) -> String {
    serde_json::to_string(r.cases.iter().find(|c| c.spec.id() == id).unwrap()).unwrap()
}

#[test]
fn tables_plots_determinism_and_failures() {
    let Some(scenes) = ingest::shared::womd_scenes() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let a = run(&scenes, &tmp.path().join("a"), Box::new(sim::simulate), true);
    assert_eq!(a.cases.len(), 2 * 8 * 2 * 3);
    for f in ["summary.md", "table1.md", "table1.csv", "table2.md", "table2.csv", "report.json", "table1.png"] {
        assert!(tmp.path().join("a").join(f).is_file(), "{f} missing");
    }
    assert!(a.plot_errors.is_empty(), "{:?}", a.plot_errors);
    let done: Vec<_> = a.cases.iter().filter(|c| matches!(c.status, Status::Done { .. })).collect();
    assert!(!done.is_empty());
    for c in &done {
        let d = tmp.path().join("a/cases").join(c.spec.id());
        for f in ["case.json", "scenario.json", "executed.json", "bev.png", "tracking.png"] {
            assert!(d.join(f).is_file(), "{}/{f} missing", c.spec.id());
        }
    }
    // Table I has a refinement row for the planner only, and (insertion by default) the planner's
    // rows split by logged and inserted adversaries; every row counts over all 32 attempts, and
    // the split rows' planned attempts add up to the whole row's.
    let rows: Vec<(&str, &str)> = a.table1.iter().map(|r| (r.agent.as_str(), r.variant.as_str())).collect();
    let whole = [("planner", "as planned"), ("planner", "+ refine"), ("rule", "as planned"), ("random", "as planned")];
    let split = [
        ("planner", "as planned, logged adversaries"),
        ("planner", "+ refine, logged adversaries"),
        ("planner", "as planned, inserted adversaries"),
        ("planner", "+ refine, inserted adversaries"),
    ];
    assert_eq!(rows.iter().filter(|r| !split.contains(r)).copied().collect::<Vec<_>>(), whole);
    let row = |v: &str| a.table1.iter().find(|r| r.agent == AgentName::Planner && r.variant == v).unwrap();
    if rows.contains(&split[0]) {
        for (w, l, i) in [("as planned", 0, 2), ("+ refine", 1, 3)] {
            assert_eq!(row(split[l].1).planned + row(split[i].1).planned, row(w).planned, "{w}");
        }
        let ins = row(split[3].1);
        println!(
            "planner + refine, inserted: planned {}, verified {}, valid {}",
            ins.planned, ins.verified_k, ins.valid
        );
    }
    assert!(a.table1.iter().all(|r| r.attempts == 32));
    let whole_rows = a.table1.iter().filter(|r| !r.variant.contains("adversaries"));
    assert!(whole_rows.into_iter().all(|r| r.planned + r.no_feasible + r.failed == 32));
    assert!(a.failures.is_empty());
    // Every outcome counted: the invalid counts are the cases' own validity records, and an
    // invalid rollout is never a success.
    for row in a.table1.iter().filter(|r| r.variant == "as planned") {
        let firsts: Vec<_> = a.cases.iter().filter(|c| c.spec.agent == row.agent).filter_map(|c| c.first()).collect();
        let invalid = firsts.iter().filter(|r| !r.metrics.validity.valid).count();
        assert_eq!(row.validity.invalid, invalid, "{:?}", row.agent);
        let count =
            |key: &str| firsts.iter().filter(|r| r.metrics.validity.reasons.iter().any(|x| x.key() == key)).count();
        let v = &row.validity;
        assert_eq!(
            [v.tracking_diverged, v.friction_limit, v.contact_with_other, v.left_road],
            scene::executed::InvalidReason::KEYS.map(count)
        );
        assert!(firsts.iter().all(|r| r.metrics.validity.valid || !r.metrics.success_center));
    }
    let table1_md = std::fs::read_to_string(tmp.path().join("a/table1.md")).unwrap();
    assert!(table1_md.contains("| invalid | diverged | friction limit | contact with other | left road |"));

    // Deterministic: a second run gives the same cases and tables.
    let b = run(&scenes, &tmp.path().join("b"), Box::new(sim::simulate), false);
    assert_eq!(serde_json::to_string(&a.cases).unwrap(), serde_json::to_string(&b.cases).unwrap());
    assert_eq!(serde_json::to_string(&a.table1).unwrap(), serde_json::to_string(&b.table1).unwrap());

    // One case's simulation fails: it is listed with its reason, nothing else changes.
    let victim = done.iter().find(|c| c.spec.agent == AgentName::Planner).unwrap().spec.clone();
    let (vs, vt) = (victim.scene.clone(), victim.t0_s);
    let vb = victim.behavior;
    let failing = move |scene: &scene::Scene, plan: &scene::Plan, cfg: &sim::RolloutConfig| {
        let t0 = plan.start_time_s - scene.frames[0].timestamp_s;
        if scene.name == vs && plan.agent == "planner" && plan.behavior == vb && (t0 - vt).abs() < 1e-9 {
            return Err(sim::SimError::Reference("injected failure".into()));
        }
        sim::simulate(scene, plan, cfg)
    };
    let c = run(&scenes, &tmp.path().join("c"), Box::new(failing), false);
    let failed: Vec<&str> = c.failures.iter().map(|f| f.case.as_str()).collect();
    assert_eq!(failed, [victim.id().as_str()]);
    let f = c.failures.iter().find(|f| f.case == victim.id()).unwrap();
    assert_eq!(f.stage, "simulate");
    assert!(f.reason.contains("injected failure"));
    for case in &a.cases {
        if !failed.contains(&case.spec.id().as_str()) {
            assert_eq!(case_json(&a, &case.spec.id()), case_json(&c, &case.spec.id()), "{} changed", case.spec.id());
        }
    }
    assert_eq!(c.table1[0].failed, 1);
    assert_eq!(c.table1[0].cases + 1, a.table1[0].cases);
    let summary = std::fs::read_to_string(tmp.path().join("c/summary.md")).unwrap();
    assert!(summary.contains(&victim.id()) && summary.contains("injected failure"));

    // Refinement reports the best round: never worse than the first attempt.
    for c in &done {
        let (first, best) = (c.first().unwrap(), c.best().unwrap());
        let key = |m: &metrics::CaseMetrics| (m.zone_hit, m.success_center);
        assert!(key(&best.metrics) >= key(&first.metrics), "{}", c.spec.id());
    }
}
