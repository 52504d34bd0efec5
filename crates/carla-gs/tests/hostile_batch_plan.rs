//! `carla-gs batch plan` with a million `[eval_cases]` shards for one log wrote a 906 MB plan;
//! it is now refused with exit 2 naming the manifest and the budget, and no `plan.json` is
//! written (pipeline::batch::budget).

use std::process::Command;

#[test]
fn a_million_shards_are_refused_and_no_plan_is_written() {
    let d = tempfile::tempdir().unwrap();
    let m = d.path().join("m.toml");
    std::fs::write(&m, "[[log]]\nname = \"a\"\nscene = \"s\"\n[eval_cases]\nshards = 1000000\n").unwrap();
    let out = d.path().join("plan");
    let r = Command::new(env!("CARGO_BIN_EXE_carla-gs"))
        .args(["batch", "plan", m.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(err.contains("m.toml") && err.contains("shards = 1000000: expected 1 to 1000"), "{err}");
    assert!(!out.join("plan.json").exists());
}
