//! Folder inputs on the shared real data (KITTI odometry 06, instant-ngp fox) and on broken or
//! small hand-made copies: scene content, frame conventions, stereo geometry, undistortion and
//! errors that name the file and line and leave nothing behind.

use indicatif::ProgressBar;
use ingest::{Expect, IngestError};
use scene::glam::{DVec2, DVec3};
use scene::Scene;
use std::path::{Path, PathBuf};

fn run(input: &Path, out: &Path, expect: Expect) -> Result<Scene, IngestError> {
    ingest::ingest(&[input.to_path_buf()], out, expect, false, &ProgressBar::hidden()).map(|mut w| w.remove(0).scene)
}

fn copy_dir(src: &Path, dst: &Path) {
    std::fs::create_dir_all(dst).unwrap();
    for e in std::fs::read_dir(src).unwrap() {
        let e = e.unwrap();
        let to = dst.join(e.file_name());
        if e.file_type().unwrap().is_dir() {
            copy_dir(&e.path(), &to);
        } else {
            std::fs::copy(e.path(), to).unwrap();
        }
    }
}

fn kitti() -> Option<PathBuf> {
    ingest::shared::data_path("kitti/odometry_06")
}

#[test]
fn kitti_scene_is_z_up_and_travels_60_m() {
    let Some(src) = kitti() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("scene");
    let s = run(&src, &out, Expect::Auto).unwrap();
    assert_eq!(s.source.kind, scene::SourceKind::KittiOdometry);
    assert_eq!(s.cameras.iter().map(|c| c.name.as_str()).collect::<Vec<_>>(), ["LEFT", "RIGHT"]);
    assert_eq!(s.frames.len(), 26);
    assert!(s.tracks.is_empty());
    let d = s.ego_distance_m();
    assert!((55.0..65.0).contains(&d), "ego travelled {d} m");
    // Frame 0: the ego is at the world origin, 1.65 m below the left camera.
    assert!(s.frames[0].world_from_ego.translation().length() < 1e-6);
    // World z is up: the ego drives in the world xy plane (forward = +x), z changes little.
    let last = s.frames.last().unwrap().world_from_ego.translation();
    assert!(last.x > 55.0 && last.y.abs() < 3.0, "end position {last}");
    for f in &s.frames {
        let p = f.world_from_ego.translation();
        assert!(p.z.abs() < 0.05 * p.truncate().length() + 0.05, "frame {}: z = {} m", f.index, p.z);
        // The ego's up axis stays near world up.
        assert!(f.world_from_ego.transform_vector(DVec3::Z).z > 0.99);
    }
    // PNG bytes are copied unchanged.
    let a = std::fs::read(out.join(&s.frames[3].images[1].path)).unwrap();
    assert_eq!(a, std::fs::read(src.join("image_1/000006.png")).unwrap());
    assert!(scene::load_scene(&out).is_ok());
}

#[test]
fn kitti_stereo_triangulation_projects_back() {
    let Some(src) = kitti() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let s = run(&src, &tmp.path().join("scene"), Expect::KittiOdometry).unwrap();
    let (l, r) = (&s.cameras[0], &s.cameras[1]);
    let k = l.intrinsics;
    // calib.txt's own numbers: fx * baseline = -P1[0][3].
    let fx_b = 379.8145;
    for (u, v, disparity) in [(300.5, 250.5, 40.0), (900.25, 120.0, 8.5), (601.0, 300.0, 70.0)] {
        // Rays of the left pixel and of the right pixel with that disparity, in the ego frame.
        let ray = |c: &scene::Camera, u: f64| {
            let cv = DVec3::new((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
            let ego_from_cv = c.cv_from_ego().inverse();
            (ego_from_cv.transform_point(DVec3::ZERO), ego_from_cv.transform_vector(cv))
        };
        let (o1, d1) = ray(l, u);
        let (o2, d2) = ray(r, u - disparity);
        // Midpoint triangulation of the two rays.
        let w = o1 - o2;
        let (a, b, c, d, e) = (d1.dot(d1), d1.dot(d2), d2.dot(d2), d1.dot(w), d2.dot(w));
        let den = a * c - b * b;
        let t1 = (b * e - c * d) / den;
        let t2 = (a * e - b * d) / den;
        let p = 0.5 * (o1 + t1 * d1 + o2 + t2 * d2);
        assert!(((o1 + t1 * d1) - (o2 + t2 * d2)).length() < 1e-9, "rectified rays must intersect");
        // Depth along the optical axis matches KITTI's z = fx b / d ...
        let z = l.cv_from_ego().transform_point(p).z;
        assert!((z - fx_b / disparity).abs() < 1e-3 * z, "depth {z} vs {}", fx_b / disparity);
        // ... and the point projects back onto both pixels.
        assert!((l.project_ego(p).unwrap() - DVec2::new(u, v)).length() < 1e-6);
        assert!((r.project_ego(p).unwrap() - DVec2::new(u - disparity, v)).length() < 1e-6);
    }
}

/// A broken copy of the KITTI folder must fail with `needle` in the message and write nothing.
fn kitti_broken(edit: impl FnOnce(&Path), needle: &str) {
    let Some(src) = kitti() else { return };
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("odometry_06");
    copy_dir(&src, &dir);
    edit(&dir);
    let out = tmp.path().join("scene");
    let err = run(&dir, &out, Expect::Auto).unwrap_err().to_string();
    assert!(err.contains(needle), "expected `{needle}` in: {err}");
    assert!(!out.exists(), "output left behind");
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 1, "staging left behind");
}

#[test]
fn kitti_errors_name_file_and_line() {
    let calib = |d: &Path| std::fs::read_to_string(d.join("calib.txt")).unwrap();
    kitti_broken(
        |d| {
            let first = calib(d).lines().next().unwrap().to_string();
            std::fs::write(d.join("calib.txt"), first).unwrap();
        },
        "calib.txt: line 2: missing the projection P1",
    );
    kitti_broken(
        |d| {
            let c = calib(d).replacen(" 0.000000000000e+00", "", 1);
            std::fs::write(d.join("calib.txt"), c).unwrap();
        },
        "calib.txt: line 1: expected 12 numbers",
    );
    kitti_broken(
        |d| {
            let p = std::fs::read_to_string(d.join("poses.txt")).unwrap();
            let lines: Vec<&str> = p.lines().collect();
            std::fs::write(d.join("poses.txt"), lines[..25].join("\n")).unwrap();
        },
        "poses.txt: holds 25 poses but image_0 holds 26 images",
    );
    kitti_broken(
        |d| {
            let p = std::fs::read_to_string(d.join("poses.txt")).unwrap().replacen("1.000000e+00", "x", 1);
            std::fs::write(d.join("poses.txt"), p).unwrap();
        },
        "poses.txt: line 1: `x` is not a finite number",
    );
    kitti_broken(|d| std::fs::remove_file(d.join("image_1/000004.png")).unwrap(), "image_1/000004.png: missing");
}

#[test]
fn fox_ingest_sorts_and_undistorts() {
    let Some(src) = ingest::shared::data_path("fox") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("scene");
    let s = run(&src, &out, Expect::Auto).unwrap();
    assert_eq!(s.source.kind, scene::SourceKind::TransformsJson);
    assert_eq!(s.frames.len(), 50);
    assert_eq!(s.cameras.len(), 1);
    let c = &s.cameras[0];
    assert_eq!((c.width, c.height), (1080, 1920));
    assert!(c.distortion.is_zero(), "undistorted at ingest");
    // Sorted by file name, synthetic 1 s clock.
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(src.join("transforms.json")).unwrap()).unwrap();
    let mut names: Vec<&str> =
        json["frames"].as_array().unwrap().iter().map(|f| f["file_path"].as_str().unwrap()).collect();
    names.sort();
    let first = json["frames"].as_array().unwrap().iter().find(|f| f["file_path"] == names[0]).unwrap();
    let m = &first["transform_matrix"];
    // The ego (= camera, Waymo axes) looks along OpenGL -z of the first file's pose.
    let fwd = s.frames[0].world_from_ego.transform_vector(DVec3::X);
    let gl_z = DVec3::new(m[0][2].as_f64().unwrap(), m[1][2].as_f64().unwrap(), m[2][2].as_f64().unwrap());
    assert!((fwd + gl_z).length() < 1e-9);
    for (i, f) in s.frames.iter().enumerate() {
        assert_eq!(f.timestamp_s, i as f64);
    }
    let img = image::open(out.join(&s.frames[0].images[0].path)).unwrap();
    assert_eq!((img.width(), img.height()), (1080, 1920));
}

/// A tiny hand-made transforms.json set: `camera_angle_x` only, per-frame intrinsics, paths
/// without extension (NeRF-synthetic style), unsorted frames.
#[test]
fn small_transforms_json_variants() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("set");
    std::fs::create_dir_all(dir.join("train")).unwrap();
    for n in ["r_0", "r_1", "r_2"] {
        image::RgbImage::from_pixel(40, 30, image::Rgb([10, 20, 30])).save(dir.join(format!("train/{n}.png"))).unwrap();
    }
    let pose = "[[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]";
    let json = format!(
        r#"{{"camera_angle_x": 0.6911112070083618, "frames": [
        {{"file_path": "./train/r_2", "transform_matrix": {pose}}},
        {{"file_path": "./train/r_0", "transform_matrix": {pose}}},
        {{"file_path": "./train/r_1", "transform_matrix": {pose}, "fl_x": 50.0, "fl_y": 50.0}}]}}"#
    );
    std::fs::write(dir.join("transforms.json"), &json).unwrap();
    let s = run(&dir, &tmp.path().join("a"), Expect::TransformsJson).unwrap();
    assert_eq!(s.frames.len(), 3);
    assert_eq!(s.cameras.len(), 2, "per-frame intrinsics make a second camera");
    let c0 = &s.cameras[0];
    assert!((c0.intrinsics.fx - 20.0 / (0.6911112070083618f64 / 2.0).tan()).abs() < 1e-9);
    assert_eq!((c0.intrinsics.cx, c0.intrinsics.cy), (20.0, 15.0));
    assert_eq!(s.frames[1].images[0].camera, "CAM1");
    assert_eq!(s.frames[1].images[0].path, "images/000001_CAM1.png");
    // The camera looks along world -z (OpenGL -z), 4 units up.
    let t = s.frames[0].world_from_ego;
    assert!((t.transform_vector(DVec3::X) - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
    assert!((t.translation() - DVec3::new(0.0, 0.0, 4.0)).length() < 1e-12);

    // Errors: a non-rigid matrix and a missing image name the field / file; nothing is written.
    let bad = json.replacen("[[1,0,0,0]", "[[2,0,0,0]", 1);
    std::fs::write(dir.join("transforms.json"), bad).unwrap();
    let out = tmp.path().join("b");
    let err = run(&dir, &out, Expect::Auto).unwrap_err().to_string();
    assert!(err.contains("transforms.json: `frames[0].transform_matrix`: not a rigid"), "{err}");
    assert!(!out.exists());
    std::fs::write(dir.join("transforms.json"), &json).unwrap();
    std::fs::remove_file(dir.join("train/r_1.png")).unwrap();
    let err = run(&dir, &out, Expect::Auto).unwrap_err().to_string();
    assert!(err.contains("train/r_1: missing (named by `frames[2].file_path`"), "{err}");
    assert!(!out.exists());
}
