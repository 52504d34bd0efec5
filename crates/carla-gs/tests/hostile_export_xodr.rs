//! Fuzzing find about `export-xodr`: a lane of 1,000,000 points wrote a 162 MB OpenDRIVE file,
//! and a point 1e300 m away was written. Both exit with code 2 naming the lane and the budget,
//! before anything is written. A lane that is long but reaches far beyond the scene (a city's
//! boundary) is not refused: the map is cropped to the scene's region first (issue 53).

mod cli_support;

use cli_support::{carla_gs, ok, refused, s};
use serde_json::Value;
use std::path::Path;

/// Adds a lane of `points` to the map of the scene in `scene` (creating the map if needed).
fn add_lane(scene: &Path, points: Vec<Value>) {
    let path = scene.join("scene.json");
    let mut j: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
    if j["map"].is_null() {
        j["map"] = serde_json::json!({"lanes": [], "road_edges": [], "road_lines": []});
    }
    j["map"]["lanes"].as_array_mut().unwrap().push(serde_json::json!({"id": 99, "points": points}));
    std::fs::write(&path, serde_json::to_vec(&j).unwrap()).unwrap();
}

#[test]
fn huge_or_absurd_lanes_are_refused_before_writing() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = tmp.path().join("s40");
    ok(carla_gs(&["synth", "--out", s(&scene), "--frames", "40", "--width", "32", "--height", "24", "--cameras", "1"]));
    let xodr = tmp.path().join("map.xodr");
    ok(carla_gs(&["export-xodr", s(&scene), "--out", s(&xodr)]));
    std::fs::remove_file(&xodr).unwrap();
    let pristine = std::fs::read(scene.join("scene.json")).unwrap();

    // 500 km of lane, 0.5 m apart: cropped to the scene's region and written.
    add_lane(&scene, (0..1_000_000).map(|k| serde_json::json!([k as f64 * 0.5, 0.0, 0.0])).collect());
    ok(carla_gs(&["export-xodr", s(&scene), "--out", s(&xodr)]));
    let written = std::fs::metadata(&xodr).unwrap().len();
    assert!(written < 5_000_000, "the cropped lane wrote {written} bytes");
    std::fs::remove_file(&xodr).unwrap();

    // 1,000,000 points within 200 m of the street: refused by the point budget.
    std::fs::write(scene.join("scene.json"), &pristine).unwrap();
    add_lane(&scene, (0..1_000_000).map(|k| serde_json::json!([k as f64 * 0.0002, 0.0, 0.0])).collect());
    refused(carla_gs(&["export-xodr", s(&scene), "--out", s(&xodr)]), &["(id 99)", "1000000 points", "100000"]);
    assert!(!xodr.exists());

    std::fs::write(scene.join("scene.json"), &pristine).unwrap();
    add_lane(&scene, vec![serde_json::json!([0.0, 0.0, 0.0]), serde_json::json!([1e300, 0.0, 0.0])]);
    refused(carla_gs(&["export-xodr", s(&scene), "--out", s(&xodr)]), &["(id 99) point 1", "1e300 m"]);
    assert!(!xodr.exists());
}
