//! Issue 28 item 6, numeric arguments (docs/fuzz.md): the binary on a small street with extreme
//! values (0, -1, NaN, inf, 1e300, 2^63) for numeric flags of `render`, `simulate`, `reason`,
//! `synth`, `train` and `priors`. Each run is killed after 20 s; the exit code must be 0 or 2 (3
//! also for `reason`), never a signal, 101 (panic) or 134 (abort).

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const EXTREMES: [&str; 6] = ["0", "-1", "NaN", "inf", "1e300", "9223372036854775808"];

/// Exit code of `carla-gs args`, killing it after 20 s (`None`: killed or ended by a signal).
fn exit_code(args: &[&str]) -> Option<i32> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_carla-gs"))
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("run carla-gs");
    let start = Instant::now();
    loop {
        if let Some(st) = child.try_wait().unwrap() {
            return st.code();
        }
        if start.elapsed() > Duration::from_secs(20) {
            child.kill().unwrap();
            child.wait().unwrap();
            return None;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn numeric_flags_exit_0_2_or_3() {
    let tmp = tempfile::tempdir().unwrap();
    let (scene, plan, ex) = (tmp.path().join("s"), tmp.path().join("plan.json"), tmp.path().join("ex.json"));
    let synth = ["synth", "--out", s(&scene), "--frames", "40", "--width", "32", "--height", "24", "--cameras", "1"];
    assert_eq!(exit_code(&synth), Some(0));
    assert_eq!(exit_code(&["reason", s(&scene), "--t0", "1", "--out", s(&plan)]), Some(0));
    let out = |n: &str| tmp.path().join(n).to_str().unwrap().to_string();
    let (o_png, o_ex, o_plan, o_s, o_m) = (out("r.png"), out("e.json"), out("p.json"), out("s2"), out("m"));
    // (command before the flag, the flag, after, allowed codes)
    let runs: Vec<(Vec<&str>, &str, Vec<&str>, &[i32])> = vec![
        (vec!["render", s(&scene), "--out", &o_png], "--frame", vec![], &[0, 2]),
        (vec!["render", s(&scene), "--out", &o_png], "--scale", vec![], &[0, 2]),
        (vec!["render", s(&scene), "--out", &o_png], "--shift-m", vec![], &[0, 2]),
        (vec!["simulate", s(&plan), "--scene", s(&scene), "--out", &o_ex], "--fps", vec![], &[0, 2]),
        (vec!["simulate", s(&plan), "--scene", s(&scene), "--out", &o_ex], "--control-dt", vec![], &[0, 2]),
        (vec!["reason", s(&scene), "--out", &o_plan], "--t0", vec![], &[0, 2, 3]),
        (vec!["reason", s(&scene), "--t0", "1", "--out", &o_plan], "--ttc", vec![], &[0, 2, 3]),
        (
            vec!["synth", "--out", &o_s, "--force", "--frames", "3", "--width", "16", "--height", "16"],
            "--cameras",
            vec![],
            &[0, 2],
        ),
        (vec!["train", s(&scene), "--out", &o_m, "--force"], "--iters", vec![], &[0, 2]),
    ];
    let mut n = 0;
    for (before, flag, after, allowed) in &runs {
        for v in EXTREMES {
            let args: Vec<&str> = before.iter().copied().chain([*flag, v]).chain(after.iter().copied()).collect();
            let code = exit_code(&args);
            n += 1;
            assert!(
                code.is_some_and(|c| allowed.contains(&c)),
                "carla-gs {args:?}: exit {code:?}, allowed {allowed:?}"
            );
        }
    }
    println!("fuzz numeric-args: {n} cases");
}
