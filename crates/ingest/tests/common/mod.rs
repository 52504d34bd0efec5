//! Hand-made PandaSet-like folders and the checks on them, shared by the test files, and the
//! helpers for hostile inputs (FIFOs, links, unreadable folders, a timeout guard).
#![allow(dead_code)] // each test file uses a part

use indicatif::ProgressBar;
use ingest::{Expect, IngestError};
use scene::Scene;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use std::time::Duration;

pub fn run(input: &Path, out: &Path, expect: Expect) -> Result<Scene, IngestError> {
    ingest::ingest(&[input.to_path_buf()], out, expect, false, &ProgressBar::hidden()).map(|mut w| w.remove(0).scene)
}

pub fn write_json(p: &Path, v: &Value) {
    std::fs::write(p, serde_json::to_vec(v).unwrap()).unwrap();
}

/// One cuboid record as PandaSet's converter writes it.
pub fn car(uuid: &str, y: f64) -> Value {
    json!({"uuid": uuid, "label": "Car", "yaw": 0.0, "position.x": 0.0, "position.y": y,
        "position.z": 0.7, "dimensions.x": 1.9, "dimensions.y": 4.5, "dimensions.z": 1.5,
        "attributes.object_motion": "Moving", "cuboids.sibling_id": "-", "cuboids.sensor_id": -1, "camera_used": 1})
}

/// A small PandaSet-like folder: 3 frames, 1 camera of 16x12, one sweep, one moving car.
pub fn tiny(dir: &Path) -> PathBuf {
    tiny_frames(dir, 3)
}

/// [`tiny`] with `n` frames (1 m and 0.1 s apart).
pub fn tiny_frames(dir: &Path, n: usize) -> PathBuf {
    let root = dir.join("seq");
    let cam = root.join("camera/front_camera");
    std::fs::create_dir_all(&cam).unwrap();
    std::fs::create_dir_all(root.join("lidar")).unwrap();
    std::fs::create_dir_all(root.join("annotations/cuboids")).unwrap();
    let pose = |y: f64, q: [f64; 4]| json!({"position": {"x": 0.0, "y": y, "z": 0.0}, "heading": {"w": q[0], "x": q[1], "y": q[2], "z": q[3]}});
    // The LiDAR drives along its +y; the camera looks along +y too (OpenCV z = LiDAR +y).
    let lidar_q = [1.0, 0.0, 0.0, 0.0];
    let s = std::f64::consts::FRAC_1_SQRT_2;
    let cam_q = [s, -s, 0.0, 0.0]; // world_from_cv: cv z -> world +y, cv y -> world -z
    let ks = 0..n;
    write_json(&root.join("lidar/poses.json"), &ks.clone().map(|k| pose(k as f64, lidar_q)).collect());
    write_json(&root.join("lidar/timestamps.json"), &ks.clone().map(|k| json!(100.0 + 0.1 * k as f64)).collect());
    write_json(&cam.join("poses.json"), &ks.clone().map(|k| pose(k as f64, cam_q)).collect());
    write_json(&cam.join("timestamps.json"), &ks.clone().map(|k| json!(99.95 + 0.1 * k as f64)).collect());
    write_json(&cam.join("intrinsics.json"), &json!({"fx": 10.0, "fy": 10.0, "cx": 8.0, "cy": 6.0}));
    for k in ks {
        image::RgbImage::from_pixel(16, 12, image::Rgb([90, 90, 90])).save(cam.join(format!("{k:02}.jpg"))).unwrap();
        write_json(&root.join(format!("annotations/cuboids/{k:02}.json")), &json!([car("a", 10.0 + k as f64)]));
    }
    let mut sweep = Vec::new();
    for i in 0..200 {
        for v in [(i % 20) as f32 * 0.5 - 5.0, (i / 20) as f32, -1.5, 7.0] {
            sweep.extend_from_slice(&v.to_le_bytes());
        }
    }
    std::fs::write(root.join("lidar/00.bin"), sweep).unwrap();
    root
}

/// Runs a broken copy of [`tiny`] and checks the error names `what`, not the staged output, and
/// nothing was written.
pub fn refused(edit: impl FnOnce(&Path), what: &[&str]) -> String {
    let tmp = tempfile::tempdir().unwrap();
    let src = tiny(tmp.path());
    edit(&src);
    refused_at(tmp.path(), &src, what)
}

/// The check of [`refused`] on the folder `src` inside `tmp`.
pub fn refused_at(tmp: &Path, src: &Path, what: &[&str]) -> String {
    let out = tmp.join("out");
    let err = run(src, &out, Expect::Auto).unwrap_err().to_string();
    for w in what {
        assert!(err.contains(w), "`{err}` does not name `{w}`");
    }
    let staged = format!(".out.{}.", std::process::id()); // the staging folder beside `out`
    assert!(!err.contains(&staged), "`{err}` names the staged output, not the input");
    assert!(!out.exists(), "output left behind after: {err}");
    let left: Vec<_> = std::fs::read_dir(tmp).unwrap().filter_map(|e| e.ok()).map(|e| e.file_name()).collect();
    assert_eq!(left, [std::ffi::OsString::from("seq")], "stray files after: {err}");
    err
}

pub fn mkfifo(p: &Path) {
    let _ = std::fs::remove_file(p);
    let ok = std::process::Command::new("mkfifo").arg(p).status().unwrap().success();
    assert!(ok, "mkfifo {}", p.display());
}

pub fn symlink(target: impl AsRef<Path>, link: &Path) {
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(target, link).unwrap();
}

/// Runs `f` on its own thread and fails the test if it has not returned within `secs` (an
/// open of a FIFO nobody writes never returns).
pub fn within<T: Send + 'static>(secs: u64, what: &str, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(Duration::from_secs(secs)).unwrap_or_else(|_| panic!("{what}: ingest still blocked after {secs} s"))
}

/// True when this process can read what `chmod 000` forbids (root): permission tests skip.
pub fn permissions_ignored(dir: &Path) -> bool {
    let probe = dir.join("probe");
    std::fs::create_dir(&probe).unwrap();
    std::fs::set_permissions(&probe, std::os::unix::fs::PermissionsExt::from_mode(0o000)).unwrap();
    let ignored = std::fs::read_dir(&probe).is_ok();
    std::fs::set_permissions(&probe, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    std::fs::remove_dir(&probe).unwrap();
    ignored
}
