//! KITTI odometry and `transforms.json` folders built to break ingest, as `pandaset_hostile.rs`
//! does for PandaSet: a FIFO, device, directory, looping or dangling link or unreadable file in
//! place of an input file, files past their size caps and implausible intrinsics. Each must be
//! refused naming the input file (and field), quickly, with nothing left behind; the hand-made
//! folders themselves convert.

mod common;

use common::{mkfifo, permissions_ignored, refused_at, run, symlink, within};
use ingest::Expect;
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// KITTI-like images: 40x30 grey PNGs.
const W: u32 = 40;
const H: u32 = 30;

/// `calib.txt` with `fx = fy`, `cx`, `cy` and a 0.5 m baseline.
fn calib(fx: f64, cx: f64, cy: f64) -> String {
    let p = |tx: f64| format!("{fx:e} 0 {cx:e} {tx:e} 0 {fx:e} {cy:e} 0 0 0 1 0");
    format!("P0: {}\nP1: {}\n", p(0.0), p(-0.5 * fx))
}

/// A tiny KITTI odometry folder `dir/seq`: 3 stereo pairs 0.2 s apart, driving 1 m a frame.
fn kitti_tiny(dir: &Path) -> PathBuf {
    let root = dir.join("seq");
    for cam in ["image_0", "image_1"] {
        std::fs::create_dir_all(root.join(cam)).unwrap();
        for k in 0..3 {
            image::GrayImage::from_pixel(W, H, image::Luma([80])).save(root.join(format!("{cam}/{k:06}.png"))).unwrap();
        }
    }
    std::fs::write(root.join("calib.txt"), calib(30.0, 20.0, 15.0)).unwrap();
    let poses: String = (0..3).map(|k| format!("1 0 0 0 0 1 0 0 0 0 1 {k}\n")).collect();
    std::fs::write(root.join("poses.txt"), poses).unwrap();
    std::fs::write(root.join("times.txt"), "0.0\n0.2\n0.4\n").unwrap();
    root
}

/// A tiny `transforms.json` set `dir/seq`: 3 frames of 40x30 PNGs named without extension.
fn nerf_tiny(dir: &Path) -> PathBuf {
    let root = dir.join("seq");
    std::fs::create_dir_all(root.join("train")).unwrap();
    for k in 0..3 {
        image::RgbImage::from_pixel(W, H, image::Rgb([10, 20, 30]))
            .save(root.join(format!("train/r_{k}.png")))
            .unwrap();
    }
    let pose = json!([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 4], [0, 0, 0, 1]]);
    let frames: Vec<Value> =
        (0..3).map(|k| json!({"file_path": format!("./train/r_{k}"), "transform_matrix": pose})).collect();
    common::write_json(&root.join("transforms.json"), &json!({"fl_x": 30.0, "fl_y": 30.0, "frames": frames}));
    root
}

/// Runs a broken copy of the folder `make` builds (edited by `edit`) and checks the error names
/// every one of `what` and nothing was left behind, within 20 s (a FIFO must not block).
fn refused(make: fn(&Path) -> PathBuf, edit: impl FnOnce(&Path), what: &[&str]) -> String {
    let tmp = tempfile::tempdir().unwrap();
    let src = make(tmp.path());
    edit(&src);
    let what: Vec<String> = what.iter().map(|s| s.to_string()).collect();
    let label = what.join(" / ");
    within(20, &label, move || {
        let what: Vec<&str> = what.iter().map(String::as_str).collect();
        refused_at(tmp.path(), &src, &what)
    })
}

fn replace_with_dir(p: &Path) {
    std::fs::remove_file(p).unwrap();
    std::fs::create_dir(p).unwrap();
}

fn grow(p: &Path, len: u64) {
    std::fs::OpenOptions::new().write(true).open(p).unwrap().set_len(len).unwrap();
}

#[test]
fn the_tiny_folders_convert() {
    let tmp = tempfile::tempdir().unwrap();
    let s = run(&kitti_tiny(tmp.path()), &tmp.path().join("k"), Expect::Auto).unwrap();
    assert_eq!((s.frames.len(), s.cameras.len()), (3, 2));
    assert_eq!((s.cameras[0].width, s.cameras[0].height), (W, H));
    let tmp = tempfile::tempdir().unwrap();
    let s = run(&nerf_tiny(tmp.path()), &tmp.path().join("n"), Expect::Auto).unwrap();
    assert_eq!((s.frames.len(), s.cameras.len()), (3, 1));
    assert_eq!(s.cameras[0].intrinsics.fx, 30.0);
}

#[test]
fn kitti_non_files_are_refused_not_waited_on() {
    for rel in ["calib.txt", "poses.txt", "times.txt", "image_0/000001.png", "image_1/000000.png", "image_1/000002.png"]
    {
        refused(kitti_tiny, |d| mkfifo(&d.join(rel)), &[rel, "FIFO (named pipe); expected a regular file"]);
    }
    refused(kitti_tiny, |d| replace_with_dir(&d.join("times.txt")), &["times.txt", "is a directory"]);
    refused(kitti_tiny, |d| replace_with_dir(&d.join("image_0/000002.png")), &["image_0/000002.png", "directory"]);
    refused(
        kitti_tiny,
        |d| symlink("nowhere.txt", &d.join("poses.txt")),
        &["poses.txt", "nowhere.txt", "does not exist"],
    );
    refused(kitti_tiny, |d| symlink("calib.txt", &d.join("calib.txt")), &["calib.txt", "symbolic links"]);
    refused(
        kitti_tiny,
        |d| symlink("/dev/zero", &d.join("image_1/000001.png")),
        &["image_1/000001.png", "character device"],
    );
    refused(kitti_tiny, |d| symlink("/dev/zero", &d.join("times.txt")), &["times.txt", "character device"]);
    // Absent is still absent (not a FIFO error, not a hang).
    refused(kitti_tiny, |d| std::fs::remove_file(d.join("times.txt")).unwrap(), &["times.txt", "No such file"]);
    let tmp = tempfile::tempdir().unwrap();
    if permissions_ignored(tmp.path()) {
        eprintln!("SKIP: unreadable-file cases: this process reads files of mode 000 (root)");
        return;
    }
    for rel in ["calib.txt", "image_1/000001.png"] {
        refused(
            kitti_tiny,
            |d| std::fs::set_permissions(d.join(rel), std::os::unix::fs::PermissionsExt::from_mode(0o000)).unwrap(),
            &[rel, "Permission denied"],
        );
    }
}

#[test]
fn kitti_files_past_their_size_caps_are_refused_from_their_size() {
    refused(kitti_tiny, |d| grow(&d.join("times.txt"), (64 << 20) + 1), &["times.txt", "67108865 bytes", "67108864"]);
    refused(
        kitti_tiny,
        |d| grow(&d.join("image_1/000002.png"), (64 << 20) + 1),
        &["image_1/000002.png", "67108865 bytes", "an image"],
    );
}

#[test]
fn kitti_implausible_intrinsics_are_refused() {
    // 40x30 images: fx within [0.4, 40000], cx within [-40, 80], cy within [-30, 60].
    let with = |fx, cx, cy| move |d: &Path| std::fs::write(d.join("calib.txt"), calib(fx, cx, cy)).unwrap();
    refused(kitti_tiny, with(1e-300, 20.0, 15.0), &["calib.txt: line 1", "P0[0][0]", "fx = 1e-300", "[0.4, 40000.0]"]);
    refused(kitti_tiny, with(4e4 + 1.0, 20.0, 15.0), &["calib.txt: line 1", "P0[0][0]", "40001.0"]);
    refused(kitti_tiny, with(30.0, -900000.0, 15.0), &["calib.txt", "P0[0][2]", "cx = -900000.0", "[-40.0, 80.0]"]);
    refused(kitti_tiny, with(30.0, 20.0, 61.0), &["calib.txt", "P0[1][2]", "cy = 61.0", "[-30.0, 60.0]"]);
}

#[test]
fn transforms_json_non_files_are_refused_not_waited_on() {
    for rel in ["transforms.json", "train/r_1.png"] {
        refused(nerf_tiny, |d| mkfifo(&d.join(rel)), &[rel, "FIFO (named pipe); expected a regular file"]);
    }
    refused(nerf_tiny, |d| replace_with_dir(&d.join("train/r_0.png")), &["train/r_0.png", "is a directory"]);
    refused(nerf_tiny, |d| symlink("gone.png", &d.join("train/r_2.png")), &["train/r_2.png", "gone.png"]);
    refused(nerf_tiny, |d| symlink("r_1.png", &d.join("train/r_1.png")), &["train/r_1.png", "symbolic links"]);
    refused(nerf_tiny, |d| symlink("/dev/zero", &d.join("transforms.json")), &["transforms.json", "character device"]);
    refused(nerf_tiny, |d| symlink("/dev/zero", &d.join("train/r_0.png")), &["train/r_0.png", "character device"]);
    // A truly missing image is still "missing", naming the frame.
    refused(
        nerf_tiny,
        |d| std::fs::remove_file(d.join("train/r_1.png")).unwrap(),
        &["train/r_1: missing", "frames[1].file_path"],
    );
    let tmp = tempfile::tempdir().unwrap();
    if permissions_ignored(tmp.path()) {
        eprintln!("SKIP: unreadable-file cases: this process reads files of mode 000 (root)");
        return;
    }
    for rel in ["transforms.json", "train/r_1.png"] {
        refused(
            nerf_tiny,
            |d| std::fs::set_permissions(d.join(rel), std::os::unix::fs::PermissionsExt::from_mode(0o000)).unwrap(),
            &[rel, "Permission denied"],
        );
    }
}

#[test]
fn transforms_json_files_past_their_size_caps_are_refused_from_their_size() {
    refused(
        nerf_tiny,
        |d| grow(&d.join("transforms.json"), (64 << 20) + 1),
        &["transforms.json", "67108865 bytes", "67108864"],
    );
    refused(nerf_tiny, |d| grow(&d.join("train/r_1.png"), (64 << 20) + 1), &["train/r_1.png", "67108865 bytes"]);
}

#[test]
fn transforms_json_implausible_intrinsics_are_refused_naming_the_key() {
    let edit = |f: fn(&mut Value)| {
        move |d: &Path| {
            let p = d.join("transforms.json");
            let mut v: Value = serde_json::from_slice(&std::fs::read(&p).unwrap()).unwrap();
            f(&mut v);
            common::write_json(&p, &v);
        }
    };
    // 40x30 images: fx, fy within [0.4, 40000], cx within [-40, 80], cy within [-30, 60].
    refused(
        nerf_tiny,
        edit(|v| v["fl_x"] = json!(1e-300)),
        &["transforms.json", "`fl_x`", "1e-300", "[0.4, 40000.0]", "40x30"],
    );
    refused(nerf_tiny, edit(|v| v["fl_y"] = json!(1e9)), &["`fl_y`", "1000000000.0"]);
    refused(
        nerf_tiny,
        edit(|v| v["frames"][1]["cx"] = json!(-900000.0)),
        &["`frames[1].cx`", "-900000.0", "[-40.0, 80.0]"],
    );
    refused(nerf_tiny, edit(|v| v["cy"] = json!(61.0)), &["`cy`", "61.0", "[-30.0, 60.0]"]);
    // A field of view of almost 180 degrees gives a focal length of 1e-5 px: named by its angle.
    refused(
        nerf_tiny,
        edit(|v| {
            let o = v.as_object_mut().unwrap();
            o.remove("fl_x");
            o.remove("fl_y");
            o.insert("camera_angle_x".into(), json!(std::f64::consts::PI - 1e-5));
        }),
        &["`camera_angle_x`", "fx = "],
    );
    refused(nerf_tiny, edit(|v| v["fl_x"] = json!(f64::MAX)), &["`fl_x`", "1.7976931348623157e308"]);
}
