//! Shards of the attempt list on the shared WOMD scenes: the N shards are a partition of the
//! attempts (union = all, no overlap) whatever the order the scenes are given in; the merge of
//! four shard runs writes the same table files, byte for byte, as one run over all attempts;
//! and the merge refuses a missing shard, a duplicated shard and shards of mixed settings.

use cases::merge::{merge, MergeError};
use cases::runner::CaseConfig;
use cases::shard::{assign, Shard};
use cases::spec::{attempts, AgentName, T0Spec};
use cases::{run_eval, EvalConfig};
use indicatif::ProgressBar;
use reason::ReasonOptions;
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

fn config(out: &Path, seed: u64, shard: Option<Shard>) -> EvalConfig {
    EvalConfig {
        agents: vec![AgentName::Planner, AgentName::Random],
        behaviors: scene::Behavior::ALL.to_vec(),
        t0: T0Spec::List(vec![2.0, 4.5]),
        seed,
        out: out.to_path_buf(),
        plots: false,
        case: CaseConfig {
            reason: ReasonOptions::default(),
            rollout: sim::RolloutConfig::default(),
            refine_rounds: 1,
            simulate: Box::new(sim::simulate),
            window: cases::window::Window::default(),
            requests: Default::default(),
            check_rollouts: true,
            streets: Default::default(),
        },
        shard,
        cli_settings: Default::default(),
    }
}

fn no_backend(_: AgentName) -> Result<Box<dyn reason::backend::Backend>, String> {
    Err("no LLM in this test".into())
}

fn eval(scenes: &[scene::Scene], out: &Path, seed: u64, shard: Option<Shard>) -> cases::Report {
    run_eval(scenes, &config(out, seed, shard), &no_backend, &ProgressBar::hidden()).unwrap()
}

const TABLES: [&str; 6] =
    ["table1.md", "table1.csv", "table1_paired.md", "table1_paired.csv", "why_no_plan.md", "table2.md"];

#[test]
fn shards_partition_the_attempts_in_any_scene_order() {
    let Some(scenes) = ingest::shared::womd_scenes() else {
        println!("SKIP: ../shared/data/waymo is absent");
        return;
    };
    let mut reversed = scenes.clone();
    reversed.reverse();
    let t0 = T0Spec::Every(0.5);
    let all = attempts(&scenes, &scene::Behavior::ALL, &t0, 3);
    let all_rev = attempts(&reversed, &scene::Behavior::ALL, &t0, 3);
    assert!(all.len() > 100);
    // The list itself (ids and seeds) does not depend on the scene order.
    let ids = |v: &[cases::spec::Attempt]| v.iter().map(|a| (a.id(), a.seed)).collect::<Vec<_>>();
    assert_eq!(ids(&all), ids(&all_rev));
    for n in 1..=7 {
        let s = assign(&all, n);
        let s_rev = assign(&all_rev, n);
        let mut union = BTreeSet::new();
        for i in 0..n {
            let mine: BTreeSet<String> = all.iter().zip(&s).filter(|(_, k)| **k == i).map(|(a, _)| a.id()).collect();
            let mine_rev: BTreeSet<String> =
                all_rev.iter().zip(&s_rev).filter(|(_, k)| **k == i).map(|(a, _)| a.id()).collect();
            assert_eq!(mine, mine_rev, "shard {i}/{n} depends on the scene order");
            assert!(mine.len() >= all.len() / n && mine.len() <= all.len() / n + 1, "shard {i}/{n}: {}", mine.len());
            for id in mine {
                assert!(union.insert(id.clone()), "{id} in two shards of {n}");
            }
        }
        assert_eq!(union.len(), all.len(), "the {n} shards miss attempts");
    }
}

fn read(dir: &Path, f: &str) -> String {
    std::fs::read_to_string(dir.join(f)).unwrap_or_else(|e| panic!("{}/{f}: {e}", dir.display()))
}

#[test]
fn four_shards_merge_into_the_tables_of_one_run() {
    let Some(scenes) = ingest::shared::womd_scenes() else {
        println!("SKIP: ../shared/data/waymo is absent");
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let one = tmp.path().join("one");
    let whole = eval(&scenes, &one, 5, None);
    // The shards get the scenes in the other order, two of them share an output directory.
    let mut reversed = scenes.clone();
    reversed.reverse();
    let dirs: Vec<PathBuf> = ["s0", "s1", "s23", "s23"].iter().map(|d| tmp.path().join(d)).collect();
    let mut planned = 0;
    for (i, d) in dirs.iter().enumerate() {
        let r = eval(&reversed, d, 5, Some(Shard { index: i, count: 4 }));
        assert!(d.join(format!("shard-{i}-of-4.json")).is_file());
        assert!(!d.join("table1.md").exists(), "a shard writes no partial tables");
        planned += r.cases.iter().filter(|c| c.first().is_some()).count();
    }
    assert_eq!(planned, whole.cases.iter().filter(|c| c.first().is_some()).count());
    let merged = merge(&dirs[..3]).unwrap();
    let out = tmp.path().join("merged");
    cases::report::write(&out, &merged, false).unwrap();
    for f in TABLES.iter().chain(&["table2.csv"]) {
        assert_eq!(read(&one, f), read(&out, f), "{f} differs");
    }
    assert_eq!(serde_json::to_value(&merged.cases).unwrap(), serde_json::to_value(&whole.cases).unwrap());
    assert_eq!(merged.attempts, whole.attempts);
    assert_eq!(merged.scenes, whole.scenes);
    let cases_timed: usize = merged.timing.iter().map(|t| t.cases).sum();
    assert_eq!(cases_timed, whole.cases.len());
    // A directory of shard directories is found too.
    let found = merge(&[tmp.path().to_path_buf()]).unwrap();
    assert_eq!(serde_json::to_value(&found.cases).unwrap(), serde_json::to_value(&whole.cases).unwrap());

    // Refusals: a missing shard, a duplicated one, mixed settings, a missing case file.
    match merge(&dirs[..2]) {
        Err(e @ MergeError::Missing { .. }) => {
            assert!(e.to_string().contains("2/4") && e.to_string().contains("3/4"), "{e}")
        }
        other => panic!("missing shards: {other:?}"),
    }
    let dup = tmp.path().join("dup");
    std::fs::create_dir_all(&dup).unwrap();
    std::fs::copy(dirs[0].join("shard-0-of-4.json"), dup.join("shard-0-of-4.json")).unwrap();
    match merge(&[dirs[0].clone(), dirs[1].clone(), dirs[2].clone(), dup.clone()]) {
        Err(e @ MergeError::Duplicate { .. }) => assert!(e.to_string().contains("0/4"), "{e}"),
        other => panic!("duplicated shard: {other:?}"),
    }
    let other_seed = tmp.path().join("seed6");
    eval(&scenes, &other_seed, 6, Some(Shard { index: 1, count: 4 }));
    match merge(&[dirs[0].clone(), other_seed, dirs[2].clone()]) {
        Err(e @ MergeError::Mixed { .. }) => assert!(e.to_string().contains("seed (5 vs 6)"), "{e}"),
        other => panic!("mixed settings: {other:?}"),
    }
    let first = merged.cases.iter().find(|c| c.spec.scene == merged.scenes[0]).unwrap().spec.id();
    let holder = dirs.iter().find(|d| d.join("cases").join(&first).is_dir()).unwrap();
    std::fs::remove_dir_all(holder.join("cases").join(&first)).unwrap();
    match merge(&dirs[..3]) {
        Err(e @ MergeError::CaseMissing { .. }) => assert!(e.to_string().contains(&first), "{e}"),
        other => panic!("missing case: {other:?}"),
    }
}
