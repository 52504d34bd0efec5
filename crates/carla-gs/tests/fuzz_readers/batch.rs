//! Fuzz targets over the batch and merge inputs (issue 56 E): the batch manifest (TOML), the
//! plan (JSON, as `batch exec` reads it), and a shard run's record with its case file, read back
//! by `tables` (`cases::merge`, which checks each case file's numbers). The record and case file
//! come from `eval-cases --shard 0/1` on the fixture's street.

use super::{clean, fuzz, fuzz_files};
use std::path::{Path, PathBuf};
use std::process::Command;

const MANIFEST: &str = r#"[[log]]
name = "street"
scene = "street"

[priors]
args = []

[train]
device = "cpu"
iters = 100
scale = 0.5
seed = 3
cpus = 2
memory_gb = 8.0

[eval_cases]
agents = "planner,rule"
behaviors = "sudden_braking,sudden_cut_in"
t0 = "every:1s"
seed = 0
horizon = "5"
shards = 4
args = ["--no-plots"]

[run]
behaviors = ["sudden_cut_in"]
args = ["--layouts", "front3"]
"#;

/// A folder holding the manifest's scene folder (existence is what `batch plan` checks of it).
fn manifest_dir() -> tempfile::TempDir {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::create_dir(tmp.path().join("street")).unwrap();
    tmp
}

#[test]
fn fuzz_batch_manifest() {
    use pipeline::batch::manifest::Manifest;
    let tmp = manifest_dir();
    let file = tmp.path().join("m.toml");
    fuzz("batch manifest", MANIFEST.as_bytes(), true, |b| {
        std::fs::write(&file, b).unwrap();
        let m = Manifest::read(&file).map_err(|e| e.to_string())?;
        pipeline::batch::checks::inputs_exist(&m, &file).map_err(|e| e.to_string())?;
        clean(pipeline::batch::plan::build(&m, &file, &tmp.path().join("out")))
    });
}

#[test]
fn fuzz_batch_plan() {
    use pipeline::batch::{manifest::Manifest, node, plan};
    let tmp = manifest_dir();
    let file = tmp.path().join("m.toml");
    std::fs::write(&file, MANIFEST).unwrap();
    let p = plan::build(&Manifest::read(&file).unwrap(), &file, &tmp.path().join("out")).unwrap();
    let base = serde_json::to_vec_pretty(&p).unwrap();
    let at = tmp.path().join("plan.json");
    fuzz("batch plan", &base, true, |b| {
        std::fs::write(&at, b).unwrap();
        let p = node::read_plan(&at).map_err(|e| e.to_string())?;
        let n = node::find(&p, Some("tables"), None).map_err(|e| e.to_string())?;
        let _ = node::stamp_path(&p, n);
        clean(node::check_command(n))
    });
}

/// `eval-cases --shard 0/1` on `scene` (planner, one attempt): the record and the case file.
fn shard_run(scene: &Path, out: &Path) -> (PathBuf, PathBuf) {
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let args = [
        "eval-cases",
        &s(scene),
        "--agents",
        "planner",
        "--behaviors",
        "sudden_cut_in",
        "--t0",
        "1",
        "--refine-rounds",
        "1",
        "--no-plots",
        "--shard",
        "0/1",
        "--out",
        &s(out),
    ];
    let r = Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let case = std::fs::read_dir(out.join("cases")).unwrap().next().unwrap().unwrap().path().join("case.json");
    (out.join("shard-0-of-1.json"), case)
}

#[test]
fn fuzz_shard_record_and_case_file() {
    let tmp = tempfile::tempdir().unwrap();
    let (record, case) = shard_run(&super::files::fixture_scene(), &tmp.path().join("run"));
    let case_rel = case.strip_prefix(tmp.path().join("run")).unwrap().to_path_buf();
    let base = vec![
        ("shard record".to_string(), std::fs::read(&record).unwrap()),
        ("case.json".to_string(), std::fs::read(&case).unwrap()),
    ];
    let dir = tmp.path().join("fuzzed");
    std::fs::create_dir_all(dir.join(case_rel.parent().unwrap())).unwrap();
    fuzz_files("shard record+case", &base, true, |files| {
        std::fs::write(dir.join("shard-0-of-1.json"), &files[0].1).unwrap();
        std::fs::write(dir.join(&case_rel), &files[1].1).unwrap();
        clean(cases::merge::merge(std::slice::from_ref(&dir)))
    });
}
