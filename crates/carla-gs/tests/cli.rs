//! End-to-end tests of `carla-gs ingest` and `inspect` on the shared real Waymo data, and of
//! every kind of bad input: exit code 2, a message naming the problem, and no output directory.

use ingest::proto::Frame;
use ingest::tfrecord::{write_record, TfRecordReader};
use prost::Message;
use serde_json::Value;
use std::path::Path;
use std::process::{Command, Output};

fn carla_gs(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_carla-gs")).args(args).output().expect("run carla-gs")
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn inspect_json(dir: &Path) -> Value {
    let out = carla_gs(&["inspect", s(dir), "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

/// Runs `ingest` expecting failure: exit code 2, `needle` in the message, no output left.
fn assert_rejected(input: &Path, needle: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let out_dir = tmp.path().join("scene");
    let out = carla_gs(&["ingest", s(input), "--out", s(&out_dir)]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "stderr: {err}");
    assert!(err.contains(needle), "expected `{needle}` in: {err}");
    assert!(!out_dir.exists(), "partial output directory left behind");
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path()).unwrap().collect();
    assert!(leftovers.is_empty(), "staging files left behind: {leftovers:?}");
    // `inspect` of the same file fails the same way.
    let out = carla_gs(&["inspect", s(input)]);
    assert_eq!(out.status.code(), Some(2));
}

fn frame_record(path: &Path) -> Vec<u8> {
    TfRecordReader::new(std::fs::File::open(path).unwrap()).next().unwrap().unwrap().data
}

fn write_tfrecord(path: &Path, records: &[Vec<u8>]) {
    let mut bytes = Vec::new();
    for r in records {
        write_record(&mut bytes, r).unwrap();
    }
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn waymo_frame_ingest_and_inspect() {
    let Some(input) = ingest::shared::waymo_file("pvps_data_one_frame.tfrecord") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("scene");
    let out = carla_gs(&["ingest", s(&input), "--out", s(&dir)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let j = inspect_json(&dir);
    assert_eq!(j["frames"], 1);
    assert_eq!(j["tracks"], 75);
    let cams = j["cameras"].as_array().unwrap();
    assert_eq!(cams.len(), 5);
    let sizes: Vec<(u64, u64)> =
        cams.iter().map(|c| (c["width"].as_u64().unwrap(), c["height"].as_u64().unwrap())).collect();
    assert_eq!(sizes.iter().filter(|s| **s == (1920, 1280)).count(), 3);
    assert_eq!(sizes.iter().filter(|s| **s == (1920, 886)).count(), 2);
    // Images are the original JPEG bytes.
    let frame = Frame::decode(&frame_record(&input)[..]).unwrap();
    let front = frame.images.iter().find(|i| i.name == Some(1)).unwrap();
    assert_eq!(std::fs::read(dir.join("images/000000_FRONT.jpg")).unwrap(), front.image.clone().unwrap());
    // A second ingest to the same place needs --force.
    let again = carla_gs(&["ingest", s(&input), "--out", s(&dir)]);
    assert_eq!(again.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&again.stderr).contains("--force"));
    assert!(carla_gs(&["ingest", s(&input), "--out", s(&dir), "--force"]).status.success());
}

#[test]
fn womd_scenarios_ingest() {
    for (name, tracks, distance) in
        [("motion_data_one_scenario.tfrecord", 83, 0.0), ("womd_scenario_input.tfrecord", 257, 26.0)]
    {
        let Some(input) = ingest::shared::waymo_file(name) else { return };
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("scene");
        let out = carla_gs(&["ingest", s(&input), "--out", s(&dir)]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        let j = inspect_json(&dir);
        assert_eq!(j["tracks"], tracks, "{name}");
        assert_eq!(j["frames"], 91, "{name}");
        assert!((j["frame_rate_hz"].as_f64().unwrap() - 10.0).abs() < 0.05, "{name}");
        let travelled = j["ego_distance_m"].as_f64().unwrap();
        assert!((travelled - distance).abs() < 1.0, "{name}: ego travelled {travelled} m");
        // The ego is the sdc track and follows it exactly.
        let scene = scene::load_scene(&dir).unwrap();
        let ego = scene.track(scene.ego.track_id.as_deref().unwrap()).unwrap();
        for st in ego.valid_states() {
            assert!((scene.frames[st.frame].world_from_ego.translation() - st.center).length() < 1e-9);
        }
        assert!(scene.map.as_ref().is_some_and(|m| !m.lanes.is_empty()));
    }
}

#[test]
fn womd_file_with_several_scenarios_writes_one_scene_each() {
    let (Some(a), Some(b)) = (
        ingest::shared::waymo_file("motion_data_one_scenario.tfrecord"),
        ingest::shared::waymo_file("womd_scenario_input.tfrecord"),
    ) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let both = tmp.path().join("both.tfrecord");
    let mut bytes = std::fs::read(&a).unwrap();
    bytes.extend(std::fs::read(&b).unwrap());
    std::fs::write(&both, bytes).unwrap();
    let listed = carla_gs(&["inspect", s(&both), "--json"]);
    let j: Value = serde_json::from_slice(&listed.stdout).unwrap();
    let names: Vec<&str> = j["scenes"].as_array().unwrap().iter().map(|s| s["name"].as_str().unwrap()).collect();
    assert_eq!(names, ["637f20cafde22ff8", "ee519cf571686d19"]);
    let dir = tmp.path().join("out");
    assert!(carla_gs(&["ingest", s(&both), "--out", s(&dir), "--format", "womd"]).status.success());
    for n in names {
        assert!(dir.join(n).join("scene.json").is_file());
    }
    assert_eq!(inspect_json(&dir)["scenes"].as_array().unwrap().len(), 2);
}

#[test]
fn multi_file_segment_is_sorted_and_duplicates_rejected() {
    let Some(input) = ingest::shared::waymo_file("pvps_data_one_frame.tfrecord") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let mut later = Frame::decode(&frame_record(&input)[..]).unwrap();
    later.timestamp_micros = Some(later.timestamp_micros.unwrap() + 100_000);
    later.pose.as_mut().unwrap().transform[3] += 1.0; // 1 m along world x
    let (f1, f2) = (tmp.path().join("a.tfrecord"), tmp.path().join("b.tfrecord"));
    write_tfrecord(&f1, &[later.encode_to_vec()]);
    std::fs::copy(&input, &f2).unwrap();
    let dir = tmp.path().join("scene");
    let out = carla_gs(&["ingest", s(&f1), s(&f2), "--out", s(&dir)]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let scene = scene::load_scene(&dir).unwrap();
    assert_eq!(scene.frames.len(), 2);
    assert!((scene.frames[1].timestamp_s - scene.frames[0].timestamp_s - 0.1).abs() < 1e-6);
    assert!((scene.ego_distance_m() - 1.0).abs() < 1e-9);
    assert!(scene.tracks.iter().all(|t| t.states.len() == 2));
    // The same frame twice is refused.
    let dup = carla_gs(&["ingest", s(&f2), s(&f2), "--out", s(&tmp.path().join("dup"))]);
    assert_eq!(dup.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&dup.stderr).contains("duplicate frame timestamp"));
    assert!(!tmp.path().join("dup").exists());
}

#[test]
fn empty_file_is_rejected() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("empty.tfrecord");
    std::fs::write(&p, b"").unwrap();
    assert_rejected(&p, "no TFRecord records");
}

#[test]
fn truncated_record_is_rejected() {
    let Some(input) = ingest::shared::waymo_file("pvps_data_one_frame.tfrecord") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("cut.tfrecord");
    let bytes = std::fs::read(&input).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() - 1000]).unwrap();
    assert_rejected(&p, "record 0 (starting at byte 0): file ends inside the record's data");
}

#[test]
fn flipped_byte_fails_the_crc() {
    let Some(input) = ingest::shared::waymo_file("pvps_data_one_frame.tfrecord") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("flip.tfrecord");
    let mut bytes = std::fs::read(&input).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x01;
    std::fs::write(&p, &bytes).unwrap();
    assert_rejected(&p, "data CRC mismatch");
}

#[test]
fn record_of_another_kind_is_rejected() {
    let tmp = tempfile::tempdir().unwrap();
    let p = tmp.path().join("other.tfrecord");
    write_tfrecord(&p, &[br#"{"not": "a protobuf"}"#.to_vec()]);
    assert_rejected(&p, "record 0 (byte 0) is neither a Waymo v1 Frame nor a WOMD Scenario");
    // A valid protobuf of another message (a bare Label) is refused too.
    let label = ingest::proto::Label { id: Some("x".into()), ..Default::default() };
    write_tfrecord(&p, &[label.encode_to_vec()]);
    assert_rejected(&p, "neither a Waymo v1 Frame nor a WOMD Scenario");
}

#[test]
fn image_without_calibration_is_rejected() {
    let Some(input) = ingest::shared::waymo_file("pvps_data_one_frame.tfrecord") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let mut frame = Frame::decode(&frame_record(&input)[..]).unwrap();
    frame.context.as_mut().unwrap().camera_calibrations.retain(|c| c.name != Some(4)); // drop SIDE_LEFT
    let p = tmp.path().join("nocal.tfrecord");
    write_tfrecord(&p, &[frame.encode_to_vec()]);
    assert_rejected(&p, "camera SIDE_LEFT has no calibration in context.camera_calibrations");
}

#[test]
fn corrupt_scene_json_names_the_field() {
    let Some(input) = ingest::shared::waymo_file("pvps_data_one_frame.tfrecord") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("scene");
    assert!(carla_gs(&["ingest", s(&input), "--out", s(&dir)]).status.success());
    let file = dir.join("scene.json");
    let good: Value = serde_json::from_slice(&std::fs::read(&file).unwrap()).unwrap();
    type Edit = fn(&mut Value);
    let cases: [(&str, Edit, &str); 4] = [
        ("type", |j| j["frames"][0]["timestamp_s"] = "soon".into(), "frames[0].timestamp_s"),
        ("width", |j| j["cameras"][3]["width"] = 0.into(), "cameras[3].width"),
        ("track", |j| j["tracks"][7]["states"][0]["frame"] = 4.into(), "tracks[7].states[0].frame"),
        ("version", |j| j["format"] = "carla-gs-scene/0".into(), "`format`: expected \"carla-gs-scene/1\""),
    ];
    for (what, edit, needle) in cases {
        let mut j = good.clone();
        edit(&mut j);
        std::fs::write(&file, serde_json::to_vec(&j).unwrap()).unwrap();
        let out = carla_gs(&["inspect", s(&dir)]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{what}");
        assert!(err.contains(needle), "{what}: expected `{needle}` in: {err}");
    }
    std::fs::remove_file(dir.join("images/000000_FRONT.jpg")).unwrap();
    std::fs::write(&file, serde_json::to_vec(&good).unwrap()).unwrap();
    let err = String::from_utf8_lossy(&carla_gs(&["inspect", s(&dir)]).stderr).into_owned();
    assert!(err.contains("frames[0].images[") && err.contains("does not exist"), "{err}");
}
