//! Fuzz targets over the ingest sources: TFRecord framing, Waymo Frame and WOMD Scenario protos
//! (each mutated record re-framed with a valid checksum, so the proto decoder and converter see
//! it), and the transforms.json, KITTI and PandaSet folders (one text file mutated per case). The
//! Waymo, KITTI and PandaSet bases are the shared real data; absent, the target prints `SKIP:`.

use super::{clean, fuzz, fuzz_files};
use indicatif::ProgressBar;
use ingest::tfrecord::{write_record, TfRecordReader};
use ingest::Expect;
use std::path::{Path, PathBuf};

fn read_scenes(input: &Path, expect: Expect) -> Result<(), String> {
    clean(ingest::read_scenes(&[input.to_path_buf()], expect, &ProgressBar::hidden()))
}

#[test]
fn fuzz_tfrecord_framing() {
    let mut base = Vec::new();
    for payload in [&b"first"[..], &[7u8; 40][..], b""] {
        write_record(&mut base, payload).unwrap();
    }
    fuzz("tfrecord", &base, false, |b| {
        for r in TfRecordReader::new(b).take(16) {
            r.map_err(|e| e.to_string())?;
        }
        Ok(())
    });
}

/// The first record of a shared Waymo file, fuzzed as a one-record file read by `read_scenes`.
fn fuzz_first_record(target: &str, file: &str, expect: Expect) {
    let Some(path) = ingest::shared::data_path(&format!("waymo/{file}")) else {
        super::cli_support::fuzz_log(&format!("SKIP: fuzz {target}: ../shared/data/waymo/{file} absent"));
        return;
    };
    let first = TfRecordReader::new(std::fs::File::open(path).unwrap()).next().unwrap().unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("one.tfrecord");
    fuzz(target, &first.data, false, |b| {
        let mut framed = Vec::new();
        write_record(&mut framed, b).unwrap();
        std::fs::write(&out, framed).unwrap();
        read_scenes(&out, expect)
    });
}

#[test]
fn fuzz_womd_scenario() {
    fuzz_first_record("womd-scenario", "motion_data_one_scenario.tfrecord", Expect::Auto);
}

#[test]
fn fuzz_waymo_frame() {
    fuzz_first_record("waymo-frame", "pvps_data_one_frame.tfrecord", Expect::Auto);
}

/// Mirrors `src` into `dst`: files for which `mutable` holds are copied and returned (path
/// relative to `dst`, bytes), the others linked.
fn mirror(src: &Path, dst: &Path, mutable: &dyn Fn(&Path) -> bool, out: &mut Vec<(String, Vec<u8>)>) {
    std::fs::create_dir_all(dst).unwrap();
    let mut entries: Vec<_> = std::fs::read_dir(src).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for p in entries {
        let d = dst.join(p.file_name().unwrap());
        if p.is_dir() {
            mirror(&p, &d, mutable, out);
        } else if mutable(&p) {
            let bytes = std::fs::read(&p).unwrap();
            std::fs::write(&d, &bytes).unwrap();
            out.push((d.to_str().unwrap().to_string(), bytes));
        } else {
            std::os::unix::fs::symlink(&p, &d).unwrap();
        }
    }
}

/// Fuzzes a folder source: each case writes the mutated files into the mirror and reads it.
fn fuzz_folder(target: &str, dir: &Path, files: Vec<(String, Vec<u8>)>, expect: Expect) {
    fuzz_files(target, &files, true, |set| {
        for (p, b) in set {
            std::fs::write(p, b).unwrap();
        }
        read_scenes(dir, expect)
    });
}

fn fuzz_shared_folder(target: &str, rel: &str, mutable: &dyn Fn(&Path) -> bool, expect: Expect) {
    let Some(src) = ingest::shared::data_path(rel) else {
        super::cli_support::fuzz_log(&format!("SKIP: fuzz {target}: ../shared/data/{rel} absent"));
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("seq");
    let mut files = Vec::new();
    mirror(&src, &dir, mutable, &mut files);
    fuzz_folder(target, &dir, files, expect);
}

#[test]
fn fuzz_kitti() {
    let txt = |p: &Path| p.extension().is_some_and(|e| e == "txt");
    fuzz_shared_folder("kitti", "kitti/odometry_06", &txt, Expect::KittiOdometry);
}

#[test]
fn fuzz_pandaset() {
    // The JSON files of the sequence and the first frame's cuboids (gzip: mutated as bytes).
    let mutable =
        |p: &Path| p.extension().is_some_and(|e| e == "json") || p.ends_with("annotations/cuboids/00.json.gz");
    fuzz_shared_folder("pandaset", "pandaset/002", &mutable, Expect::Pandaset);
}

#[test]
fn fuzz_transforms_json() {
    let tmp = tempfile::tempdir().unwrap();
    let dir: PathBuf = tmp.path().join("set");
    std::fs::create_dir_all(dir.join("train")).unwrap();
    for n in ["r_0", "r_1", "r_2"] {
        image::RgbImage::from_pixel(40, 30, image::Rgb([10, 20, 30])).save(dir.join(format!("train/{n}.png"))).unwrap();
    }
    let pose = "[[1,0,0,0],[0,1,0,0],[0,0,1,4],[0,0,0,1]]";
    let json = format!(
        r#"{{"camera_angle_x": 0.69, "frames": [
        {{"file_path": "./train/r_2", "transform_matrix": {pose}}},
        {{"file_path": "./train/r_0", "transform_matrix": [[1,0,0,1],[0,1,0,0],[0,0,1,4],[0,0,0,1]]}},
        {{"file_path": "./train/r_1", "transform_matrix": {pose}, "fl_x": 50.0, "fl_y": 50.0}}]}}"#
    );
    let file = dir.join("transforms.json");
    fuzz_folder(
        "transforms.json",
        &dir,
        vec![(file.to_str().unwrap().to_string(), json.into_bytes())],
        Expect::TransformsJson,
    );
}
