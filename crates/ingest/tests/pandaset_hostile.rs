//! PandaSet folders built to break ingest, one per defect the fuzzing pass of 2026-11-28 found
//! (`carla-gs ingest` on mutated copies of sequence 002): a panic, memory bombs, a FIFO that
//! blocked forever, out-of-range numbers written into the scene, cameras and cuboid files
//! silently dropped, errors naming the staged output instead of the input. Each must be refused
//! naming the input file and field (or, where the input is sound, converted), quickly, with
//! nothing left behind.

mod common;

use common::{
    car, mkfifo, permissions_ignored, refused, refused_at, run, symlink, tiny, tiny_frames, within, write_json,
};
use ingest::Expect;
use scene::glam::DVec3;
use serde_json::{json, Value};
use std::io::Write;
use std::path::{Path, PathBuf};

fn edit_json(p: &Path, f: impl FnOnce(&mut Value)) {
    let mut v: Value = serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap();
    f(&mut v);
    write_json(p, &v);
}

fn set_all(p: &Path, path: &[&str], value: impl Fn(usize) -> Value) {
    edit_json(p, |v| {
        for (i, e) in v.as_array_mut().unwrap().iter_mut().enumerate() {
            let mut o = e;
            for k in path {
                o = &mut o[*k];
            }
            *o = value(i);
        }
    });
}

fn sweep_bytes(points: &[[f32; 4]]) -> Vec<u8> {
    points.iter().flatten().flat_map(|v| v.to_le_bytes()).collect()
}

/// A 16x12 JPEG whose frame header claims `w` x `h`.
fn jpeg_claiming(w: u16, h: u16) -> Vec<u8> {
    let mut bytes = Vec::new();
    image::RgbImage::from_pixel(16, 12, image::Rgb([90, 90, 90]))
        .write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Jpeg)
        .unwrap();
    let mut i = 2;
    while i + 9 < bytes.len() {
        assert_eq!(bytes[i], 0xFF);
        let len = u16::from_be_bytes([bytes[i + 2], bytes[i + 3]]) as usize;
        if matches!(bytes[i + 1], 0xC0..=0xC2) {
            bytes[i + 5..i + 7].copy_from_slice(&h.to_be_bytes());
            bytes[i + 7..i + 9].copy_from_slice(&w.to_be_bytes());
            return bytes;
        }
        i += 2 + len;
    }
    panic!("no frame header");
}

#[test]
fn ground_points_just_below_the_top_height_bin_do_not_panic() {
    // 60 points 1 - 2^-53 m above the LiDAR origin: ((z + 4) / 0.05) rounds to 100, one past the
    // 100 bins (the fuzz case `b_ground_bin_edge_panic` ended in an index-out-of-bounds panic).
    let tmp = tempfile::tempdir().unwrap();
    let src = tiny(tmp.path());
    set_all(&src.join("lidar/poses.json"), &["position", "z"], |_| json!(2f64.powi(-53)));
    let mut pts: Vec<[f32; 4]> = (0..200).map(|i| [(i % 20) as f32 * 0.5 - 5.0, (i / 20) as f32, -1.5, 7.0]).collect();
    pts.extend((0..60).map(|i| [i as f32 * 0.05, 1.0, 1.0, 7.0]));
    std::fs::write(src.join("lidar/00.bin"), sweep_bytes(&pts)).unwrap();
    let s = run(&src, &tmp.path().join("out"), Expect::Auto).unwrap();
    assert_eq!(s.frames[0].lidar.as_ref().unwrap().points, 260);
}

#[test]
fn cuboid_records_are_checked_and_counted_while_parsing() {
    // 30,000 empty records (the fuzz case: 9.6 M of them peaked at 6.3 GB): refused at the first.
    let bomb = format!("[{}]", vec![r#"{"":0}"#; 30_000].join(","));
    refused(
        |d| std::fs::write(d.join("annotations/cuboids/01.json"), &bomb).unwrap(),
        &["cuboids/01.json", "record 0 `uuid`"],
    );
    // One record past the per-frame limit: refused at that record.
    let many: Vec<Value> = (0..20_001).map(|i| car(&format!("u{i}"), i as f64 * 0.01)).collect();
    refused(
        |d| write_json(&d.join("annotations/cuboids/01.json"), &json!(many)),
        &["cuboids/01.json", "record 20000", "20000"],
    );
}

#[test]
fn lidar_sweeps_past_the_total_budget_are_refused_from_their_sizes() {
    // 9 sweeps at the 256 MiB cap (sparse files): 2.25 GiB in all, past the 2 GiB budget; refused
    // before any is read (the fuzz case held every sweep at once: 3.15 GB for 10).
    let tmp = tempfile::tempdir().unwrap();
    let src = tiny_frames(tmp.path(), 9);
    for k in 0..9 {
        std::fs::File::create(src.join(format!("lidar/{k:02}.bin"))).unwrap().set_len(256 << 20).unwrap();
    }
    let err = within(60, "9 large sweeps", {
        let (tmp, src) = (tmp.path().to_path_buf(), src.clone());
        move || refused_at(&tmp, &src, &["lidar", "2415919104 bytes", "2147483648"])
    });
    assert!(err.contains("9 sweeps"), "{err}");
}

#[test]
fn image_files_past_the_size_cap_are_refused_from_their_size() {
    // A valid JPEG header followed by zeros up to 64 MiB + 1 (the fuzz case: 4 GiB read whole).
    refused(
        |d| {
            let f = std::fs::OpenOptions::new().write(true).open(d.join("camera/front_camera/01.jpg")).unwrap();
            f.set_len((64 << 20) + 1).unwrap();
        },
        &["front_camera/01.jpg", "67108865 bytes", "67108864"],
    );
}

#[test]
fn fifos_and_other_non_files_are_refused_not_waited_on() {
    for rel in [
        "camera/front_camera/intrinsics.json",
        "camera/front_camera/poses.json",
        "lidar/timestamps.json",
        "annotations/cuboids/01.json",
        "lidar/00.bin",
        "camera/front_camera/01.jpg",
    ] {
        let tmp = tempfile::tempdir().unwrap();
        let src = tiny(tmp.path());
        mkfifo(&src.join(rel));
        within(20, rel, {
            let (tmp, src) = (tmp.path().to_path_buf(), src.clone());
            move || refused_at(&tmp, &src, &[rel, "FIFO"])
        });
    }
}

#[test]
fn present_but_unusable_inputs_are_refused_not_treated_as_absent() {
    let cub = |d: &Path| d.join("annotations/cuboids/01.json");
    refused(
        |d| {
            std::fs::remove_file(cub(d)).unwrap();
            std::fs::create_dir(cub(d)).unwrap()
        },
        &["cuboids/01.json", "directory"],
    );
    refused(|d| symlink("01.json", &cub(d)), &["cuboids/01.json", "symbolic links"]);
    refused(|d| symlink("nowhere.json", &cub(d)), &["cuboids/01.json", "nowhere"]);
    refused(
        |d| {
            std::fs::remove_file(d.join("lidar/00.bin")).unwrap();
            std::fs::create_dir(d.join("lidar/00.bin")).unwrap()
        },
        &["lidar/00.bin", "directory"],
    );
    refused(|d| symlink("/dev/zero", &d.join("lidar/01.bin")), &["lidar/01.bin", "device"]);
    // A second camera whose poses.json is gone: refused, not dropped (fuzz case `cp_missing`).
    let second = |d: &Path| {
        let to = d.join("camera/back_camera");
        std::fs::create_dir(&to).unwrap();
        for e in std::fs::read_dir(d.join("camera/front_camera")).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
        to
    };
    refused(|d| std::fs::remove_file(second(d).join("poses.json")).unwrap(), &["back_camera/poses.json", "missing"]);
    refused(
        |d| std::fs::remove_file(second(d).join("intrinsics.json")).unwrap(),
        &["back_camera/intrinsics.json", "missing"],
    );
    refused(|d| symlink("side_camera", &d.join("camera/side_camera")), &["camera/side_camera", "symbolic links"]);
    // Unreadable folders (fuzz cases `u_camdir000`, `u_cubdir000`, run as an ordinary user).
    let tmp = tempfile::tempdir().unwrap();
    if permissions_ignored(tmp.path()) {
        eprintln!("SKIP: unreadable-folder cases: this process reads folders of mode 000 (root)");
        return;
    }
    for (rel, named) in [("camera/back_camera", "camera/back_camera"), ("annotations/cuboids", "annotations/cuboids")] {
        let tmp = tempfile::tempdir().unwrap();
        let src = tiny(tmp.path());
        if rel == "camera/back_camera" {
            second(&src);
        }
        let mode = |m| std::fs::set_permissions(src.join(rel), std::os::unix::fs::PermissionsExt::from_mode(m));
        mode(0o000).unwrap();
        let out = tmp.path().join("out");
        let err = run(&src, &out, Expect::Auto).map(|_| ()).unwrap_err().to_string();
        mode(0o755).unwrap();
        assert!(err.contains(named) && err.contains("Permission denied"), "{err}");
        assert!(!out.exists());
    }
}

#[test]
fn out_of_range_numbers_are_refused() {
    // Finite f32 points that overflow on the way to the ego frame (fuzz case `b_huge_coords`).
    refused(
        |d| std::fs::write(d.join("lidar/00.bin"), sweep_bytes(&[[3e38, 3e38, 3e38, 0.0]; 10])).unwrap(),
        &["lidar/00.bin", "point 0", "10000 km"],
    );
    refused(
        |d| set_all(&d.join("lidar/poses.json"), &["position", "x"], |i| json!(if i == 1 { 1e308 } else { 0.0 })),
        &["lidar/poses.json", "[1]", "10000 km"],
    );
    refused(
        |d| {
            let p = d.join("camera/front_camera/poses.json");
            set_all(&p, &["position", "z"], |i| json!(if i == 2 { 1e300 } else { 0.0 }))
        },
        &["front_camera/poses.json", "[2]", "10000 km"],
    );
    let all_times = |d: &Path, t: &dyn Fn(usize) -> f64| {
        for f in ["lidar/timestamps.json", "camera/front_camera/timestamps.json"] {
            write_json(&d.join(f), &json!((0..3).map(t).collect::<Vec<_>>()));
        }
    };
    refused(|d| all_times(d, &|i| 1e300 * (1 + i) as f64), &["lidar/timestamps.json", "[0]", "1e11"]);
    // Times 1e-310 s apart: every speed would be infinite (fuzz case `t_tiny_spacing`).
    refused(|d| all_times(d, &|i| 1e-310 * i as f64), &["lidar/timestamps.json", "[1]", "1e-6 s"]);
}

#[test]
fn implausible_intrinsics_for_the_image_are_refused() {
    // The tiny camera's images are 16x12: fx, fy within [0.16, 16000], cx within [-16, 32],
    // cy within [-12, 24] (fuzz cases: fx = 1e-300, cx = -900000 on a 960 px image).
    let k = |d: &Path, v: Value| write_json(&d.join("camera/front_camera/intrinsics.json"), &v);
    refused(
        |d| k(d, json!({"fx": 1e-300, "fy": 10.0, "cx": 8.0, "cy": 6.0})),
        &["front_camera/intrinsics.json", "`fx`", "1e-300", "[0.16, 16000.0]", "16x12"],
    );
    refused(
        |d| k(d, json!({"fx": 10.0, "fy": 10.0, "cx": -900000.0, "cy": 6.0})),
        &["front_camera/intrinsics.json", "`cx`", "-900000.0", "[-16.0, 32.0]"],
    );
    refused(|d| k(d, json!({"fx": 10.0, "fy": 16001.0, "cx": 8.0, "cy": 6.0})), &["`fy`", "16001.0"]);
    refused(|d| k(d, json!({"fx": 10.0, "fy": 10.0, "cx": 8.0, "cy": 25.0})), &["`cy`", "[-12.0, 24.0]"]);
    // The bounds themselves pass.
    let tmp = tempfile::tempdir().unwrap();
    let src = tiny(tmp.path());
    k(&src, json!({"fx": 0.16, "fy": 16000.0, "cx": -16.0, "cy": 24.0}));
    run(&src, &tmp.path().join("out"), Expect::Auto).unwrap();
}

#[test]
fn the_forward_axis_comes_from_horizontal_motion() {
    // Straight up: no horizontal motion, so the documented axis (+y) with a warning, as for an
    // ego that stands still (the mean direction used to be NaN and passed every check).
    let tmp = tempfile::tempdir().unwrap();
    let src = tiny(tmp.path());
    set_all(&src.join("lidar/poses.json"), &["position", "y"], |_| json!(0.0));
    set_all(&src.join("lidar/poses.json"), &["position", "z"], |i| json!(0.5 * i as f64));
    let s = run(&src, &tmp.path().join("out"), Expect::Auto).unwrap();
    let x = s.frames[0].world_from_ego.transform_vector(DVec3::X);
    assert!((x - DVec3::Y).length() < 1e-9, "forward {x}");
    // Forth and back: 4 m of driving with no mean direction.
    refused(
        |d| set_all(&d.join("lidar/poses.json"), &["position", "y"], |i| json!([0.0, 2.0, 0.0][i])),
        &["lidar/poses.json", "no mean direction"],
    );
}

#[test]
fn camera_folder_names_and_sizes_are_checked_against_the_input() {
    let copy_as = |d: &Path, name: &std::ffi::OsStr| {
        let to = d.join("camera").join(name);
        std::fs::create_dir(&to).unwrap();
        for e in std::fs::read_dir(d.join("camera/front_camera")).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), to.join(e.file_name())).unwrap();
        }
    };
    refused(|d| copy_as(d, "back camera".as_ref()), &["camera/back camera", "letters, digits"]);
    refused(|d| copy_as(d, "evil\nname".as_ref()), &["letters, digits"]);
    let bad_utf8: &std::ffi::OsStr = std::os::unix::ffi::OsStrExt::from_bytes(b"cam\xff");
    refused(|d| copy_as(d, bad_utf8), &["camera/cam", "UTF-8"]);
    // Every image claims 20000x20000: past the camera size budget, named at the image.
    refused(
        |d| {
            for k in 0..3 {
                std::fs::write(d.join(format!("camera/front_camera/{k:02}.jpg")), jpeg_claiming(20000, 20000)).unwrap();
            }
        },
        &["front_camera/00.jpg", "20000x20000", "16384"],
    );
}

#[test]
fn gzip_members_are_all_read_and_trailing_bytes_refused() {
    let gz = |bytes: &[u8]| {
        let mut e = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
        e.write_all(bytes).unwrap();
        e.finish().unwrap()
    };
    let tmp = tempfile::tempdir().unwrap();
    let src = tiny(tmp.path());
    let cub = src.join("annotations/cuboids");
    let text = serde_json::to_vec(&json!([car("a", 11.0), car("b", 30.0)])).unwrap();
    let (a, b) = text.split_at(text.len() / 2);
    std::fs::write(cub.join("01.json.gz"), [gz(a), gz(b)].concat()).unwrap();
    std::fs::remove_file(cub.join("01.json")).unwrap();
    let s = run(&src, &tmp.path().join("out"), Expect::Auto).unwrap();
    assert_eq!(s.tracks.len(), 2, "both records of the two-member file are read");
    // Bytes after the last member are not gzip: refused.
    refused(
        |d| {
            let cub = d.join("annotations/cuboids");
            std::fs::write(cub.join("02.json.gz"), [gz(&text), b"trailing garbage".to_vec()].concat()).unwrap();
            std::fs::remove_file(cub.join("02.json")).unwrap();
        },
        &["cuboids/02.json.gz", "gzip"],
    );
}

#[test]
fn sibling_links_must_join_one_object_and_fields_must_have_their_types() {
    // A car and a pedestrian 29 m apart naming each other as siblings (fuzz case
    // `c_sibling_ring`): two objects, not one track.
    let tmp = tempfile::tempdir().unwrap();
    let src = tiny(tmp.path());
    let mut ped = car("p", 40.0);
    ped["label"] = json!("Pedestrian");
    ped["cuboids.sibling_id"] = json!("a");
    let mut a = car("a", 11.0);
    a["cuboids.sibling_id"] = json!("p");
    write_json(&src.join("annotations/cuboids/01.json"), &json!([a, ped]));
    let s = run(&src, &tmp.path().join("out"), Expect::Auto).unwrap();
    let ids: Vec<&str> = s.tracks.iter().map(|t| t.id.as_str()).collect();
    assert_eq!(ids, ["a", "p"]);
    // The same link through the library: counted as refused; a uuid twice in one frame counted.
    let frames: Vec<Vec<ingest::pandaset::cuboids::Cuboid>> = (0..3)
        .map(|k| {
            let f = src.join(format!("annotations/cuboids/{k:02}.json"));
            ingest::pandaset::cuboid_records::parse_frame(&f, &std::fs::read(&f).unwrap()).unwrap()
        })
        .collect();
    let (tracks, report) = ingest::pandaset::cuboids::tracks(&frames, &[100.0, 100.1, 100.2]);
    assert_eq!((tracks.len(), report.refused_sibling_links, report.duplicate_uuid_records), (2, 1, 0));
    let mut twice = frames.clone();
    let mut far = twice[2][0].clone();
    far.center.x += 30.0;
    twice[2].push(far);
    let (_, report) = ingest::pandaset::cuboids::tracks(&twice, &[100.0, 100.1, 100.2]);
    assert_eq!(report.duplicate_uuid_records, 1);
    // A sensor id that is not a number (fuzz case `c_sensor_str`).
    refused(
        |d| {
            let mut c = car("a", 11.0);
            c["cuboids.sensor_id"] = json!("zero");
            write_json(&d.join("annotations/cuboids/01.json"), &json!([c]))
        },
        &["cuboids/01.json", "record 0 `cuboids.sensor_id`"],
    );
    // A literal NaN: the record is named.
    refused(
        |d| {
            let c = serde_json::to_string(&json!([car("a", 11.0), car("b", 20.0)])).unwrap();
            let c = c.replacen("\"yaw\":0.0", "\"yaw\":NaN", 2).replacen("\"yaw\":NaN", "\"yaw\":0.0", 1);
            std::fs::write(d.join("annotations/cuboids/01.json"), c).unwrap()
        },
        &["cuboids/01.json", "record 1", "NaN"],
    );
}

#[test]
fn a_failed_ingest_removes_the_parent_folders_it_created() {
    let tmp = tempfile::tempdir().unwrap();
    let src = tiny(tmp.path());
    std::fs::write(src.join("lidar/timestamps.json"), "[100.0, 100.0, 100.2]").unwrap();
    let out: PathBuf = tmp.path().join("a/b/c/out");
    let err = run(&src, &out, Expect::Auto).unwrap_err().to_string();
    assert!(err.contains("lidar/timestamps.json"), "{err}");
    assert!(!tmp.path().join("a").exists(), "created parents left behind after: {err}");
    // A parent that was there before stays.
    std::fs::create_dir(tmp.path().join("a")).unwrap();
    run(&src, &out, Expect::Auto).unwrap_err();
    assert!(tmp.path().join("a").is_dir() && !tmp.path().join("a/b").exists());
}

#[test]
fn per_frame_lists_are_counted_while_parsing() {
    // 100,001 times: refused at the one past the frame limit, not after building all (the fuzz
    // pass's 33 M-entry timestamps.json took 337 MB before its count was checked).
    let long =
        format!("[{}]", (0..100_001).map(|i| format!("{}", 100.0 + 0.1 * i as f64)).collect::<Vec<_>>().join(","));
    refused(
        |d| std::fs::write(d.join("lidar/timestamps.json"), &long).unwrap(),
        &["lidar/timestamps.json", "more than 100000 entries"],
    );
}

#[test]
fn a_missing_cuboid_file_is_refused_not_a_frame_without_boxes() {
    // Was: every box of frame 1 dropped, exit 0, no word.
    refused(
        |src| std::fs::remove_file(src.join("annotations/cuboids/01.json")).unwrap(),
        &["annotations/cuboids/01.json.gz", "missing", "2 of the 3 frames"],
    );
}
