//! Issue 28 (hostile input), the rows about outputs and messages (22-29): a file at an output
//! path is never replaced, `--force` replaces only our own outputs, writing over an existing
//! model needs `--force`, a failed or killed run leaves the old output or the new one and no
//! debris, a non-UTF-8 scene path is refused up front, a repeated WOMD scenario is named, and an
//! error says its cause once naming the field. S = `synth --frames 3 --width 64 --height 48`,
//! M = `train S --iters 5`, as in the issue, in a temporary directory.

use std::collections::BTreeMap;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn carla_gs<A: AsRef<OsStr>>(args: &[A]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Exit code 2 with every needle in the message.
fn refused(out: Output, needles: &[&str]) -> String {
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "expected a refusal naming {needles:?}: {stderr}");
    for n in needles {
        assert!(stderr.contains(n), "expected `{n}` in: {stderr}");
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
    stderr
}

fn ok(out: Output) -> String {
    assert_eq!(out.status.code(), Some(0), "stderr: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn synth(dir: &Path, name: &str) -> PathBuf {
    let scene = dir.join(name);
    ok(carla_gs(&["synth", "--out", s(&scene), "--frames", "3", "--width", "64", "--height", "48"]));
    scene
}

fn train(scene: &Path, out: &Path, iters: &str, extra: &[&str]) -> Output {
    carla_gs(&[&["train", s(scene), "--out", s(out), "--iters", iters][..], extra].concat())
}

/// Every file under `dir` with its bytes.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(snapshot(&p));
        } else {
            out.insert(p.clone(), std::fs::read(&p).unwrap());
        }
    }
    out
}

/// The names in `dir`, sorted.
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

/// A transforms.json photo set of two 64x48 images.
fn photo_set(dir: &Path, fl_x: &str) -> PathBuf {
    let set = dir.join("set");
    std::fs::create_dir_all(&set).unwrap();
    for n in 0..2 {
        let img = image::RgbImage::from_fn(64, 48, |x, y| image::Rgb([(x * 4) as u8, (y * 5) as u8, 60]));
        img.save(set.join(format!("r_{n}.png"))).unwrap();
    }
    let pose = "[[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]";
    let json = format!(
        r#"{{"fl_x": {fl_x}, "fl_y": 50, "cx": 32, "cy": 24, "w": 64, "h": 48, "frames": [
        {{"file_path": "r_0.png", "transform_matrix": {pose}}}, {{"file_path": "r_1.png", "transform_matrix": {pose}}}]}}"#
    );
    std::fs::write(set.join("transforms.json"), json).unwrap();
    set
}

/// Row 22: `ingest`, `synth` or `priors --force` over a file installed the new output, moved the
/// file to `.NAME.old-PID` and said "nothing was written"; now the file is refused and untouched.
#[test]
fn a_file_at_the_output_path_is_never_replaced() {
    let tmp = tempfile::tempdir().unwrap();
    let set = photo_set(tmp.path(), "50");
    let scene = synth(tmp.path(), "S");
    let out = tmp.path().join("out");
    let file = out.join("F");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(&file, b"the user's file").unwrap();
    let synth_f = ["synth", "--out", s(&file), "--frames", "3", "--width", "64", "--height", "48", "--force"];
    for args in
        [&synth_f[..], &["ingest", s(&set), "--out", s(&file), "--force"], &["ingest", s(&set), "--out", s(&file)]]
    {
        refused(carla_gs(args), &[s(&file), "is not a directory"]);
        assert_eq!(std::fs::read(&file).unwrap(), b"the user's file");
        assert_eq!(names(&out), ["F"], "debris beside the file");
    }
    let priors = scene.join("priors");
    std::fs::write(&priors, b"the user's file").unwrap();
    let before = names(&scene);
    refused(carla_gs(&["priors", s(&scene), "--force"]), &[s(&priors), "is not a directory"]);
    assert_eq!(std::fs::read(&priors).unwrap(), b"the user's file");
    assert_eq!(names(&scene), before);
}

/// Row 23: `ingest --out <a folder of the user's own files> --force` deleted the folder; now
/// `--force` replaces only a directory carrying our marker, for ingest, synth and priors.
#[test]
fn force_replaces_only_our_own_outputs() {
    let tmp = tempfile::tempdir().unwrap();
    let set = photo_set(tmp.path(), "50");
    let mine = tmp.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("thesis.tex"), b"years of work").unwrap();
    let synth_mine = ["synth", "--out", s(&mine), "--frames", "3", "--width", "64", "--height", "48", "--force"];
    for args in [&["ingest", s(&set), "--out", s(&mine), "--force"][..], &synth_mine[..]] {
        refused(carla_gs(args), &[s(&mine), "not a scene directory", "--force replaces only our own outputs"]);
        assert_eq!(names(&mine), ["thesis.tex"]);
        assert_eq!(names(tmp.path()), ["mine", "set"], "debris left");
    }
    // Our own scene is replaced with --force, and refused without it.
    let scene = tmp.path().join("scene");
    ok(carla_gs(&["ingest", s(&set), "--out", s(&scene)]));
    refused(carla_gs(&["ingest", s(&set), "--out", s(&scene)]), &["already exists (pass --force to replace it)"]);
    ok(carla_gs(&["ingest", s(&set), "--out", s(&scene), "--force"]));
    // priors/ holding the user's files is not replaced either.
    let priors = scene.join("priors");
    std::fs::create_dir(&priors).unwrap();
    std::fs::write(priors.join("notes.txt"), b"mine").unwrap();
    refused(carla_gs(&["priors", s(&scene), "--force"]), &[s(&priors), "not a priors directory"]);
    assert_eq!(names(&priors), ["notes.txt"]);
}

/// Row 24: `train` or `replace` into an existing model directory overwrote it without `--force`.
#[test]
fn an_existing_model_is_replaced_only_with_force() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = synth(tmp.path(), "S");
    let model = tmp.path().join("M");
    ok(train(&scene, &model, "5", &[]));
    let before = snapshot(&model);
    refused(train(&scene, &model, "6", &[]), &[s(&model), "already exists (pass --force to replace it)"]);
    assert_eq!(snapshot(&model), before, "the model changed without --force");
    ok(train(&scene, &model, "6", &["--force"]));
    let record: serde_json::Value = serde_json::from_slice(&std::fs::read(model.join("model.json")).unwrap()).unwrap();
    assert_eq!(record["iterations"], 6);
    // A folder of the user's is not a model, with or without --force.
    let mine = tmp.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("notes.txt"), b"mine").unwrap();
    refused(train(&scene, &mine, "5", &["--force"]), &[s(&mine), "not a model directory"]);
    assert_eq!(names(&mine), ["notes.txt"]);
    // replace: an existing --out is refused before anything is read.
    let other = tmp.path().join("M2");
    ok(train(&scene, &other, "5", &[]));
    let other_before = snapshot(&other);
    let replace = |out: &Path, force: bool| {
        let mut args = vec!["replace", s(&model), "--track", "t", "--asset", "a", "--out", s(out)];
        if force {
            args.push("--force");
        }
        carla_gs(&args)
    };
    refused(replace(&other, false), &[s(&other), "already exists (pass --force to replace it)"]);
    refused(replace(&mine, true), &[s(&mine), "not a model directory"]);
    assert_eq!(snapshot(&other), other_before);
    assert_eq!(names(&mine), ["notes.txt"]);
}

/// Row 25: a run that failed on the scene's data left an empty `--out` directory.
#[test]
fn a_run_failing_on_the_scene_data_leaves_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = synth(tmp.path(), "S");
    std::fs::write(scene.join("images/000000_FRONT.jpg"), b"not a JPEG at all").unwrap();
    let model = tmp.path().join("M");
    refused(train(&scene, &model, "5", &[]), &["000000_FRONT.jpg"]);
    assert_eq!(names(tmp.path()), ["S"], "train left something behind");
}

/// Row 26: `kill -9` of `train S --out M --iters 7` over an existing M left a mix of old and new
/// files; a stray temporary in M survived `--resume`. The new model is now built beside M and
/// renamed over it in one step: a process killed just before that rename leaves M as it was, and
/// the next run removes its staging directory. A resumed run removes stray temporaries.
#[test]
fn a_killed_run_leaves_the_old_model_or_the_new_one() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = synth(tmp.path(), "S");
    let model = tmp.path().join("M");
    ok(train(&scene, &model, "5", &[]));
    let before = snapshot(&model);
    let killed = Command::new(env!("CARGO_BIN_EXE_carla-gs"))
        .args(["train", s(&scene), "--out", s(&model), "--iters", "7", "--force"])
        .env("CARLA_GS_TEST_ABORT", "before-commit")
        .output()
        .unwrap();
    assert!(!killed.status.success(), "the test hook did not stop the run");
    assert_eq!(snapshot(&model), before, "the old model was touched before the new one was whole");
    let staging: Vec<String> = names(tmp.path()).into_iter().filter(|n| n.starts_with(".M.")).collect();
    assert_eq!(staging.len(), 1, "the new model was not built beside M: {:?}", names(tmp.path()));
    ok(carla_gs(&["eval-recon", s(&model), s(&scene)]));
    // The next run replaces M whole and removes the dead run's staging directory.
    ok(train(&scene, &model, "7", &["--force"]));
    assert_eq!(names(tmp.path()), ["M", "S"]);
    let record: serde_json::Value = serde_json::from_slice(&std::fs::read(model.join("model.json")).unwrap()).unwrap();
    assert_eq!(record["iterations"], 7);
    // A stopped run with stray temporaries in it resumes, and the temporaries go.
    let part = tmp.path().join("P");
    ok(train(&scene, &part, "5", &["--stop-after", "3"]));
    std::fs::write(part.join(".tmpAb12Cd"), vec![7u8; 1 << 20]).unwrap();
    std::fs::write(part.join(".checkpoint.bin.Xy9.tmp"), b"half").unwrap();
    ok(train(&scene, &part, "5", &["--resume"]));
    let left = names(&part);
    assert!(left.iter().all(|n| !n.starts_with('.')), "stray temporaries survived --resume: {left:?}");
    assert!(left.contains(&"model.json".to_string()));
}

/// Row 27: a scene path with a non-UTF-8 byte trained, then failed writing model.json, leaving a
/// model directory without one; it is now refused before anything is trained or written.
#[cfg(unix)]
#[test]
fn a_non_utf8_scene_path_is_refused_up_front() {
    use std::os::unix::ffi::OsStrExt;
    let tmp = tempfile::tempdir().unwrap();
    let scene = synth(tmp.path(), "S");
    let odd = tmp.path().join(OsStr::from_bytes(b"sc\xffene"));
    std::fs::rename(&scene, &odd).unwrap();
    let model = tmp.path().join("M");
    let out = carla_gs(&[
        OsStr::new("train"),
        odd.as_os_str(),
        OsStr::new("--out"),
        model.as_os_str(),
        OsStr::new("--iters"),
        OsStr::new("5"),
    ]);
    refused(out, &["invalid UTF-8"]);
    assert!(!model.exists(), "a model directory was left");
}

/// Row 28: a WOMD file holding one scenario twice said "already exists (pass --force to replace
/// it)" even with --force; it now names the repeated scenario id in the input.
#[test]
fn a_repeated_womd_scenario_is_named() {
    let Some(a) = ingest::shared::waymo_file("motion_data_one_scenario.tfrecord") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let twice = tmp.path().join("twice.tfrecord");
    let one = std::fs::read(&a).unwrap();
    std::fs::write(&twice, [one.clone(), one].concat()).unwrap();
    let out = tmp.path().join("out");
    let msg = refused(
        carla_gs(&["ingest", s(&twice), "--out", s(&out), "--format", "womd", "--force"]),
        &["twice.tfrecord", "`scenario_id`", "637f20cafde22ff8", "more than once in the input"],
    );
    assert!(!msg.contains("already exists"), "{msg}");
    assert!(!out.exists());
}

/// Row 29: messages said their cause two or three times, and transforms.json `fl_x: "big"` was
/// reported at `.`; each message now says its cause once and names the field.
#[test]
fn a_message_says_its_cause_once_and_names_the_field() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let set = photo_set(tmp.path(), "\"big\"");
    refused(carla_gs(&["ingest", s(&set), "--out", s(&out)]), &["transforms.json: `fl_x`: expected a number"]);
    let mut record = Vec::new();
    ingest::tfrecord::write_record(&mut record, &[1u8; 400]).unwrap();
    let cut = tmp.path().join("cut.tfrecord");
    std::fs::write(&cut, &record[..200]).unwrap();
    let msg = refused(carla_gs(&["ingest", s(&cut), "--out", s(&out)]), &["cut.tfrecord", "record 0"]);
    let line = msg.lines().find(|l| l.starts_with("error:")).unwrap();
    let parts: Vec<&str> = line.split(": ").map(|p| p.trim()).collect();
    for (i, p) in parts.iter().enumerate() {
        assert!(!parts[i + 1..].iter().any(|q| q.contains(p) || p.contains(q)), "cause said twice: {line}");
    }
    assert_eq!(line.matches("truncated").count(), 1, "{line}");
    assert!(!out.exists());
}
