//! Issue 56, `tables` on edited shard records and case files: the merge's inputs are data from
//! elsewhere. A record's `attempts_total` or `shard.count` is never allocated from, a shard
//! `I/N` with `I >= N` is named as such, a changed digest shows both digests, and a case file's
//! MinTTC, Success flags and a record's horizon must be ones a run writes. Fixture: a 6 s
//! synthetic scene, `eval-cases` with the planner on sudden braking at t0 = 2 s, in two shards.

mod cli_support;
use cli_support::{carla_gs, dot_entries_beside, killed_after, ok, refused, s};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Two shard runs (0/2 and 1/2) of two attempts (sudden braking and cut-in at t0 = 2 s).
fn shards(t: &Path) -> PathBuf {
    let scene = t.join("scene");
    ok(carla_gs(&["synth", "--out", s(&scene), "--frames", "60", "--cameras", "1", "--width", "32", "--height", "24"]));
    let out = t.join("shards");
    for shard in ["0/2", "1/2"] {
        ok(carla_gs(&[
            "eval-cases",
            s(&scene),
            "--agents",
            "planner",
            "--behaviors",
            "sudden_braking,sudden_cut_in",
            "--t0",
            "2",
            "--refine-rounds",
            "0",
            "--no-plots",
            "--shard",
            shard,
            "--out",
            s(&out),
        ]));
    }
    out
}

fn edit(file: &Path, f: impl FnOnce(&mut Value)) {
    let mut v: Value = serde_json::from_slice(&std::fs::read(file).unwrap()).unwrap();
    f(&mut v);
    std::fs::write(file, serde_json::to_vec_pretty(&v).unwrap()).unwrap();
}

/// A fresh copy of the fixture's shard outputs under `t/<name>`.
fn copy(from: &Path, t: &Path, name: &str) -> PathBuf {
    let to = t.join(name);
    let status = std::process::Command::new("cp").args(["-r", s(from), s(&to)]).status().unwrap();
    assert!(status.success());
    to
}

fn tables(dir: &Path, t: &Path) -> std::process::Output {
    carla_gs(&["tables", s(dir), "--no-plots", "--out", s(&t.join("tables-out"))])
}

/// The case file of the done case (the one with rounds).
fn done_case(dir: &Path) -> PathBuf {
    let cases = dir.join("cases");
    let mut v: Vec<PathBuf> = std::fs::read_dir(&cases).unwrap().map(|e| e.unwrap().path().join("case.json")).collect();
    v.sort();
    v.into_iter()
        .find(|p| std::fs::read_to_string(p).unwrap().contains("\"rounds\""))
        .expect("the fixture has a done case")
}

#[test]
fn edited_shard_records_and_case_files_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let base = shards(t);
    ok(tables(&base, t));
    let record0 = "shard-0-of-2.json";

    // attempts_total of 1e15: refused before anything is allocated from it (was an abort).
    let d = copy(&base, t, "total");
    edit(&d.join(record0), |v| v["attempts_total"] = Value::from(1_000_000_000_000_000u64));
    edit(&d.join("shard-1-of-2.json"), |v| v["attempts_total"] = Value::from(1_000_000_000_000_000u64));
    refused(tables(&d, t), &["attempts_total", "hold 2 attempts"]);

    // shard.count of 2^62 (was an abort), and a record claiming shard 5/3 (was "2/3 missing").
    let d = copy(&base, t, "count");
    edit(&d.join(record0), |v| v["shard"]["count"] = Value::from(1u64 << 62));
    refused(tables(&d, t), &["shard-0-of-2.json", "shard: 0/4611686018427387904", "0 <= I < N"]);
    let d = copy(&base, t, "five-of-three");
    edit(&d.join(record0), |v| v["shard"] = serde_json::json!({"index": 5, "count": 3}));
    refused(tables(&d, t), &["shard: 5/3"]);

    // A changed digest: both sides are shown, and they differ.
    let d = copy(&base, t, "digest");
    edit(&d.join(record0), |v| v["attempts_digest"] = Value::from("0123456789abcdef-2"));
    refused(tables(&d, t), &["digest 0123456789abcdef-2"]);

    // A negative horizon (was printed in the summary).
    let d = copy(&base, t, "horizon");
    for r in [record0, "shard-1-of-2.json"] {
        edit(&d.join(r), |v| v["settings"]["window"]["horizon"] = serde_json::json!({"seconds": -5.0}));
    }
    refused(tables(&d, t), &["settings.window.horizon", "-5"]);

    // MinTTC of 1e308 (was a 308-digit mean "± inf").
    let d = copy(&base, t, "minttc");
    let case = done_case(&d);
    edit(&case, |v| v["rounds"][0]["metrics"]["min_ttc_center_s"] = Value::from(1e308));
    refused(tables(&d, t), &["case.json", "rounds[0].metrics.min_ttc_center_s", "[0, 5]"]);

    // A forged Success flag (was counted).
    let d = copy(&base, t, "success");
    let case = done_case(&d);
    edit(&case, |v| {
        let m = &mut v["rounds"][0]["metrics"];
        let forged = !m["success_center"].as_bool().unwrap();
        m["success_center"] = Value::from(forged);
    });
    refused(tables(&d, t), &["case.json", "success_center", "MinTTC"]);
}

/// The tables `plant_old` plants (those `tables` writes but its plot and report.json).
const TABLES: [&str; 6] = ["table1.md", "table1.csv", "table1_paired.md", "why_no_plan.md", "table2.md", "summary.md"];

/// Whether the files `names` of `dir` are the planted earlier set (`old`), none of it (`new`) or
/// both (`mixed`); and whether `report.json` is there.
fn table_state(dir: &Path, names: &[&str]) -> (&'static str, bool) {
    let old: Vec<bool> = names.iter().filter_map(|n| std::fs::read(dir.join(n)).ok()).map(|b| b == b"old").collect();
    let state = match (old.iter().all(|o| *o), old.iter().all(|o| !o)) {
        (true, _) => "old",
        (_, true) => "new",
        _ => "mixed",
    };
    (state, dir.join("report.json").is_file())
}

#[test]
fn a_killed_tables_leaves_the_old_set_or_the_new_and_a_rerun_completes() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let base = shards(t);
    // The delays cover the merge, the plot and the moves (a whole run takes a few hundred ms).
    let delays_ms = [0u64, 5, 15, 30, 60, 100, 150, 250, 400, 700];
    for (name, beside_shards) in [("beside-shards", true), ("tables-only", false)] {
        let shards_dir = copy(&base, t, name);
        let out = if beside_shards { shards_dir.clone() } else { t.join(format!("{name}-out")) };
        // Beside shards, report.json is planted as an old file too (the shard records make the
        // folder ours); a tables-only folder is ours by a report.json that reads as one.
        let names: Vec<&str> = TABLES.iter().copied().chain(beside_shards.then_some("report.json")).collect();
        let mut seen = std::collections::BTreeSet::new();
        for ms in delays_ms {
            ok(carla_gs(&["tables", s(&shards_dir), "--out", s(&out)]));
            for n in &names {
                std::fs::write(out.join(n), b"old").unwrap();
            }
            killed_after(&["tables", s(&shards_dir), "--out", s(&out)], ms);
            let (state, report) = table_state(&out, &names);
            if beside_shards {
                // report.json is removed before the first move and moved in last: with it there,
                // the set is whole, old or new.
                assert!(!(report && state == "mixed"), "{name}, killed after {ms} ms: a mixed set with report.json");
            } else {
                // Replaced in one rename.
                assert!(report && state != "mixed", "{name}, killed after {ms} ms: {state}, report.json {report}");
            }
            seen.insert(state);
            // A re-run completes, with nothing of ours left beside --out.
            ok(carla_gs(&["tables", s(&shards_dir), "--out", s(&out)]));
            assert_eq!(table_state(&out, &names), ("new", true), "{name}: the re-run after a kill at {ms} ms");
            let leftovers = dot_entries_beside(&out);
            assert!(leftovers.is_empty(), "{name}: left beside --out: {leftovers:?}");
        }
        // A kill hit before the moves at least (the old set); the later ones usually find the new
        // set, but how late that is depends on the machine's load, so it is not required.
        assert!(seen.contains("old"), "{name}: kills only saw {seen:?}");
    }
}
