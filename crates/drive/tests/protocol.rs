//! The subprocess protocol end to end: the Python example policy (`tools/policy_example.py`,
//! standard library only) drives an episode; a policy that hangs, answers garbage, answers out
//! of range or dies ends the episode with a clear error and nothing written.

mod common;

use common::*;
use drive::cameras::Cameras;
use drive::episode::EpisodeSettings;
use drive::protocol::Subprocess;
use recon::backend::CpuF32;
use scene::Behavior;
use std::path::{Path, PathBuf};
use std::process::Command;

fn python() -> Option<String> {
    let ok = Command::new("python3").arg("--version").output().is_ok_and(|o| o.status.success());
    if !ok {
        println!("SKIP: python3 is not installed");
    }
    ok.then(|| "python3".into())
}

fn example() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/policy_example.py")
}

struct Fixture {
    _tmp: tempfile::TempDir,
    root: PathBuf,
    scene: scene::Scene,
    model: recon::SceneModel,
    executed: scene::Executed,
    settings: EpisodeSettings,
}

fn fixture() -> Fixture {
    let tmp = tempfile::tempdir().unwrap();
    let root = tmp.path().to_path_buf();
    let scene = synth_scene(&root.join("scene"));
    let model = box_model(&scene);
    let executed = case(&scene, Behavior::SuddenBraking).expect("a sudden-braking case");
    let settings = EpisodeSettings { cameras: front3(&scene), scale: 1.0, ..Default::default() };
    Fixture { _tmp: tmp, root, scene, model, executed, settings }
}

fn drive_with(f: &Fixture, policy: &mut Subprocess, out: &Path) -> Result<drive::EpisodeFile, drive::DriveError> {
    let cams = Cameras::new(&CpuF32, &f.model, &f.scene, &f.settings.cameras, f.settings.scale).unwrap();
    let req = drive::Request {
        scene: &f.scene,
        executed: &f.executed,
        settings: &f.settings,
        case: drive::output::case_info(&f.executed, None),
        policy_command: Some("test".into()),
        draw: Some((&cams, "cpu-f32".into())),
        video: true,
        png_only: true,
        out,
        force: false,
    };
    drive::drive(&req, policy)
}

/// Nothing of an episode at `out` or beside it (no staging directory left over).
fn nothing_written(out: &Path) {
    assert!(!out.exists(), "{} was written", out.display());
    let name = out.file_name().unwrap().to_string_lossy().into_owned();
    let left: Vec<String> = std::fs::read_dir(out.parent().unwrap())
        .unwrap()
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains(&name))
        .collect();
    assert!(left.is_empty(), "left beside --out: {left:?}");
}

#[test]
fn the_python_example_drives_an_episode() {
    let Some(py) = python() else { return };
    let f = fixture();
    for gt in [false, true] {
        let mut args = vec![example().display().to_string()];
        if gt {
            args.push("--ground-truth".into());
        }
        let mut policy = Subprocess::spawn(&py, &args, 20.0).unwrap();
        let out = f.root.join(format!("episode-{gt}"));
        let file = drive_with(&f, &mut policy, &out).unwrap();
        assert_eq!(file.policy, if gt { "python-example-gt" } else { "python-example" });
        assert_eq!(file.ground_truth, gt);
        assert!(file.ticks.len() > 10);
        for tick in &file.ticks {
            assert_eq!(tick.images.len(), 3, "tick {}: every camera's PNG was given", tick.tick);
            for img in &tick.images {
                assert!(out.join(img).is_file(), "{img}");
            }
        }
        // Every tick answered a control, but the last when the episode ran to its end.
        assert!(file.ticks[..file.ticks.len() - 1]
            .iter()
            .all(|t| matches!(t.action, Some(drive::action::Action::Control(_)))));
        println!(
            "ground truth {gt}: {} ticks, {}, NCAP {:.2}, policy {:.4} s a tick",
            file.ticks.len(),
            file.scores
                .contact
                .as_ref()
                .map_or("no collision".into(), |c| format!("collision at {:.1} m/s", c.impact_speed)),
            file.scores.ncap_score,
            file.timing.policy_s_mean
        );
    }
}

/// A policy in Python that reads the hello, says it is ready and then does `body` each tick.
fn scripted(py: &str, body: &str, timeout_s: f64) -> Subprocess {
    let script = format!(
        "import sys, json, time\nsys.stdin.readline()\nprint(json.dumps({{'type': 'ready', 'name': 'bad'}}), flush=True)\n\
         for line in sys.stdin:\n    {body}\n"
    );
    Subprocess::spawn(py, &["-c".into(), script], timeout_s).unwrap()
}

#[test]
fn a_policy_that_hangs_or_talks_nonsense_ends_the_episode_with_nothing_written() {
    let Some(py) = python() else { return };
    let f = fixture();
    let cases: [(&str, &str, &str); 5] = [
        ("hangs", "time.sleep(60)", "did not answer within 1 s at tick 0"),
        ("garbage", "print('hello there', flush=True)", "answered nonsense at tick 0"),
        (
            "unknown field",
            "print(json.dumps({'control': {'steer': 0, 'throttle': 0, 'brake': 0, 'horn': 1}}), flush=True)",
            "unknown field `horn`",
        ),
        (
            "out of range",
            "print(json.dumps({'control': {'steer': 0, 'throttle': 3.0, 'brake': 0}}), flush=True)",
            "`control.throttle` must be from 0 to 1, got 3",
        ),
        ("dies", "sys.stderr.write('boom\\n'); sys.exit(3)", "the policy ended (exit status: 3) at tick 0"),
    ];
    for (what, body, expected) in cases {
        let mut policy = scripted(&py, body, 1.0);
        let out = f.root.join(format!("episode-{}", what.replace(' ', "-")));
        let clock = std::time::Instant::now();
        let err = drive_with(&f, &mut policy, &out).expect_err(what).to_string();
        println!("{what}: {err} ({:.1} s)", clock.elapsed().as_secs_f64());
        assert!(err.contains(expected), "{what}: `{err}` does not say `{expected}`");
        if what == "dies" {
            assert!(err.contains("boom"), "the policy's stderr is quoted: {err}");
        }
        assert!(clock.elapsed().as_secs_f64() < 30.0, "{what} took too long to be stopped");
        nothing_written(&out);
    }
    // A policy that cannot start at all.
    let err = Subprocess::spawn("/nonexistent/policy", &[], 1.0).err().expect("no such program").to_string();
    assert!(err.contains("cannot start the policy"), "{err}");
}
