//! `carla-gs bench-cases` on a small subset of the real data (the two WOMD scenes and a short
//! KITTI window of each sequence, mirrored and with parked cars, t0 every 3 s): the command succeeds and the
//! counts in `bench.json` are consistent (planned + no plan = attempts for every row, invalid <=
//! rollouts = planned, verified <= planned, the behaviours add up to the total and to the
//! subsets, cut-in adjacency within the cut-in attempts). Skips with a printed reason where
//! `../shared/data` is absent.

mod cli_support;
use serde_json::Value;
use std::path::PathBuf;
use std::process::Command;

fn data() -> Option<PathBuf> {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    let need = ["waymo/motion_data_one_scenario.tfrecord", "waymo/womd_scenario_input.tfrecord", "kitti/poses/00.txt"];
    match need.iter().find(|f| !d.join(f).is_file()) {
        Some(f) => {
            println!("SKIP: {} not found (shared data folder absent)", d.join(f).display());
            None
        }
        None => Some(d),
    }
}

fn n(v: &Value, k: &str) -> u64 {
    v[k].as_u64().unwrap_or_else(|| panic!("{k} missing in {v}"))
}

#[test]
fn bench_counts_are_consistent() {
    let Some(data) = data() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("bench");
    let o = Command::new(env!("CARGO_BIN_EXE_carla-gs"))
        .args(["bench-cases", "--data", data.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .args(["--sources", "womd,kitti", "--kitti-windows", "1", "--kitti-window-s", "9", "--perturbations"])
        .args(["mirror,parked", "--t0", "every:3s", "--refine-rounds", "1", "--seed", "3"])
        .output()
        .expect("run carla-gs");
    assert!(o.status.success(), "bench-cases failed: {}", String::from_utf8_lossy(&o.stderr));
    let r: Value = serde_json::from_slice(&std::fs::read(out.join("bench.json")).unwrap()).unwrap();
    assert!(out.join("bench.md").is_file());
    let scenes = r["scenes"].as_array().unwrap();
    assert_eq!(scenes.len(), 4 * 3, "2 WOMD scenes and a KITTI window per sequence, each with 2 copies: {scenes:?}");
    let attempts = n(&r, "attempts");
    assert!(attempts > 0);
    let rows: Vec<&Value> = r["by_behavior"].as_array().unwrap().iter().collect();
    let subsets: Vec<&Value> = r["by_subset"].as_array().unwrap().iter().collect();
    let sources: Vec<&Value> = r["by_source"].as_array().unwrap().iter().collect();
    for row in rows.iter().chain(&subsets).chain(&sources) {
        let (att, planned) = (n(row, "attempts"), n(row, "planned"));
        assert_eq!(planned + n(row, "no_plan"), att, "{row}");
        assert!(n(row, "failed") <= n(row, "no_plan"));
        assert_eq!(n(row, "rollouts"), planned, "one measured rollout per planned attempt");
        let invalid = &row["invalid"];
        assert!(n(invalid, "invalid") <= planned);
        for reason in ["contact_with_other", "left_road", "friction_limit", "tracking_diverged"] {
            assert!(n(invalid, reason) <= n(invalid, "invalid") * 4);
        }
        assert!(n(row, "verified") <= planned);
        assert!(n(row, "pairs_verified") <= n(row, "pairs"));
        let why: u64 = row["why_no_plan"].as_array().unwrap().iter().map(|w| w[1].as_u64().unwrap()).sum();
        assert_eq!(why, n(row, "no_plan"), "every attempt without a plan has a reason: {row}");
        for k in ["zone_hit_per_rollout", "success_per_rollout"] {
            match row[k].as_f64() {
                Some(x) => assert!((0.0..=1.0).contains(&x) && planned > 0),
                None => assert_eq!(planned, 0),
            }
        }
    }
    for variant in ["as planned", "+ refine"] {
        let of = |v: &[&Value], label: Option<&str>| -> Vec<Value> {
            v.iter()
                .filter(|x| x["variant"] == variant && label.is_none_or(|l| x["label"] == l))
                .map(|x| (*x).clone())
                .collect()
        };
        let total = &of(&rows, Some("total"))[0];
        assert_eq!(n(total, "attempts"), attempts);
        let parts: Vec<Value> = of(&rows, None).into_iter().filter(|x| x["label"] != "total").collect();
        assert_eq!(parts.len(), 8, "the paper's eight behaviours");
        for k in ["attempts", "planned", "verified", "rollouts"] {
            assert_eq!(parts.iter().map(|x| n(x, k)).sum::<u64>(), n(total, k), "{k} over behaviours");
            assert_eq!(of(&subsets, None).iter().map(|x| n(x, k)).sum::<u64>(), n(total, k), "{k} over subsets");
            assert_eq!(of(&sources, None).iter().map(|x| n(x, k)).sum::<u64>(), n(total, k), "{k} over sources");
        }
        assert!(n(total, "pairs") * 8 == attempts, "every (scene, t0) pair has the eight behaviours");
    }
    let cut = &r["cut_in"][0];
    assert!(n(cut, "planned_with_adjacent") <= n(cut, "with_adjacent"));
    assert!(n(cut, "with_adjacent") <= n(cut, "attempts") && n(cut, "positioned") <= n(cut, "with_adjacent"));
    let t = &r["timing"][0];
    assert_eq!(n(t, "cases"), attempts);
    assert!(t["cases_per_s"].as_f64().unwrap() > 0.0);
}

fn bench(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).arg("bench-cases").args(args).output().expect("run carla-gs")
}

fn refused(o: std::process::Output, needle: &str) {
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "expected a refusal naming `{needle}`: {err}");
    assert!(err.contains(needle), "expected `{needle}` in: {err}");
}

/// Issue 56: `bench-cases --out` wrote `bench.json`, `bench.md` and `eval/` into any folder. Now it
/// is new, empty or ours (replaced whole, and only with `--force`), never inside `--data`.
#[test]
fn bench_out_is_new_empty_or_ours_replaced_whole_with_force() {
    let Some(data) = data() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let small = ["--sources", "womd", "--perturbations", "none", "--behaviors", "sudden_braking", "--t0", "2"];
    let small: Vec<&str> =
        small.into_iter().chain(["--refine-rounds", "0", "--data", data.to_str().unwrap()]).collect();
    // A person's folder with a bench.json of their own: refused, with or without --force.
    let mine = tmp.path().join("mine");
    std::fs::create_dir_all(&mine).unwrap();
    std::fs::write(mine.join("bench.json"), br#"{"my": "numbers"}"#).unwrap();
    let mine_s = s(&mine);
    for extra in [&[][..], &["--force"]] {
        let args: Vec<&str> = small.iter().copied().chain(["--out", &mine_s]).chain(extra.iter().copied()).collect();
        refused(bench(&args), "not a bench-cases output");
        assert_eq!(std::fs::read_dir(&mine).unwrap().count(), 1);
        assert_eq!(std::fs::read(mine.join("bench.json")).unwrap(), br#"{"my": "numbers"}"#);
    }
    // Inside --data.
    let inside = tmp.path().join("data-copy");
    std::fs::create_dir_all(&inside).unwrap();
    let args = ["--data", &s(&inside), "--out", &s(&inside.join("bench"))];
    refused(bench(&args), "inside the input directory");
    assert!(!inside.join("bench").exists());
    // Ours: kept without --force, replaced whole with it.
    let out = tmp.path().join("bench");
    let out_s = s(&out);
    let with_out: Vec<&str> = small.iter().copied().chain(["--out", &out_s]).collect();
    assert!(bench(&with_out).status.success());
    std::fs::write(out.join("stale.txt"), b"from before").unwrap();
    refused(bench(&with_out), "pass --force");
    assert!(out.join("stale.txt").is_file());
    let forced: Vec<&str> = with_out.iter().copied().chain(["--force"]).collect();
    assert!(bench(&forced).status.success());
    assert!(out.join("bench.json").is_file() && out.join("eval/report.json").is_file());
    assert!(!out.join("stale.txt").exists(), "replaced whole");
    let beside = cli_support::dot_entries_beside(&out);
    assert!(beside.is_empty(), "staging left beside --out: {beside:?}");
}
