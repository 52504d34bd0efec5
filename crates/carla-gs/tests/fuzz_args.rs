//! Issue 28 item 6, numeric arguments (docs/fuzz.md): the binary on a small street with extreme
//! values (0, -1, NaN, inf, 1e300, 2^63) for numeric flags of `render`, `simulate`, `reason`,
//! `synth`, `train`, `run`, `eval-cases`, `bench-splat`, `export-xodr`, `asset`, `priors`,
//! `drive`, `demo`, `eval-drive` and `bench-cases` (the last on `../shared/data`'s KITTI paths,
//! skipped with a printed reason where they are absent). Each run is killed after 20 s; the exit code must be 0 or 2 (3
//! also for `reason`), never a signal, 101 (panic) or 134 (abort).

mod cli_support;
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
    let (scene, plan, model) = (tmp.path().join("s"), tmp.path().join("plan.json"), tmp.path().join("m0"));
    let synth = ["synth", "--out", s(&scene), "--frames", "40", "--width", "32", "--height", "24", "--cameras", "1"];
    assert_eq!(exit_code(&synth), Some(0));
    let reason =
        ["reason", s(&scene), "--t0", "1", "--behavior", "sudden_cut_in", "--agent", "planner", "--out", s(&plan)];
    assert_eq!(exit_code(&reason), Some(0));
    assert_eq!(exit_code(&["train", s(&scene), "--out", s(&model), "--iters", "2"]), Some(0));
    let out = |n: &str| tmp.path().join(n).to_str().unwrap().to_string();
    let (o_png, o_ex, o_plan, o_s, o_m) = (out("r.png"), out("e.json"), out("p.json"), out("s2"), out("m"));
    let render = vec!["render", s(&model), "--scene", s(&scene), "--camera", "FRONT", "--out", &o_png];
    let simulate = vec!["simulate", s(&plan), "--scene", s(&scene), "--out", &o_ex];
    let reason_at = vec!["reason", s(&scene), "--behavior", "sudden_cut_in", "--agent", "planner", "--out", &o_plan];
    let synth2 = vec!["synth", "--out", &o_s, "--force", "--frames", "3", "--width", "16", "--height", "16"];
    let o_run = out("run");
    let run_at =
        vec!["run", s(&scene), "--model", s(&model), "--behavior", "sudden_cut_in", "--t0", "1", "--out", &o_run];
    let run_at: Vec<&str> = run_at.into_iter().chain(["--layouts", "compare:FRONT", "--fps", "2"]).collect();
    // (command before the flag, the flag, after, a sane value that must succeed, allowed codes)
    type Run<'a> = (Vec<&'a str>, &'a str, Vec<&'a str>, &'a str, &'a [i32]);
    let (o_ev, o_bench) = (out("ev"), out("bench.json"));
    let eval = vec!["eval-cases", s(&scene), "--agents", "planner", "--behaviors", "sudden_cut_in", "--no-plots"];
    // Each run replaces the last one's output (ours), which takes --force (issue 56).
    let eval: Vec<&str> = eval.into_iter().chain(["--out", &o_ev, "--force"]).collect();
    let bench_splat = vec!["bench-splat", "--cases", "10x8x8", "--out", &o_bench];
    let mut runs: Vec<Run> = vec![
        (render.clone(), "--frame", vec![], "0", &[0, 2]),
        (render.clone(), "--scale", vec!["--frame", "0"], "0.5", &[0, 2]),
        (render.clone(), "--shift-m", vec!["--frame", "0"], "1", &[0, 2]),
        (simulate.clone(), "--fps", vec![], "24", &[0, 2]),
        (simulate.clone(), "--control-dt", vec![], "0.05", &[0, 2]),
        (reason_at.clone(), "--t0", vec![], "1", &[0, 2, 3]),
        (reason_at.clone(), "--ttc", vec!["--t0", "1"], "3", &[0, 2, 3]),
        (synth2.clone(), "--cameras", vec![], "1", &[0, 2]),
        (run_at.clone(), "--horizon", vec![], "5", &[0, 2, 3]),
        (vec!["train", s(&scene), "--out", &o_m, "--force"], "--iters", vec![], "1", &[0, 2]),
    ];
    // Issue 56: the numeric flags of the other commands.
    runs.extend::<Vec<Run>>(vec![
        (reason_at.clone(), "--dt", vec!["--t0", "1"], "0.1", &[0, 2, 3]),
        (reason_at.clone(), "--radius", vec!["--t0", "1"], "60", &[0, 2, 3]),
        (eval.clone(), "--t0", vec![], "1", &[0, 2, 3]),
        (eval.clone(), "--seed", vec!["--t0", "1"], "1", &[0, 2, 3]),
        (eval.clone(), "--refine-rounds", vec!["--t0", "1"], "1", &[0, 2, 3]),
        (eval.clone(), "--horizon", vec!["--t0", "1"], "5", &[0, 2, 3]),
        (bench_splat.clone(), "--iters", vec![], "1", &[0, 2]),
        (run_at.clone(), "--seeds-per-t0", vec![], "1", &[0, 2, 3]),
    ]);
    // Issue 56, the rest: export-xodr, asset, priors and drive (on a run made here).
    let (o_x, o_lib, o_run_d, o_drive) = (out("map.xodr"), out("lib"), out("run-d"), out("drive"));
    let run_d: Vec<&str> =
        run_at[..run_at.len()].iter().map(|a| if *a == o_run.as_str() { o_run_d.as_str() } else { a }).collect();
    assert!(matches!(exit_code(&run_d), Some(0 | 3)), "carla-gs {run_d:?}");
    let drive = vec!["drive", &o_run_d, "--scene", s(&scene), "--model", s(&model), "--policy", "constant"];
    let drive: Vec<&str> =
        drive.into_iter().chain(["--cameras", "FRONT", "--no-video", "--force", "--out", &o_drive]).collect();
    let xodr = vec!["export-xodr", s(&scene), "--out", &o_x, "--force"];
    let asset = vec!["asset", "--from-synth", "van", "--library", &o_lib, "--name", "v", "--force"];
    runs.extend::<Vec<Run>>(vec![
        (xodr.clone(), "--lane-width", vec![], "3.5", &[0, 2]),
        (asset.clone(), "--voxel", vec![], "0.2", &[0, 2]),
        (vec!["priors", s(&scene), "--force"], "--seed", vec![], "1", &[0, 2]),
    ]);
    if Path::new(&o_run_d).join("scenario.json").is_file() {
        for (flag, sane) in
            [("--dt", "0.1"), ("--lead-in", "1"), ("--tail", "1"), ("--scale", "0.5"), ("--policy-timeout", "10")]
        {
            runs.push((drive.clone(), flag, vec![], sane, &[0, 2]));
        }
    }
    // Every other numeric flag of the commands above (issue 56: "numeric flags of every command").
    let synth4 = vec!["synth", "--out", &o_s, "--force", "--cameras", "1"];
    for (flag, sane, fixed) in [
        ("--frames", "3", vec!["--width", "16", "--height", "16"]),
        ("--width", "16", vec!["--frames", "3", "--height", "16"]),
        ("--height", "16", vec!["--frames", "3", "--width", "16"]),
        ("--seed", "1", vec!["--frames", "3", "--width", "16", "--height", "16"]),
    ] {
        runs.push((synth4.clone(), flag, fixed, sane, &[0, 2]));
    }
    let train_m = vec!["train", s(&scene), "--out", &o_m, "--force", "--iters", "1"];
    runs.push((train_m.clone(), "--scale", vec![], "1", &[0, 2]));
    runs.push((train_m.clone(), "--seed", vec![], "1", &[0, 2]));
    runs.push((reason_at.clone(), "--seed", vec!["--t0", "1"], "1", &[0, 2, 3]));
    let o_video = out("v.mp4");
    let ex_d = format!("{o_run_d}/executed.json");
    if Path::new(&ex_d).is_file() {
        let video = vec!["video", &ex_d, "--scene", s(&scene), "--model", s(&model), "--out", &o_video, "--force"];
        let video: Vec<&str> = video.into_iter().chain(["--layouts", "compare:FRONT", "--png"]).collect();
        for (flag, sane) in [("--fps", "2"), ("--scale", "1"), ("--lead-in", "0")] {
            runs.push((video.clone(), flag, vec![], sane, &[0, 2]));
        }
    }
    let o_lib_h = out("lib-h");
    let harvest = vec!["asset", "harvest", s(&scene), "--model", s(&model), "--library", &o_lib_h, "--force"];
    for (flag, sane) in [("--max-closest-m", "15"), ("--min-azimuth-bins", "3"), ("--min-hull-px", "10")] {
        runs.push((harvest.clone(), flag, vec![], sane, &[0, 2]));
    }
    // The rest of issue 56: demo, eval-drive and bench-cases.
    let (o_demo, o_ed, o_bc) = (out("demo"), out("eval-drive"), out("bench-cases"));
    // A real log is trained at a quarter of its cameras' size: 96x64 keeps 24x16.
    let demo_scene = out("demo-scene");
    let synth3 = ["synth", "--out", &demo_scene, "--frames", "30", "--width", "96", "--height", "64", "--cameras", "1"];
    assert_eq!(exit_code(&synth3), Some(0));
    let demo = vec!["demo", "--input", &demo_scene, "--out", &o_demo, "--force", "--no-auto-replace"];
    runs.push((demo.clone(), "--iters", vec![], "1", &[0, 2]));
    runs.push((demo.clone(), "--seed", vec!["--iters", "1"], "1", &[0, 2]));
    if Path::new(&o_run_d).join("scenario.json").is_file() {
        let ed =
            vec!["eval-drive", &o_run_d, "--scene", s(&scene), "--policies", "constant", "--out", &o_ed, "--force"];
        for (flag, sane) in [("--dt", "0.1"), ("--lead-in", "1"), ("--tail", "1"), ("--policy-timeout", "10")] {
            runs.push((ed.clone(), flag, vec![], sane, &[0, 2]));
        }
    }
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if data.join("kitti/poses/00.txt").is_file() {
        // Every flag's own default left out of the base (a flag given twice is a usage error).
        let base = [
            ("--sources", "kitti"),
            ("--kitti-windows", "1"),
            ("--kitti-window-s", "5"),
            ("--perturbations", "none"),
            ("--behaviors", "sudden_braking"),
            ("--t0", "2"),
            ("--refine-rounds", "0"),
        ];
        for (flag, sane) in [
            ("--seed", "1"),
            ("--kitti-windows", "1"),
            ("--kitti-window-s", "5"),
            ("--refine-rounds", "0"),
            ("--t0", "2"),
            ("--horizon", "5"),
        ] {
            let mut bc = vec!["bench-cases", "--data", s(&data), "--out", &o_bc, "--force"];
            bc.extend(base.iter().filter(|(f, _)| *f != flag).flat_map(|(f, v)| [*f, *v]));
            runs.push((bc, flag, vec![], sane, &[0, 2]));
        }
    } else {
        cli_support::fuzz_log(&format!("SKIP: fuzz numeric-args of bench-cases: {} absent", data.display()));
    }
    let mut n = 0;
    for (before, flag, after, sane, allowed) in &runs {
        // The command itself is right: with a sane value it succeeds (so a refusal below is the
        // value's, not a usage error).
        let args: Vec<&str> = before.iter().copied().chain([*flag, sane]).chain(after.iter().copied()).collect();
        // `reason` may find no case with that value (3); 2 would be a usage error.
        let code = exit_code(&args);
        assert!(matches!(code, Some(0)) || (allowed.contains(&3) && code == Some(3)), "carla-gs {args:?}: {code:?}");
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
    cli_support::fuzz_log(&format!("fuzz numeric-args: {n} cases"));
}
