//! Issue 56: a `run` into an existing run directory deleted a person's `videos/*.mp4` (any `.mp4`
//! there was taken for ours), though a run never deletes files it did not write. Now only the
//! files the earlier run recorded in its `run.json` count as ours: anything else under `videos/`
//! or `placement/` is refused (exit 2, naming it) and left as it was; a second run over our own
//! run directory still replaces it.

mod cli_support;
use cli_support::{carla_gs, listing, ok, refused, s};

#[test]
fn a_run_never_deletes_a_persons_videos() {
    let t = tempfile::tempdir().unwrap();
    let (scene, model, out) = (t.path().join("s"), t.path().join("m"), t.path().join("run"));
    let synth = ["synth", "--out", s(&scene), "--frames", "40", "--width", "32", "--height", "24", "--cameras", "1"];
    ok(carla_gs(&synth));
    ok(carla_gs(&["train", s(&scene), "--out", s(&model), "--iters", "2"]));
    let run = || {
        let args = ["run", s(&scene), "--model", s(&model), "--behavior", "sudden_braking", "--out", s(&out)];
        carla_gs(&[&args[..], &["--layouts", "single:FRONT", "--fps", "2", "--scale", "0.5", "--png"]].concat())
    };
    ok(run());
    // Our own run directory is replaced by the next run.
    ok(run());
    for mine in ["videos/holiday.mp4", "videos/compare-FRONT.mp4", "placement/t9.00_FRONT.png"] {
        let p = out.join(mine);
        std::fs::create_dir_all(p.parent().unwrap()).unwrap();
        std::fs::write(&p, b"a person's own video").unwrap();
        let before = listing(t.path());
        refused(run(), &[mine.rsplit('/').next().unwrap(), "not in its run.json"]);
        assert_eq!(listing(t.path()), before, "{mine}");
        std::fs::remove_file(&p).unwrap();
    }
    // A folder of a run's names without run.json (a person's): its videos are not ours either.
    let theirs = t.path().join("theirs");
    std::fs::create_dir_all(theirs.join("videos")).unwrap();
    std::fs::write(theirs.join("videos/front3.mp4"), b"mine").unwrap();
    let before = listing(&theirs);
    let args = ["run", s(&scene), "--model", s(&model), "--behavior", "sudden_braking", "--out", s(&theirs)];
    refused(carla_gs(&args), &["front3.mp4"]);
    assert_eq!(listing(&theirs), before);
}
