//! Hostile inputs to the scene readers (fuzz findings): a `scene.json` that is a link to an
//! endless device, a FIFO, a directory or a file over its budget is refused quickly, naming the
//! file, instead of being read until the memory runs out. Files over a budget are sparse (no disk
//! is used), so the tests also show that nothing is read before the size is checked.

use scene::format::{find_scene_dirs, load_scene, read_json, read_lidar, SCENE_FILE};
use scene::input::{
    read_capped, MAX_EXECUTED_BYTES, MAX_LIDAR_BYTES, MAX_LIDAR_POINTS, MAX_PLAN_BYTES, MAX_SCENE_JSON_BYTES,
};
use scene::{Ego, EgoSizeSource, Frame, LidarRef, Scene, SceneError, Source, SourceKind, Transform3, SCENE_FORMAT};
use std::path::Path;
use std::time::{Duration, Instant};

/// A file of `len` bytes that takes no disk (a hole).
fn sparse(path: &Path, len: u64) {
    std::fs::File::create(path).unwrap().set_len(len).unwrap();
}

fn refused<T: std::fmt::Debug>(r: Result<T, SceneError>, needles: &[&str]) -> SceneError {
    let e = r.unwrap_err();
    let text = e.to_string();
    for n in needles {
        assert!(text.contains(n), "`{n}` not in: {text}");
    }
    e
}

fn one_frame_scene(lidar: Option<LidarRef>) -> Scene {
    Scene {
        format: SCENE_FORMAT.into(),
        name: "s".into(),
        source: Source { kind: SourceKind::Synthetic, files: vec![], id: "s".into() },
        ego: Ego { size_lwh: [4.5, 2.0, 1.8], size_source: EgoSizeSource::Default, track_id: None },
        cameras: vec![],
        frames: vec![Frame { index: 0, timestamp_s: 0.0, world_from_ego: Transform3::IDENTITY, images: vec![], lidar }],
        tracks: vec![],
        map: None,
    }
}

#[test]
fn a_scene_json_linked_to_an_endless_device_is_refused_quickly() {
    let tmp = tempfile::tempdir().unwrap();
    for dev in ["/dev/zero", "/dev/urandom"] {
        let dir = tmp.path().join(&dev[5..]);
        std::fs::create_dir(&dir).unwrap();
        std::os::unix::fs::symlink(dev, dir.join(SCENE_FILE)).unwrap();
        let start = Instant::now();
        refused(load_scene(&dir), &["scene.json: is a character device; expected a regular file"]);
        assert!(start.elapsed() < Duration::from_secs(5));
        // `inspect` and `eval-cases` find it as a scene (and loading it names the problem).
        assert_eq!(find_scene_dirs(&dir).unwrap(), vec![dir.clone()]);
        assert_eq!(find_scene_dirs(tmp.path()).unwrap().len(), if dev == "/dev/zero" { 1 } else { 2 });
    }
}

#[test]
fn a_scene_json_that_is_a_directory_or_fifo_is_named() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::create_dir(tmp.path().join(SCENE_FILE)).unwrap();
    refused(load_scene(tmp.path()), &["scene.json: is a directory; expected a regular file"]);
    let fifo = tempfile::tempdir().unwrap();
    let made = std::process::Command::new("mkfifo").arg(fifo.path().join(SCENE_FILE)).status();
    if made.is_ok_and(|s| s.success()) {
        refused(load_scene(fifo.path()), &["scene.json: is a FIFO (named pipe); expected a regular file"]);
    } else {
        eprintln!("SKIP (FIFO part): mkfifo is not available");
    }
}

#[test]
fn a_scene_json_over_its_budget_is_refused_before_reading() {
    let tmp = tempfile::tempdir().unwrap();
    sparse(&tmp.path().join(SCENE_FILE), MAX_SCENE_JSON_BYTES + 1);
    let start = Instant::now();
    refused(
        load_scene(tmp.path()),
        &["scene.json: 1073741825 bytes, more than the 1073741824 bytes a scene.json may have"],
    );
    assert!(start.elapsed() < Duration::from_secs(2), "the file was read: {:?}", start.elapsed());
}

#[test]
fn a_file_that_reads_longer_than_its_size_stops_at_the_budget() {
    // /proc files say 0 bytes and hold more: the size check passes, the bounded read does not.
    let maps = Path::new("/proc/self/maps");
    if !maps.exists() {
        eprintln!("SKIP: no /proc");
        return;
    }
    refused(read_capped(maps, 16, "a test file"), &["maps: more than 16 bytes (it grew while being read)"]);
}

#[test]
fn plans_executed_files_and_other_json_have_their_budgets() {
    let tmp = tempfile::tempdir().unwrap();
    let plan = tmp.path().join("plan.json");
    sparse(&plan, MAX_PLAN_BYTES + 1);
    refused(scene::plan::load_plan(&plan), &["plan.json: 67108865 bytes", "a plan file may have"]);
    let executed = tmp.path().join("executed.json");
    sparse(&executed, MAX_EXECUTED_BYTES + 1);
    refused(scene::executed::load_executed(&executed), &["executed.json: 536870913 bytes", "an executed file"]);
    let zero = tmp.path().join("config.json");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    refused(read_json::<serde_json::Value>(&zero), &["config.json: is a character device"]);
    // Within its budget a file still parses, with the field named on error.
    std::fs::write(&plan, br#"{"format": 3}"#).unwrap();
    refused(scene::plan::load_plan(&plan), &["plan.json: at `format`"]);
}

#[test]
fn lidar_sweeps_have_a_budget() {
    let tmp = tempfile::tempdir().unwrap();
    let bin = tmp.path().join("000000.bin");
    sparse(&bin, MAX_LIDAR_BYTES + 16);
    refused(read_lidar(&bin), &["000000.bin: 268435472 bytes", "a LiDAR sweep may have"]);
    std::fs::remove_file(&bin).unwrap();
    std::os::unix::fs::symlink("/dev/zero", &bin).unwrap();
    refused(read_lidar(&bin), &["000000.bin: is a character device"]);
    std::fs::remove_file(&bin).unwrap();
    scene::format::write_lidar(&bin, &[[1.0, 2.0, 3.0, 0.5]]).unwrap();
    assert_eq!(read_lidar(&bin).unwrap(), vec![[1.0, 2.0, 3.0, 0.5]]);
}

#[test]
fn a_scene_naming_a_sweep_over_the_budget_or_a_device_is_refused_when_loaded() {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::create_dir(tmp.path().join("lidar")).unwrap();
    let write = |s: &Scene| std::fs::write(tmp.path().join(SCENE_FILE), serde_json::to_vec(s).unwrap()).unwrap();
    let n = MAX_LIDAR_POINTS + 1;
    write(&one_frame_scene(Some(LidarRef { path: "lidar/000000.bin".into(), points: n })));
    sparse(&tmp.path().join("lidar/000000.bin"), 16 * n as u64);
    refused(load_scene(tmp.path()), &["frames[0].lidar.points", "more than the 16777216 a sweep may have"]);
    std::fs::remove_file(tmp.path().join("lidar/000000.bin")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", tmp.path().join("lidar/000000.bin")).unwrap();
    write(&one_frame_scene(Some(LidarRef { path: "lidar/000000.bin".into(), points: 1 })));
    refused(load_scene(tmp.path()), &["frames[0].lidar.path", "`lidar/000000.bin` is a character device"]);
    write(&one_frame_scene(None));
    load_scene(tmp.path()).unwrap();
}
