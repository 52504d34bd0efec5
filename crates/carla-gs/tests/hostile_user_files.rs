//! Issue 56, "a user's files lost or mixed": `eval-cases`, `tables`, `ablate` and `batch plan`
//! overwrote same-named files of a person's (`summary.md`, `table3.md`, `plan.json`); now each is refused
//! with exit 2 naming the folder or file, and the person's files are listed unchanged after.
//! `eval-cases` killed part-way left a partial `cases/` (or, over a finished run, old tables
//! beside half of the new case files); its output is now built beside `--out` and swapped in at
//! the end, so a kill leaves the old output whole and a re-run completes.

mod cli_support;
use cli_support::{carla_gs, listing, ok, refused, s};
use std::path::{Path, PathBuf};

fn synth(t: &Path) -> PathBuf {
    let scene = t.join("scene");
    let args = ["synth", "--out", s(&scene), "--frames", "40", "--width", "32", "--height", "24", "--cameras", "1"];
    ok(carla_gs(&args));
    scene
}

fn eval_cases(scene: &Path, out: &Path, extra: &[&str]) -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_carla-gs"));
    c.args(["eval-cases", s(scene), "--agents", "planner", "--behaviors", "sudden_braking", "--t0", "1"]);
    c.args(["--refine-rounds", "0", "--no-plots", "--out", s(out)]).args(extra);
    c
}

fn a_persons_folder(dir: &Path, file: &str) {
    std::fs::create_dir_all(dir).unwrap();
    std::fs::write(dir.join(file), b"a person's own notes").unwrap();
    std::fs::write(dir.join("thesis.tex"), b"\\section{mine}").unwrap();
}

#[test]
fn eval_cases_never_overwrites_a_persons_files() {
    let t = tempfile::tempdir().unwrap();
    let scene = synth(t.path());
    let out = t.path().join("mine");
    a_persons_folder(&out, "summary.md");
    let before = listing(t.path());
    for extra in [&[][..], &["--force"]] {
        refused(eval_cases(&scene, &out, extra).output().unwrap(), &[s(&out), "summary.md", "eval-cases output"]);
        assert_eq!(listing(t.path()), before, "{extra:?}");
    }
    // A shard adds to a folder of ours only.
    refused(eval_cases(&scene, &out, &["--shard", "0/2"]).output().unwrap(), &[s(&out), "summary.md"]);
    assert_eq!(listing(t.path()), before);
}

#[test]
fn eval_cases_killed_before_the_swap_leaves_the_old_output_and_a_rerun_completes() {
    let t = tempfile::tempdir().unwrap();
    let scene = synth(t.path());
    let out = t.path().join("eval");
    ok(eval_cases(&scene, &out, &[]).output().unwrap());
    assert!(out.join("summary.md").is_file() && out.join("cases").is_dir());
    // Our own output: replaced only with --force.
    refused(eval_cases(&scene, &out, &[]).output().unwrap(), &[s(&out), "--force"]);
    let before = listing(&out);
    // Killed (abort, as kill -9) with the new cases all written, just before they move in.
    let killed = eval_cases(&scene, &out, &["--force", "--seed", "7"])
        .env("CARLA_GS_TEST_ABORT", "before-commit")
        .output()
        .unwrap();
    assert_ne!(killed.status.code(), Some(0), "{}", String::from_utf8_lossy(&killed.stderr));
    assert_eq!(listing(&out), before, "old tables beside new case files");
    ok(eval_cases(&scene, &out, &["--force", "--seed", "7"]).output().unwrap());
    let report = std::fs::read_to_string(out.join("report.json")).unwrap();
    assert!(report.contains("\"seed\": 7"), "{report}");
    // The killed run's staging directory went with the re-run; nothing else is beside --out.
    let mut names: Vec<String> =
        std::fs::read_dir(t.path()).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into()).collect();
    names.sort();
    assert_eq!(names, ["eval", "scene"]);
}

#[test]
fn eval_cases_over_what_an_older_killed_run_left_completes() {
    let t = tempfile::tempdir().unwrap();
    let scene = synth(t.path());
    let done = t.path().join("done");
    ok(eval_cases(&scene, &done, &[]).output().unwrap());
    // Killed part-way, in place: some case files, no tables.
    let out = t.path().join("eval");
    std::fs::create_dir(&out).unwrap();
    let status = std::process::Command::new("cp").args(["-r", s(&done.join("cases")), s(&out)]).status().unwrap();
    assert!(status.success());
    refused(eval_cases(&scene, &out, &[]).output().unwrap(), &[s(&out), "--force"]);
    ok(eval_cases(&scene, &out, &["--force"]).output().unwrap());
    assert!(out.join("summary.md").is_file() && out.join("report.json").is_file());
}

#[test]
fn eval_cases_killed_at_any_moment_leaves_old_or_new_never_mixed() {
    let t = tempfile::tempdir().unwrap();
    let scene = synth(t.path());
    let out = t.path().join("eval");
    ok(eval_cases(&scene, &out, &[]).output().unwrap());
    for (delay_ms, seed) in [(30, "11"), (300, "12")] {
        let old = listing(&out);
        let mut child = eval_cases(&scene, &out, &["--force", "--seed", seed])
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(std::time::Duration::from_millis(delay_ms));
        let _ = child.kill();
        child.wait().unwrap();
        let report = std::fs::read_to_string(out.join("report.json")).unwrap();
        let new = report.contains(&format!("\"seed\": {seed}"));
        assert!(listing(&out) == old || new, "killed after {delay_ms} ms: a mixed output");
        // The re-run completes, whatever the kill left.
        ok(eval_cases(&scene, &out, &["--force", "--seed", seed]).output().unwrap());
        assert!(std::fs::read_to_string(out.join("report.json")).unwrap().contains(&format!("\"seed\": {seed}")));
    }
}

#[test]
fn tables_never_overwrite_a_persons_summary() {
    let t = tempfile::tempdir().unwrap();
    let scene = synth(t.path());
    let shard = t.path().join("shard");
    ok(eval_cases(&scene, &shard, &["--shard", "0/1"]).output().unwrap());
    let out = t.path().join("mine");
    a_persons_folder(&out, "summary.md");
    let before = listing(t.path());
    refused(carla_gs(&["tables", s(&shard), "--no-plots", "--out", s(&out)]), &[s(&out), "summary.md"]);
    assert_eq!(listing(t.path()), before);
    // Into the shards' own directory (ours), as before.
    ok(carla_gs(&["tables", s(&shard), "--no-plots", "--out", s(&shard)]));
    assert!(shard.join("summary.md").is_file());
}

#[test]
fn ablate_never_overwrites_a_persons_table() {
    let t = tempfile::tempdir().unwrap();
    let scene = synth(t.path());
    let out = t.path().join("mine");
    a_persons_folder(&out, "table3.md");
    let before = listing(t.path());
    for extra in [&[][..], &["--force"]] {
        let args = [&["ablate", s(&scene), "--out", s(&out), "--iters", "2"][..], extra].concat();
        refused(carla_gs(&args), &[s(&out), "table3.md", "ablation output"]);
        assert_eq!(listing(t.path()), before, "{extra:?}");
    }
}

#[test]
fn batch_plan_never_overwrites_a_persons_plan_json() {
    let t = tempfile::tempdir().unwrap();
    let scene = synth(t.path());
    let m = t.path().join("m.toml");
    std::fs::write(&m, format!("[[log]]\nname = \"a\"\nscene = \"{}\"\n[eval_cases]\nshards = 2\n", s(&scene)))
        .unwrap();
    let out = t.path().join("batch");
    a_persons_folder(&out, "plan.json");
    let before = listing(t.path());
    for extra in [&[][..], &["--force"]] {
        let args = [&["batch", "plan", s(&m), "--out", s(&out)][..], extra].concat();
        refused(carla_gs(&args), &[s(&out.join("plan.json"))]);
        assert_eq!(listing(t.path()), before, "{extra:?}");
    }
    // Our own plan: replaced with --force only.
    std::fs::remove_file(out.join("plan.json")).unwrap();
    ok(carla_gs(&["batch", "plan", s(&m), "--out", s(&out)]));
    refused(carla_gs(&["batch", "plan", s(&m), "--out", s(&out)]), &["plan.json", "--force"]);
    ok(carla_gs(&["batch", "plan", s(&m), "--out", s(&out), "--force"]));
    assert_eq!(std::fs::read(out.join("thesis.tex")).unwrap(), b"\\section{mine}");
}

/// `drive-tables --out` wrote `drive-eval.json`, `table.md` and `table.csv` into any folder,
/// a shard's own included (its record replaced by the merge). Now it is new, empty or an output
/// of ours, replaced whole only with `--force`, and never one of its shards.
#[test]
fn drive_tables_keeps_a_persons_folder_and_its_shards() {
    let t = tempfile::tempdir().unwrap();
    let scene = synth(t.path());
    let case = t.path().join("case1");
    std::fs::create_dir_all(&case).unwrap();
    let plan = case.join("scenario.json");
    let reason = ["reason", s(&scene), "--t0", "1", "--behavior", "sudden_braking", "--agent", "planner"];
    ok(carla_gs(&[&reason[..], &["--out", s(&plan)]].concat()));
    ok(carla_gs(&["simulate", s(&plan), "--scene", s(&scene), "--out", s(&case.join("executed.json"))]));
    let shard = t.path().join("shard0");
    let eval = ["eval-drive", s(&case), "--scene", s(&scene), "--policies", "constant", "--shard", "0/1"];
    ok(carla_gs(&[&eval[..], &["--out", s(&shard)]].concat()));
    let tables =
        |out: &Path, extra: &[&str]| carla_gs(&[&["drive-tables", s(&shard), "--out", s(out)][..], extra].concat());
    // A person's folder: refused with or without --force, unchanged.
    let mine = t.path().join("mine");
    a_persons_folder(&mine, "table.md");
    let before = listing(&mine);
    for extra in [&[][..], &["--force"]] {
        refused(tables(&mine, extra), &[s(&mine), "not a drive-tables output"]);
        assert_eq!(listing(&mine), before);
    }
    // A shard itself: refused (its record would be replaced by the merge).
    let shard_before = listing(&shard);
    refused(tables(&shard, &["--force"]), &["is an input"]);
    assert_eq!(listing(&shard), shard_before);
    // New: written; again: only with --force, whole.
    let out = t.path().join("merged");
    ok(tables(&out, &[]));
    assert!(out.join("table.md").is_file() && out.join("drive-eval.json").is_file());
    std::fs::write(out.join("stale.txt"), b"from before").unwrap();
    refused(tables(&out, &[]), &["pass --force"]);
    ok(tables(&out, &["--force"]));
    assert!(!out.join("stale.txt").exists(), "replaced whole");
}
