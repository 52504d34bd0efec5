//! `carla-gs asset harvest` on PandaSet 002 (skipped, saying so, without `../shared/data`): the
//! statistics come from the log's cameras and boxes, so a two-iteration model is enough to check
//! that they are plausible for three known vehicles (docs/render.md has the full table of a
//! trained model):
//!
//! * the lead car 5efc9139 drives ahead of the ego the whole log: seen from behind only (one
//!   azimuth sector), by the front camera of each of the 70 training frames, never nearer than
//!   8 m;
//! * the car 0d238564 overtakes the ego on the left: seen from a few metres, from behind, the
//!   side and ahead (four sectors or more) by several cameras;
//! * the oncoming car ed323433 passes on the left: seen from its front and side, closest about
//!   6 m.
//!
//! It also checks that the table lists every vehicle actor and that the library gets one
//! mirrored asset per kept vehicle.

mod cli_support;

use cli_support::{carla_gs, ok, s};
use serde_json::Value;

#[test]
fn harvest_statistics_of_known_pandaset_vehicles_are_plausible() {
    let Some(src) = ingest::shared::data_path("pandaset/002") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let (scene, model, lib) = (tmp.path().join("s"), tmp.path().join("m"), tmp.path().join("lib"));
    ok(carla_gs(&["ingest", s(&src), "--out", s(&scene)]));
    ok(carla_gs(&["train", s(&scene), "--out", s(&model), "--iters", "2", "--scale", "0.05"]));
    let text = ok(carla_gs(&["asset", "harvest", s(&scene), "--model", s(&model), "--library", s(&lib), "--json"]));
    let r: Value = serde_json::from_str(&text).unwrap();
    let vehicles = r["vehicles"].as_array().unwrap();
    assert_eq!(r["scene"], "pandaset-002");
    assert_eq!(r["held_out_every"], 8);
    assert!(vehicles.len() > 40, "PandaSet 002 has 82 vehicle tracks: {}", vehicles.len());
    let v = |id: &str| {
        vehicles.iter().find(|v| v["track_id"].as_str().unwrap().starts_with(id)).unwrap_or_else(|| panic!("{id}"))
    };
    let stat = |id: &str, k: &str| v(id)["observed"][k].as_f64().unwrap_or_else(|| panic!("{id}.{k}"));
    let sectors = |id: &str| v(id)["observed"]["azimuth_sectors"].as_array().unwrap().len();
    for id in ["5efc9139", "0d238564", "ed323433"] {
        println!("{id}: {}", v(id)["observed"]);
    }

    assert_eq!(stat("5efc9139", "views"), 70.0, "one front-camera view per training frame");
    assert_eq!(sectors("5efc9139"), 1);
    let lead = stat("5efc9139", "closest_m");
    assert!((8.0..12.0).contains(&lead), "lead car closest {lead} m");
    assert!(stat("5efc9139", "max_hull_px") > 20_000.0);

    let cut_in = stat("0d238564", "closest_m");
    assert!(cut_in < 4.0, "overtaking car closest {cut_in} m");
    assert!(sectors("0d238564") >= 4 && stat("0d238564", "azimuth_span_deg") > 90.0);
    assert!(stat("0d238564", "views") > 70.0, "seen by more than one camera");

    let oncoming = stat("ed323433", "closest_m");
    assert!((4.0..8.0).contains(&oncoming), "oncoming car closest {oncoming} m");
    assert!(sectors("ed323433") >= 3);

    let never = vehicles.iter().filter(|v| v["observed"]["views"] == 0).count();
    assert!(never > 0 && never < vehicles.len(), "{never} vehicles never in view");
    let kept: Vec<&Value> = vehicles.iter().filter(|v| v["kept"] == true).collect();
    let index: Value = serde_json::from_slice(&std::fs::read(lib.join("index.json")).unwrap()).unwrap();
    assert_eq!(index["assets"].as_array().unwrap().len(), kept.len());
    for k in &kept {
        assert!(k["why_not"].as_array().unwrap().is_empty(), "{k}");
    }
    // The table lists every vehicle actor, kept or why not.
    let table = ok(carla_gs(&["asset", "harvest", s(&scene), "--model", s(&model), "--library", s(&lib)]));
    assert_eq!(table.lines().filter(|l| l.contains(" yes ") || l.contains(" no ")).count(), vehicles.len(), "{table}");
    assert!(table.contains("never in view of a training image"), "{table}");
}
