//! A batch plan run on a local Ray instance (2 CPUs) by `tools/batch_ray.py`: the two shared
//! WOMD scenes and PandaSet 002's tracks (ingested by the plan, when present) and a small
//! synthetic scene, `eval-cases` in 4 shards merged by the plan's `tables` node. The merged
//! tables are byte-identical to one `eval-cases` process over the same scenes; one shard made
//! to crash on its first try (a wrapper that kills itself) is retried and changes nothing; a
//! second run of the plan skips every node. Skips with a printed reason without Ray
//! (tools/setup.sh installs it into `$XDG_CACHE_HOME/carla-gs/ray-venv`).

use std::path::{Path, PathBuf};
use std::process::Command;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_carla-gs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn carla_gs(args: &[&str]) {
    let out = Command::new(bin()).args(args).output().expect("run carla-gs");
    assert!(out.status.success(), "carla-gs {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

/// The Python of the Ray virtual environment set-up installs (or `CARLA_GS_RAY_PYTHON`).
fn ray_python() -> Option<PathBuf> {
    let p = match std::env::var_os("CARLA_GS_RAY_PYTHON") {
        Some(p) => PathBuf::from(p),
        None => {
            let cache = std::env::var_os("XDG_CACHE_HOME")
                .map(PathBuf::from)
                .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
            cache.join("carla-gs/ray-venv/bin/python")
        }
    };
    let ok = Command::new(&p).args(["-c", "import ray"]).output().is_ok_and(|o| o.status.success());
    ok.then_some(p)
}

fn driver() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/batch_ray.py")
}

const TABLES: [&str; 7] =
    ["table1.md", "table1.csv", "table1_paired.md", "table1_paired.csv", "why_no_plan.md", "table2.md", "table2.csv"];

#[test]
fn ray_runs_a_sharded_plan_into_the_tables_of_one_process() {
    let Some(python) = ray_python() else {
        println!("SKIP: no Python with Ray (tools/setup.sh installs it into $XDG_CACHE_HOME/carla-gs/ray-venv)");
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    let synth = t.join("synth");
    carla_gs(&["synth", "--out", s(&synth), "--frames", "60", "--cameras", "1", "--width", "96", "--height", "64"]);
    let mut manifest = String::new();
    for (name, rel) in [
        ("womd-a", "waymo/womd_scenario_input.tfrecord"),
        ("womd-b", "waymo/motion_data_one_scenario.tfrecord"),
        ("pandaset-002", "pandaset/002"),
    ] {
        match ingest::shared::data_path(rel) {
            Some(p) => manifest += &format!("[[log]]\nname = \"{name}\"\ninput = \"{}\"\n\n", p.display()),
            None => println!("SKIP part: ../shared/data/{rel} is absent; the plan runs without it"),
        }
    }
    manifest += "[[log]]\nname = \"synth\"\nscene = \"synth\"\n\n";
    let eval =
        ["--agents", "planner,rule", "--behaviors", "sudden_braking,sudden_cut_in,opposing_drift", "--t0", "2,4"];
    manifest += &format!(
        "[eval_cases]\nagents = \"{}\"\nbehaviors = \"{}\"\nt0 = \"{}\"\nshards = 4\nargs = [\"--no-plots\"]\n",
        eval[1], eval[3], eval[5]
    );
    std::fs::write(t.join("manifest.toml"), manifest).unwrap();
    let out = t.join("out");
    carla_gs(&["batch", "plan", s(&t.join("manifest.toml")), "--out", s(&out)]);
    let plan = out.join("plan.json");

    // The binary behind a wrapper that kills itself the first time it is asked for shard 1.
    let marker = t.join("crashed-once");
    let wrapper = t.join("carla-gs-crashing");
    std::fs::write(
        &wrapper,
        format!(
            "#!/bin/sh\ncase \"$*\" in *eval_cases/1-of-4*) if [ ! -e {m} ]; then touch {m}; kill -KILL $$; fi;; esac\nexec {b} \"$@\"\n",
            m = marker.display(),
            b = bin()
        ),
    )
    .unwrap();
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&wrapper, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    let run_driver = || {
        let o = Command::new(&python)
            .arg(driver())
            .args([s(&plan), "--binary", s(&wrapper), "--num-cpus", "2", "--retries", "2"])
            .env("RAY_ADDRESS", "")
            .output()
            .expect("run the Ray driver");
        let text = format!("{}\n{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr));
        assert!(o.status.success(), "driver failed:\n{text}");
        let summary: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join(".batch/ray-summary.json")).unwrap()).unwrap();
        (text, summary)
    };
    let (text, summary) = run_driver();
    assert!(marker.exists(), "the wrapper never crashed shard 1:\n{text}");
    let outcomes: Vec<(String, String)> = summary["nodes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|n| (n["id"].as_str().unwrap().to_string(), n["outcome"].as_str().unwrap().to_string()))
        .collect();
    assert!(outcomes.iter().all(|(_, o)| o == "ran"), "{outcomes:?}");
    assert_eq!(outcomes.iter().filter(|(id, _)| id.starts_with("eval_cases/")).count(), 4);

    // One process over the same scenes, given in another order.
    let scenes_dir = out.join("scenes");
    let mut args: Vec<String> = vec!["eval-cases".into(), s(&synth).into()];
    let mut ingested: Vec<PathBuf> =
        std::fs::read_dir(&scenes_dir).map(|r| r.map(|e| e.unwrap().path()).collect()).unwrap_or_default();
    ingested.sort();
    ingested.reverse();
    args.extend(ingested.iter().map(|p| s(p).to_string()));
    args.extend(eval.iter().map(|x| x.to_string()));
    let single = t.join("single");
    args.extend(["--no-plots".into(), "--out".into(), s(&single).into()]);
    carla_gs(&args.iter().map(String::as_str).collect::<Vec<_>>());
    for f in TABLES {
        let a = std::fs::read(single.join(f)).unwrap();
        let b = std::fs::read(out.join("tables").join(f)).unwrap();
        assert!(a == b, "{f} differs between one process and the merged shards");
    }

    // Idempotent: a second run skips every node and leaves the tables as they are.
    let before = std::fs::read(out.join("tables/table1.md")).unwrap();
    let (_, again) = run_driver();
    let skipped = again["nodes"].as_array().unwrap().iter().filter(|n| n["outcome"] == "skipped").count();
    assert_eq!(skipped, outcomes.len(), "{again}");
    assert_eq!(before, std::fs::read(out.join("tables/table1.md")).unwrap());
}

/// The `--slurm` output: one array job per stage, chained with afterok, valid shell.
#[test]
fn slurm_script_has_one_array_job_per_stage() {
    let tmp = tempfile::tempdir().unwrap();
    let t = tmp.path();
    std::fs::write(
        t.join("m.toml"),
        "[[log]]\nname = \"a\"\ninput = \"a.tfrecord\"\n[[log]]\nname = \"b\"\nscene = \"b\"\n\
         [train]\ndevice = \"cuda\"\n[eval_cases]\nshards = 3\n",
    )
    .unwrap();
    // `batch plan` refuses inputs that do not exist (issue 56): stand-ins, never read here.
    std::fs::write(t.join("a.tfrecord"), b"").unwrap();
    std::fs::create_dir(t.join("b")).unwrap();
    carla_gs(&["batch", "plan", s(&t.join("m.toml")), "--out", s(&t.join("out"))]);
    let script = t.join("submit.sh");
    let o = Command::new("python3")
        .arg(driver())
        .args([s(&t.join("out/plan.json")), "--binary", bin(), "--slurm", s(&script)])
        .output();
    let Ok(o) = o else {
        println!("SKIP: no python3");
        return;
    };
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(&script).unwrap();
    assert!(Command::new("bash").arg("-n").arg(&script).status().unwrap().success(), "{text}");
    let jobs: Vec<&str> = text.lines().filter(|l| l.starts_with("JOB_")).collect();
    assert_eq!(jobs.len(), 4, "ingest, train, eval_cases, tables:\n{text}");
    assert!(jobs[0].contains("--array=0-0") && !jobs[0].contains("--dependency"), "{}", jobs[0]);
    assert!(jobs[1].contains("--gres=gpu:1") && jobs[1].contains("afterok:${JOB_INGEST}"), "{}", jobs[1]);
    assert!(jobs[2].contains("--array=0-2") && jobs[2].contains("--stage eval_cases --index $SLURM_ARRAY_TASK_ID"));
    assert!(jobs[3].contains("afterok:${JOB_EVAL_CASES}"), "{}", jobs[3]);
}
