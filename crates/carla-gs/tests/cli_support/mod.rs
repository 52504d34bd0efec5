//! What the command-line tests share: running the binary, and checking a refusal (exit code 2,
//! every needle in the message, no panic) or a success. Each test file that needs them has
//! `mod cli_support;`; not every file uses every helper.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

/// Runs the built `carla-gs` with `args`.
pub fn carla_gs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

/// A path as the `&str` an argument list takes.
pub fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// Exit code 2 with every needle in the message, and no panic.
pub fn refused(out: Output, needles: &[&str]) {
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "expected a refusal naming {needles:?}: {stderr}");
    for n in needles {
        assert!(stderr.contains(n), "expected `{n}` in: {stderr}");
    }
    assert!(!stderr.contains("panicked"), "{stderr}");
}

/// Exit code 0; the standard output.
pub fn ok(out: Output) -> String {
    assert_eq!(out.status.code(), Some(0), "stderr: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// Every path under `dir` with its content, sorted (folders end in `/`): a person's files listed
/// before and after a command.
pub fn listing(dir: &Path) -> Vec<(String, Vec<u8>)> {
    fn walk(root: &Path, dir: &Path, v: &mut Vec<(String, Vec<u8>)>) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let p = e.path();
            let rel = p.strip_prefix(root).unwrap().display().to_string();
            if p.is_dir() {
                v.push((rel + "/", vec![]));
                walk(root, &p, v);
            } else {
                v.push((rel, std::fs::read(&p).unwrap_or_default()));
            }
        }
    }
    let mut v = Vec::new();
    walk(dir, dir, &mut v);
    v.sort();
    v
}

/// Prints a line of the fuzz harness's log and appends it to `fuzz-log.txt` in cargo's
/// scratch directory for integration tests (`target/tmp`), which `.ci/run` prints after the
/// test run (so the harness's counts reach the log without running it twice).
pub fn fuzz_log(line: &str) {
    use std::io::Write;
    println!("{line}");
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-log.txt");
    if let Ok(mut f) = std::fs::OpenOptions::new().create(true).append(true).open(&path) {
        let _ = writeln!(f, "{line}");
    }
}

/// Runs the built `carla-gs` with `args` (output discarded) and kills it (SIGKILL) after `ms`
/// milliseconds; whether it had already ended with exit code 0 by then.
pub fn killed_after(args: &[&str], ms: u64) -> bool {
    let mut child = Command::new(env!("CARGO_BIN_EXE_carla-gs"))
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .expect("run carla-gs");
    std::thread::sleep(std::time::Duration::from_millis(ms));
    let _ = child.kill();
    child.wait().expect("wait for carla-gs").success()
}

/// The entries beside `out` (in its parent) whose names start with a dot: our staging and
/// set-aside folders, which a finished command must not leave.
pub fn dot_entries_beside(out: &Path) -> Vec<String> {
    let parent = out.parent().expect("--out has a parent");
    let names = std::fs::read_dir(parent).unwrap().flatten().map(|e| e.file_name().to_string_lossy().into_owned());
    names.filter(|n| n.starts_with('.')).collect()
}
