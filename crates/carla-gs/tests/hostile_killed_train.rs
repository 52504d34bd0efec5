//! Issue 56: a `train` into a new directory killed before its first checkpoint left only our
//! `config.toml`; then a re-run, `--force` and `--resume` were all refused and the directory had
//! to be deleted by hand (the same blocked a batch train node's retry and a demo killed while
//! training). Now such a directory counts as a run that has not started: every mode trains it
//! afresh. The kill's state is made by copying the `config.toml` a finished run wrote into a new
//! directory, with a temporary file a killed atomic write leaves. And a `batch exec` of a train,
//! an eval-cases shard or the tables node, its process group killed as a scheduler kills a job
//! at several points, runs again to completion.

mod cli_support;
use cli_support::{carla_gs, ok, refused, s};

#[test]
fn a_train_killed_before_its_first_checkpoint_can_be_run_again() {
    let t = tempfile::tempdir().unwrap();
    let scene = t.path().join("scene");
    let synth = ["synth", "--out", s(&scene), "--frames", "40", "--width", "32", "--height", "24", "--cameras", "1"];
    ok(carla_gs(&synth));
    let train = |out: &std::path::Path, extra: &[&str]| {
        let args = [&["train", s(&scene), "--out", s(out), "--iters", "2"][..], extra].concat();
        carla_gs(&args)
    };
    let done = t.path().join("done");
    ok(train(&done, &[]));
    let config = std::fs::read(done.join("config.toml")).unwrap();
    for (name, extra) in [("plain", &[][..]), ("force", &["--force"]), ("resume", &["--resume"])] {
        let killed = t.path().join(name);
        std::fs::create_dir(&killed).unwrap();
        std::fs::write(killed.join("config.toml"), &config).unwrap();
        std::fs::write(killed.join(".checkpoint.bin.a1b2c3.tmp"), b"half a checkpoint").unwrap();
        ok(train(&killed, extra));
        assert!(killed.join("model.json").is_file(), "{name}: no model");
        assert!(!killed.join(".checkpoint.bin.a1b2c3.tmp").exists(), "{name}: the temporary file stayed");
    }
    // Killed before even the config was written (found by killing `batch exec`): an empty
    // directory, which every mode trains (was "not a model directory" even with --force).
    for (name, extra) in [("empty-plain", &[][..]), ("empty-force", &["--force"]), ("empty-resume", &["--resume"])] {
        let killed = t.path().join(name);
        std::fs::create_dir(&killed).unwrap();
        ok(train(&killed, extra));
        assert!(killed.join("model.json").is_file(), "{name}: no model");
    }
    // A person's file beside the config: not a run of ours that never started; refused, kept.
    let mine = t.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("config.toml"), &config).unwrap();
    std::fs::write(mine.join("notes.txt"), b"mine").unwrap();
    refused(train(&mine, &["--force"]), &[s(&mine)]);
    assert_eq!(std::fs::read(mine.join("notes.txt")).unwrap(), b"mine");
    assert!(!mine.join("model.json").exists());
}

/// Kills `batch exec <plan> <node>` and its command (their process group, as a scheduler does)
/// after `ms` milliseconds; whether it had finished first.
fn exec_killed_after(plan: &std::path::Path, node: &str, ms: u64) -> bool {
    use std::os::unix::process::CommandExt;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_carla-gs"))
        .args(["batch", "exec", s(plan), node])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .process_group(0)
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(ms));
    let finished = child.try_wait().unwrap().is_some();
    let group = format!("-{}", child.id());
    let _ = std::process::Command::new("kill").args(["-s", "KILL", "--", &group]).status();
    child.wait().unwrap();
    finished
}

#[test]
fn a_killed_batch_exec_runs_again_to_completion() {
    let t = tempfile::tempdir().unwrap();
    let scene = t.path().join("scene");
    let synth = ["synth", "--out", s(&scene), "--frames", "40", "--width", "32", "--height", "24", "--cameras", "1"];
    ok(carla_gs(&synth));
    let manifest = t.path().join("m.toml");
    let toml = "[[log]]\nname = \"a\"\nscene = \"scene\"\n[train]\niters = 60\n\
                [eval_cases]\nagents = \"planner\"\nbehaviors = \"sudden_braking,sudden_cut_in\"\nt0 = \"2\"\nshards = 1\n";
    std::fs::write(&manifest, toml).unwrap();
    let out = t.path().join("batch");
    ok(carla_gs(&["batch", "plan", s(&manifest), "--out", s(&out)]));
    let plan = out.join("plan.json");
    for node in ["train/a", "eval_cases/0-of-1", "tables"] {
        let mut kills = 0;
        for ms in [100u64, 400, 1200] {
            if exec_killed_after(&plan, node, ms) {
                break;
            }
            kills += 1;
        }
        // Run again, with no clean-up by hand: it completes, and a further exec skips it.
        let done = ok(carla_gs(&["batch", "exec", s(&plan), node]));
        assert!(done.contains(node), "{node}: {done}");
        let again = ok(carla_gs(&["batch", "exec", s(&plan), node]));
        assert!(again.contains(&format!("skip {node}")), "{node} after {kills} kills: {again}");
    }
}
