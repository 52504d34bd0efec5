//! OpenDRIVE export: a hand-made scene with curved, sloped lanes and a road edge, and a scene
//! without a map (flat road). Written, validated against the ASAM OpenDRIVE 1.6.1 schema with
//! xmllint (skipped with a printed reason when xmllint or the schema is missing; `tools/setup.sh`
//! installs the schema), parsed back, and checked geometrically: every logged lane vertex lies on
//! its lane's centre, every logged position lies on the flat road. The shared WOMD scenario's
//! real map goes through the same checks when the shared data is present.

use export::xodr::{build_road_network, read_xodr, write_xodr, RoadNetwork, XodrOptions};
use export::ExportError;
use scene::glam::{DVec2, DVec3};
use scene::map::{Map, Polyline};
use scene::{Ego, EgoSizeSource, Frame, ObjectClass, Scene, Source, SourceKind, Track, TrackState, Transform3};
use std::path::PathBuf;
use std::process::Command;

fn scene_with(map: Option<Map>) -> Scene {
    let frames: Vec<Frame> = (0..=40)
        .map(|i| Frame {
            index: i,
            timestamp_s: 100.0 + 0.1 * i as f64,
            world_from_ego: Transform3::from_yaw_translation(
                0.3,
                DVec3::new(5000.0 + i as f64, 2000.0 + 0.3 * i as f64, 7.0),
            ),
            images: Vec::new(),
            lidar: None,
        })
        .collect();
    let states = frames
        .iter()
        .map(|f| TrackState {
            frame: f.index,
            center: DVec3::new(5010.0 + f.index as f64 * 0.5, 1990.0, 7.75),
            heading: 0.0,
            size_lwh: [4.5, 1.9, 1.5],
            velocity: None,
            valid: true,
            motion: None,
        })
        .collect();
    Scene {
        format: scene::SCENE_FORMAT.into(),
        name: "xodr-test".into(),
        source: Source { kind: SourceKind::Synthetic, files: Vec::new(), id: "test".into() },
        ego: Ego { size_lwh: [4.5, 2.0, 1.6], size_source: EgoSizeSource::Default, track_id: None },
        cameras: Vec::new(),
        frames,
        tracks: vec![Track { id: "7".into(), class: ObjectClass::Vehicle, states }],
        map,
    }
}

/// A quarter circle of radius 40 m rising 2 m, sampled every 0.5 m (with one duplicate point),
/// and a straight lane; a road edge beside the straight lane.
fn curved_map() -> Map {
    let arc: Vec<DVec3> = (0..=125)
        .map(|k| {
            let a = k as f64 * 0.5 / 40.0;
            DVec3::new(5000.0 + 40.0 * a.sin(), 2000.0 + 40.0 * (1.0 - a.cos()), 7.0 + 2.0 * a / 1.5625)
        })
        .collect();
    let mut arc_dup = arc.clone();
    arc_dup.insert(10, arc[10]);
    let straight = vec![DVec3::new(4990.0, 1995.0, 7.0), DVec3::new(5090.0, 1995.0, 7.5)];
    let edge = vec![DVec3::new(4990.0, 1993.0, 7.0), DVec3::new(5090.0, 1993.0, 7.5)];
    Map {
        lanes: vec![Polyline { id: 11, points: arc_dup }, Polyline { id: 12, points: straight }],
        road_edges: vec![Polyline { id: 21, points: edge }],
        road_lines: Vec::new(),
    }
}

fn schema() -> Option<PathBuf> {
    let path = match std::env::var_os("CARLA_GS_OPENDRIVE_XSD") {
        Some(p) => PathBuf::from(p),
        None => {
            let cache = std::env::var_os("XDG_CACHE_HOME")
                .map(PathBuf::from)
                .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))?;
            cache.join("carla-gs/schemas/opendrive-1.6.1/opendrive_16_core.xsd")
        }
    };
    path.exists().then_some(path)
}

/// Validates with xmllint against the OpenDRIVE 1.6.1 schema; `false` after printing `SKIP` when
/// it cannot; panics when the schema rejects the document.
fn validate(text: &str, label: &str) -> bool {
    let Some(schema) = schema() else {
        println!("SKIP: OpenDRIVE schema validation ({label}): schema not installed (run tools/setup.sh)");
        return false;
    };
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("roads.xodr");
    std::fs::write(&file, text).unwrap();
    let out = match Command::new("xmllint").arg("--noout").arg("--schema").arg(&schema).arg(&file).output() {
        Ok(out) => out,
        Err(e) => {
            println!("SKIP: OpenDRIVE schema validation ({label}): cannot run xmllint ({e})");
            return false;
        }
    };
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "the OpenDRIVE 1.6.1 schema rejects the export ({label}):\n{stderr}");
    true
}

fn assert_same(a: &RoadNetwork, b: &RoadNetwork) {
    let close = |x: f64, y: f64, tol: f64| (x - y).abs() <= tol;
    assert_eq!((a.name.as_str(), a.roads.len()), (b.name.as_str(), b.roads.len()));
    assert!((a.origin - b.origin).length() < 1e-6);
    for (r, q) in a.roads.iter().zip(&b.roads) {
        assert_eq!(
            (r.id, &r.name, r.geometry.len(), r.elevation.len()),
            (q.id, &q.name, q.geometry.len(), q.elevation.len())
        );
        assert!(close(r.length, q.length, 1e-6) && close(r.lane_offset, q.lane_offset, 1e-6));
        for (g, h) in r.geometry.iter().zip(&q.geometry) {
            assert!(close(g.s, h.s, 1e-6) && close(g.x, h.x, 1e-6) && close(g.y, h.y, 1e-6), "{g:?} {h:?}");
            assert!(close(g.hdg, h.hdg, 1e-8) && close(g.length, h.length, 1e-6), "{g:?} {h:?}");
        }
        for (e, f) in r.elevation.iter().zip(&q.elevation) {
            assert!(close(e.s, f.s, 1e-6) && close(e.a, f.a, 1e-6) && close(e.b, f.b, 1e-8), "{e:?} {f:?}");
        }
        let mut l1 = r.lanes.clone();
        let mut l2 = q.lanes.clone();
        l1.sort_by_key(|l| l.id);
        l2.sort_by_key(|l| l.id);
        assert_eq!(l1, l2);
    }
}

#[test]
fn lanes_and_edges_round_trip_and_lie_on_the_logged_polylines() {
    let map = curved_map();
    let scene = scene_with(Some(map.clone()));
    let origin = DVec3::new(5000.0, 2000.0, 0.0);
    let opts = XodrOptions { origin, date: Some("2025-01-31T12:00:00Z".into()), ..XodrOptions::default() };
    let built = build_road_network(&scene, &opts).unwrap();
    assert!(built.skipped.is_empty(), "{:?}", built.skipped);
    let net = &built.network;
    assert_eq!(net.roads.len(), 3);
    assert_eq!(net.roads[0].geometry.len(), 125, "the duplicate point is merged");
    assert_eq!(net.roads[2].lanes[0].kind, "border");
    let text = write_xodr(net).unwrap();
    assert!(text.contains("revMajor=\"1\" revMinor=\"6\""));
    validate(&text, "lanes and edges");
    let back = read_xodr(&text).unwrap();
    assert_same(net, &back);
    assert_eq!(back.date.as_deref(), Some("2025-01-31T12:00:00Z"));

    // Every logged vertex is on its lane's centre (the driving lane -1) at the vertex's s, in the
    // world frame once the origin is added back; the lane is 3.5 m wide around it.
    for (road, line) in back.roads.iter().zip(map.lanes.iter().chain(&map.road_edges)) {
        let mut s = 0.0;
        let mut prev: Option<DVec3> = None;
        for p in &line.points {
            if let Some(q) = prev {
                s += (p.truncate() - q.truncate()).length();
            }
            prev = Some(*p);
            let c = road.lane_center_at(-1, s).unwrap() + back.origin;
            assert!((c - *p).length() < 1e-4, "road {} s={s}: {c} vs {p}", road.name);
        }
        assert!((road.length - s).abs() < 1e-4);
    }
    assert_eq!(back.roads[0].lanes[0].width, 3.5);
    // The quarter circle ends heading north-west-ish: 1.5625 rad of turn, within one segment.
    let (_, hdg) = back.roads[0].reference_at(back.roads[0].length);
    assert!((hdg - 1.5625).abs() < 0.02, "{hdg}");
}

#[test]
fn a_scene_without_a_map_gets_a_flat_road_covering_every_logged_position() {
    let scene = scene_with(None);
    let net = build_road_network(&scene, &XodrOptions::default()).unwrap().network;
    assert_eq!(net.roads.len(), 1);
    let text = write_xodr(&net).unwrap();
    validate(&text, "flat road");
    let back = read_xodr(&text).unwrap();
    assert_same(&net, &back);
    let road = &back.roads[0];
    let (start, hdg) = road.reference_at(0.0);
    let dir = DVec2::from_angle(hdg);
    let right_t = road.lanes.iter().filter(|l| l.id < 0).map(|l| l.width).sum::<f64>();
    let left_t = road.lanes.iter().filter(|l| l.id > 0).map(|l| l.width).sum::<f64>();
    let mut points: Vec<DVec2> = scene.ego_series().iter().map(|p| p.position()).collect();
    points.extend(scene.tracks[0].states.iter().map(|s| s.center.truncate()));
    for p in points {
        let d = p - start;
        let (s, t) = (d.dot(dir), d.dot(dir.perp()));
        assert!(s > 1.0 && s < road.length - 1.0, "s {s} outside (0, {})", road.length);
        assert!(t > -right_t + 1.0 && t < left_t - 1.0, "t {t} outside ({}, {left_t})", -right_t);
    }
    // At the ego's ground height (its origin is on the ground here: z = 7).
    assert!((road.z_at(10.0) - 7.0).abs() < 1e-9);
    // Along the ego's travel direction (atan 0.3).
    assert!((hdg - 0.3f64.atan()).abs() < 1e-9);
}

#[test]
fn bad_files_and_options_name_what_is_wrong() {
    let scene = scene_with(Some(curved_map()));
    let net = build_road_network(&scene, &XodrOptions::default()).unwrap().network;
    let text = write_xodr(&net).unwrap();
    // A geometry moved 0.5 m: the reference line is broken.
    let first_x = format!("x=\"{}\"", export::xml::num(net.roads[0].geometry[3].x, 6));
    let moved = format!("x=\"{}\"", export::xml::num(net.roads[0].geometry[3].x + 0.5, 6));
    let broken = text.replacen(&first_x, &moved, 1);
    assert_ne!(broken, text);
    let e = read_xodr(&broken).unwrap_err().to_string();
    assert!(e.contains("road[0]/planView/geometry[3]") && e.contains("not continuous"), "{e}");
    let arc = text.replacen("<line/>", "<arc curvature=\"0.1\"/>", 1);
    let e = read_xodr(&arc).unwrap_err().to_string();
    assert!(e.contains("geometry[0]") && e.contains("<line>"), "{e}");
    let e = read_xodr(&text.replacen("<width sOffset=\"0\" a=\"3.5\"", "<width sOffset=\"0\" a=\"-3.5\"", 1))
        .unwrap_err()
        .to_string();
    assert!(e.contains("width[0]@a") && e.contains("positive"), "{e}");
    let e = read_xodr(&text[..text.find("</road>").unwrap()]).unwrap_err();
    assert!(matches!(e, ExportError::Truncated { .. }), "{e}");

    let bad = XodrOptions { lane_width_m: 0.0, ..XodrOptions::default() };
    let e = build_road_network(&scene, &bad).unwrap_err().to_string();
    assert!(e.contains("lane_width_m"), "{e}");
    // Issue 28 row 21: finite but absurd widths are outside the documented range too.
    for (lane, edge) in [(1e300, 0.3), (0.01, 0.3), (3.5, 1e9)] {
        let bad = XodrOptions { lane_width_m: lane, edge_width_m: edge, ..XodrOptions::default() };
        let e = build_road_network(&scene, &bad).unwrap_err().to_string();
        let field = if lane == 3.5 { "edge_width_m" } else { "lane_width_m" };
        assert!(e.starts_with(&format!("option `{field}`: must be a width from")), "{e}");
    }
    let bad = XodrOptions { flat_margin_m: 1e12, ..XodrOptions::default() };
    assert!(build_road_network(&scene, &bad).unwrap_err().to_string().contains("flat_margin_m"));
    let mut nan_map = curved_map();
    nan_map.road_edges[0].points[1].y = f64::NAN;
    let e = build_road_network(&scene_with(Some(nan_map)), &XodrOptions::default()).unwrap_err().to_string();
    assert!(e.contains("map.road_edges[0] (id 21) point 1"), "{e}");
}

#[test]
fn real_womd_map_round_trips() {
    let Some(path) = ingest::shared::waymo_file("womd_scenario_input.tfrecord") else { return };
    let scenes = ingest::read_scenes(&[path], ingest::Expect::Scenario, &indicatif::ProgressBar::hidden()).unwrap();
    let scene = &scenes[0];
    let map = scene.map.as_ref().expect("the WOMD scenario has a map");
    let origin = scene.frames[0].world_from_ego.translation().round();
    let built = build_road_network(scene, &XodrOptions { origin, ..XodrOptions::default() }).unwrap();
    let net = &built.network;
    assert_eq!(net.roads.len() + built.skipped.len(), map.lanes.len() + map.road_edges.len());
    let text = write_xodr(net).unwrap();
    validate(&text, "WOMD");
    let back = read_xodr(&text).unwrap();
    assert_same(net, &back);
    println!(
        "WOMD OpenDRIVE: {} roads ({} lanes, {} edges), {} skipped, {} bytes",
        net.roads.len(),
        map.lanes.len(),
        map.road_edges.len(),
        built.skipped.len(),
        text.len()
    );
}
