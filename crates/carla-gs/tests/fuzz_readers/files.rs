//! Fuzz targets over the project's own files: scene.json, plan, executed (and its metrics),
//! PLY, checkpoint, training config TOML, OpenDRIVE and OpenSCENARIO. The scene, plan and
//! executed file come from `carla-gs synth`, `reason` and `simulate` on a small street.

use super::{clean, fuzz};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

struct Fixture {
    scene: PathBuf,
    plan: PathBuf,
    executed: PathBuf,
}

fn carla_gs(args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs");
    assert!(out.status.success(), "carla-gs {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

/// A 40-frame street with one 32x24 camera, its planner plan and its executed file, made afresh
/// by each run of this test binary in cargo's scratch folder for it (`CARGO_TARGET_TMPDIR`):
/// a static is never dropped, so a `TempDir` here left 41 MB in /tmp behind every run.
fn fixture() -> &'static Fixture {
    static F: OnceLock<Fixture> = OnceLock::new();
    F.get_or_init(|| {
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("fuzz-readers-fixture");
        if dir.exists() {
            std::fs::remove_dir_all(&dir).unwrap();
        }
        std::fs::create_dir_all(&dir).unwrap();
        let (scene, plan, executed) = (dir.join("s"), dir.join("plan.json"), dir.join("ex.json"));
        let s = |p: &Path| p.to_str().unwrap().to_string();
        carla_gs(&[
            "synth",
            "--out",
            &s(&scene),
            "--frames",
            "40",
            "--width",
            "32",
            "--height",
            "24",
            "--cameras",
            "1",
        ]);
        carla_gs(&["reason", &s(&scene), "--t0", "1", "--behavior", "sudden_cut_in", "--out", &s(&plan)]);
        carla_gs(&["simulate", &s(&plan), "--scene", &s(&scene), "--out", &s(&executed)]);
        Fixture { scene, plan, executed }
    })
}

/// The fixture's scene folder (for the targets of other modules).
pub fn fixture_scene() -> PathBuf {
    fixture().scene.clone()
}

/// Writes `bytes` to `dir/name` and returns the path.
fn put(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn text(b: &[u8]) -> Result<&str, String> {
    std::str::from_utf8(b).map_err(|e| e.to_string())
}

#[test]
fn fuzz_scene_json() {
    let f = fixture();
    let file = f.scene.join("scene.json");
    fuzz("scene.json", &std::fs::read(&file).unwrap(), true, |b| {
        let scene = scene::format::parse_scene_json(&file, text(b)?).map_err(|e| e.to_string())?;
        scene::validate::validate_scene(&scene, Some(&f.scene)).map_err(|(field, m)| format!("{field}: {m}"))
    });
}

/// A LiDAR point count whose byte size overflows is refused, naming the field: a fuzz case
/// (the count replaced by 2^63) found `points * 16` overflowing in the scene's validation.
#[test]
fn a_huge_lidar_point_count_is_refused() {
    let f = fixture();
    let file = f.scene.join("scene.json");
    let mut scene = scene::format::parse_scene_json(&file, &std::fs::read_to_string(&file).unwrap()).unwrap();
    let k = scene.frames.iter().position(|fr| fr.lidar.is_some()).expect("the fixture has LiDAR");
    for points in [usize::MAX, 1 << 60, (1 << 63) + 1] {
        scene.frames[k].lidar.as_mut().unwrap().points = points;
        let (field, _) = scene::validate::validate_scene(&scene, Some(&f.scene)).unwrap_err();
        assert_eq!(field, format!("frames[{k}].lidar.points"), "{points} points");
    }
}

#[test]
fn fuzz_plan() {
    let tmp = tempfile::tempdir().unwrap();
    fuzz("plan", &std::fs::read(&fixture().plan).unwrap(), true, |b| {
        clean(scene::plan::load_plan(&put(tmp.path(), "plan.json", b)))
    });
}

#[test]
fn fuzz_executed_and_metrics() {
    let tmp = tempfile::tempdir().unwrap();
    fuzz("executed+metrics", &std::fs::read(&fixture().executed).unwrap(), true, |b| {
        let e = scene::executed::load_executed(&put(tmp.path(), "executed.json", b)).map_err(|e| e.to_string())?;
        clean(metrics::evaluate(&e))
    });
}

#[test]
fn fuzz_ply() {
    let tmp = tempfile::tempdir().unwrap();
    let cam = splat::Camera::at_origin(8, 8, 8.0);
    let p = tmp.path().join("base.ply");
    splat::ply::write_ply(&p, &splat::random::random_gaussians(20, &cam, 1, 3)).unwrap();
    fuzz("ply", &std::fs::read(&p).unwrap(), false, |b| clean(splat::ply::read_ply(&put(tmp.path(), "g.ply", b))));
}

#[test]
fn fuzz_checkpoint() {
    use recon::checkpoint::{load_run, save, RunIdentity, TrainState};
    use recon::densify::Stats;
    let tmp = tempfile::tempdir().unwrap();
    let cam = splat::Camera::at_origin(8, 8, 8.0);
    let model = recon::SceneModel {
        antialiased: false,
        background: splat::random::random_gaussians(7, &cam, 1, 1),
        actors: vec![recon::model::Actor {
            track_id: "car-1".into(),
            size_lwh: [4.0, 2.0, 1.5],
            gaussians: splat::random::random_gaussians(3, &cam, 1, 2),
        }],
        sky: recon::sky::Sky::new(2, [0.3, 0.4, 0.5]),
    };
    let adam = recon::optim::AdamState::new(&model);
    let stats = model
        .sets()
        .map(|g| Stats { grad_sum: vec![0.5; g.len()], seen: vec![3; g.len()], max_radius: vec![2.0; g.len()] })
        .collect();
    let st = TrainState { next_iteration: 5, model, adam, stats, smoothing: vec![] };
    let run =
        RunIdentity { scene_name: "s".into(), scene_fingerprint: "0a0b".into(), config_fingerprint: "0102".into() };
    let p = tmp.path().join("base.bin");
    save(&p, &st, &run).unwrap();
    fuzz("checkpoint", &std::fs::read(&p).unwrap(), false, |b| clean(load_run(&put(tmp.path(), "c.bin", b))));
}

#[test]
fn fuzz_config_toml() {
    let base = include_str!("../../../../configs/real-street-gpu.toml");
    fuzz("config.toml", base.as_bytes(), true, |b| recon::TrainConfig::from_toml(text(b)?).map(|_| ()));
}

#[test]
fn fuzz_xodr_and_xosc() {
    let f = fixture();
    let scene = scene::format::load_scene(&f.scene).unwrap();
    let executed = scene::executed::load_executed(&f.executed).unwrap();
    let net = export::build_road_network(&scene, &export::XodrOptions::default()).unwrap().network;
    let xodr = export::write_xodr(&net).unwrap();
    let opts = export::XoscOptions { date: Some("2025-01-31T12:00:00Z".into()), ..Default::default() };
    let xosc = export::write_xosc(&scene, &executed, &opts).unwrap();
    fuzz("xodr", xodr.as_bytes(), true, |b| clean(export::read_xodr(text(b)?)));
    fuzz("xosc", xosc.as_bytes(), true, |b| clean(export::read_xosc(text(b)?)));
}
