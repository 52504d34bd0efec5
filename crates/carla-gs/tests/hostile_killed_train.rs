//! Issue 56: a `train` into a new directory killed before its first checkpoint left only our
//! `config.toml`; then a re-run, `--force` and `--resume` were all refused and the directory had
//! to be deleted by hand (the same blocked a batch train node's retry and a demo killed while
//! training). Now such a directory counts as a run that has not started: every mode trains it
//! afresh. The kill's state is made by copying the `config.toml` a finished run wrote into a new
//! directory, with a temporary file a killed atomic write leaves.

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
    // A person's file beside the config: not a run of ours that never started; refused, kept.
    let mine = t.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("config.toml"), &config).unwrap();
    std::fs::write(mine.join("notes.txt"), b"mine").unwrap();
    refused(train(&mine, &["--force"]), &[s(&mine)]);
    assert_eq!(std::fs::read(mine.join("notes.txt")).unwrap(), b"mine");
    assert!(!mine.join("model.json").exists());
}
