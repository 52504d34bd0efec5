//! OpenSCENARIO export of a hand-made case: schema validation with xmllint against the ASAM
//! OpenSCENARIO 1.2 XSD (skipped with a message when xmllint or the schema is missing), round
//! trip of every entity's vertices, the log clock and boxes, and errors on bad input.

use export::xosc::{read_xosc, write_xosc, write_xosc_file, EntityKind, XoscOptions, XoscVersion, ADVERSARY, EGO};
use export::ExportError;
use scene::executed::{ActorInfo, ExecutedStep, Validity, EXECUTED_FORMAT};
use scene::frames::wrap_angle;
use scene::glam::DVec3;
use scene::motion::{sample_series, Pose2};
use scene::plan::PLAN_FORMAT;
use scene::{
    Behavior, Ego, EgoSizeSource, Executed, Frame, ObjectClass, Plan, Risk, Scene, Source, SourceKind, Track,
    TrackState, Transform3, Waypoint, Zone, ZoneLayout,
};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A Unix-time log start, as in Waymo logs: the clock must survive the export exactly.
const T0: f64 = 1_557_855_600.25;
const GROUND_Z: f64 = 12.3;

fn ego_pose(t: f64) -> Pose2 {
    // 10 m/s on a gentle left curve.
    let s = t - T0;
    Pose2 { t, x: 100.0 + 10.0 * s, y: -50.0 + 0.2 * s * s, heading: (0.4 * s).atan() }
}

fn track(id: &str, class: ObjectClass, size: [f64; 3], frames: &[Frame], pose: impl Fn(f64) -> Option<Pose2>) -> Track {
    let states = frames
        .iter()
        .filter_map(|f| {
            let p = pose(f.timestamp_s)?;
            Some(TrackState {
                frame: f.index,
                center: DVec3::new(p.x, p.y, GROUND_Z + size[2] / 2.0),
                heading: p.heading,
                size_lwh: size,
                velocity: None,
                valid: true,
                motion: None,
            })
        })
        .collect();
    Track { id: id.into(), class, states }
}

/// The adversary's logged path: the lane to the ego's left, slowly merging.
fn adversary_log(t: f64) -> Pose2 {
    let s = t - T0;
    Pose2 { t, x: 108.0 + 11.0 * s, y: -46.5 - 0.3 * s, heading: (-0.3f64).atan2(11.0) }
}

fn sample_scene() -> Scene {
    let frames: Vec<Frame> = (0..=60)
        .map(|i| {
            let t = T0 + 0.1 * i as f64;
            let p = ego_pose(t);
            Frame {
                index: i,
                timestamp_s: t,
                world_from_ego: Transform3::from_yaw_translation(p.heading, DVec3::new(p.x, p.y, GROUND_Z)),
                images: Vec::new(),
                lidar: None,
            }
        })
        .collect();
    let car = [4.6, 1.9, 1.5];
    let rel = |t: f64| t - T0;
    let tracks = vec![
        track("adv-7", ObjectClass::Vehicle, car, &frames, |t| Some(adversary_log(t))),
        // Seen for 2 s, lost for 2 s, seen again: two runs.
        track("car:12", ObjectClass::Vehicle, car, &frames, |t| {
            let s = rel(t);
            (!(1.95..4.05).contains(&s)).then_some(Pose2 { t, x: 140.0 - 8.0 * s, y: -43.0, heading: 3.1 })
        }),
        track("ped/3", ObjectClass::Pedestrian, [0.6, 0.6, 1.8], &frames, |t| {
            let s = rel(t);
            (1.0..=4.0).contains(&s).then_some(Pose2 { t, x: 130.0, y: -55.0 + 1.2 * s, heading: 1.57 })
        }),
        track("sign 9", ObjectClass::Sign, [0.1, 0.8, 2.5], &frames, |t| {
            Some(Pose2 { t, x: 125.0, y: -58.0, heading: 0.0 })
        }),
        track("bike<&>", ObjectClass::Cyclist, [1.8, 0.6, 1.7], &frames, |t| {
            Some(Pose2 { t, x: 90.0 + 5.0 * rel(t), y: -52.5, heading: 0.0 })
        }),
        // Two ids that sanitise to the same name.
        track("a-b", ObjectClass::Other, [1.0, 1.0, 1.0], &frames, |t| {
            Some(Pose2 { t, x: 150.0, y: -40.0, heading: 0.0 })
        }),
        track("a_b", ObjectClass::Vehicle, car, &frames, |t| Some(Pose2 { t, x: 160.0, y: -40.0, heading: 0.0 })),
        // Seen once only: nothing to follow.
        track("blip", ObjectClass::Vehicle, car, &frames, |t| {
            ((rel(t) - 2.0).abs() < 1e-6).then_some(Pose2 { t, x: 0.0, y: 0.0, heading: 0.0 })
        }),
        // Gone before the case starts.
        track("early", ObjectClass::Vehicle, car, &frames, |t| {
            (rel(t) < 0.3).then_some(Pose2 { t, x: 0.0, y: 0.0, heading: 0.0 })
        }),
    ];
    Scene {
        format: scene::SCENE_FORMAT.into(),
        name: "hand-made".into(),
        source: Source { kind: SourceKind::Synthetic, files: Vec::new(), id: "test".into() },
        ego: Ego { size_lwh: [4.5, 2.0, 1.6], size_source: EgoSizeSource::Default, track_id: None },
        cameras: Vec::new(),
        frames,
        tracks,
        map: None,
    }
}

/// A case from 0.5 s to 4.5 s after the log start, control steps 0.05 s apart; the adversary
/// leaves its logged lane towards the ego (cut-in).
fn sample_executed(scene: &Scene) -> Executed {
    let start = T0 + 1.5;
    let plan = Plan {
        format: PLAN_FORMAT.into(),
        scene: scene.name.clone(),
        behavior: Behavior::SuddenCutIn,
        adversary_track: "adv-7".into(),
        target_zone: Zone::Front,
        zone_layout: ZoneLayout::Adjacent,
        start_time_s: start,
        ttc_s: 3.0,
        risk: Risk::High,
        agent: "test".into(),
        reasoning: String::new(),
        dt_s: 0.1,
        waypoints: (0..=30)
            .map(|k| {
                let p = adversary_log(start + 0.1 * k as f64);
                Waypoint { t: p.t, x: p.x, y: p.y - 0.1 * k as f64 }
            })
            .collect(),
        target: None,
        seed: None,
        path: None,
        inserted: None,
    };
    let ego = scene.ego_series();
    let times: Vec<f64> = (0..=80).map(|k| T0 + 0.5 + 0.05 * k as f64).collect();
    let steps = times
        .iter()
        .map(|&t| {
            let p = adversary_log(t);
            let cut = (t - start).max(0.0);
            ExecutedStep {
                t,
                x: p.x,
                y: p.y - 0.8 * cut * cut,
                heading: wrap_angle(p.heading - 0.3 * cut),
                speed: 11.0,
                yaw_rate: 0.0,
                accel_long: 0.0,
                accel_lat: 0.0,
                steering_angle: 0.0,
                steer: 0.0,
                throttle: 0.0,
                brake: 0.0,
                ref_x: p.x,
                ref_y: p.y,
            }
        })
        .collect();
    let e = Executed {
        format: EXECUTED_FORMAT.into(),
        scene: scene.name.clone(),
        backend: "test".into(),
        plan,
        control_dt_s: 0.05,
        physics_dt_s: 0.01,
        ego: ActorInfo { track_id: None, size_lwh: scene.ego.size_lwh },
        adversary: ActorInfo { track_id: Some("adv-7".into()), size_lwh: [4.6, 1.9, 1.5] },
        steps,
        ego_path: times.iter().map(|&t| sample_series(&ego, t).unwrap()).collect(),
        first_contact: None,
        validity: Validity {
            valid: true,
            reasons: Vec::new(),
            max_tracking_error_m: 0.0,
            friction_limit_s: 0.0,
            max_abs_accel_lat: 0.0,
            road_checked: false,
        },
        resampled: Vec::new(),
    };
    e.validate().unwrap();
    e
}

fn opts(include_others: bool) -> XoscOptions {
    XoscOptions { include_others, date: Some("2025-01-31T12:00:00Z".into()), ..XoscOptions::default() }
}

fn schema_path(v: XoscVersion) -> PathBuf {
    let name = match v {
        XoscVersion::V1_0 => "OpenSCENARIO_1_0.xsd",
        XoscVersion::V1_2 => "OpenSCENARIO_1_2.xsd",
    };
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/schemas").join(name)
}

/// Validates `text` with xmllint against the OpenSCENARIO 1.2 schema. `false` (after printing
/// `SKIP: ...`) when xmllint or the schema is not available; panics when the schema rejects it.
fn validate(text: &str, label: &str) -> bool {
    validate_as(XoscVersion::V1_2, text, label)
}

/// [`validate`] against the schema of version `v`.
fn validate_as(v: XoscVersion, text: &str, label: &str) -> bool {
    let schema = schema_path(v);
    if !schema.exists() {
        println!("SKIP: schema validation ({label}): {} not found", schema.display());
        return false;
    }
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("case.xosc");
    std::fs::write(&file, text).unwrap();
    let out = match Command::new("xmllint").arg("--noout").arg("--schema").arg(&schema).arg(&file).output() {
        Ok(out) => out,
        Err(e) => {
            println!("SKIP: schema validation ({label}): cannot run xmllint ({e}); install libxml2-utils");
            return false;
        }
    };
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "the OpenSCENARIO {v:?} schema rejects the export ({label}):\n{stderr}");
    assert!(stderr.contains("validates"), "{stderr}");
    true
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

#[test]
fn export_validates_against_the_schema_with_and_without_others() {
    let scene = sample_scene();
    let executed = sample_executed(&scene);
    for include_others in [false, true] {
        let text = write_xosc(&scene, &executed, &opts(include_others)).unwrap();
        validate(&text, &format!("include_others={include_others}"));
    }
    // With an OpenDRIVE file referenced.
    let with_road = XoscOptions { road_network: Some("roads/case.xodr".into()), ..opts(false) };
    let text = write_xosc(&scene, &executed, &with_road).unwrap();
    assert!(text.contains("<LogicFile filepath=\"roads/case.xodr\"/>"));
    validate(&text, "road_network");
}

#[test]
fn version_1_0_validates_against_its_schema_and_reads_back_the_same_case() {
    let scene = sample_scene();
    let executed = sample_executed(&scene);
    for include_others in [false, true] {
        let o =
            XoscOptions { version: XoscVersion::V1_0, road_network: Some("case.xodr".into()), ..opts(include_others) };
        let text = write_xosc(&scene, &executed, &o).unwrap();
        assert!(text.contains("revMinor=\"0\"") && !text.contains("TrajectoryRef") && !text.contains("greaterOrEqual"));
        validate_as(XoscVersion::V1_0, &text, &format!("1.0, include_others={include_others}"));
        // The 1.2 file of the same case does not pass the 1.0 schema (so the check above can fail).
        let v12 = write_xosc(
            &scene,
            &executed,
            &XoscOptions { road_network: Some("case.xodr".into()), ..opts(include_others) },
        )
        .unwrap();
        assert!(v12.contains("TrajectoryRef") && v12.contains("greaterOrEqual"));
        // Both versions read back as the same case on the log clock.
        let (a, b) = (read_xosc(&text).unwrap(), read_xosc(&v12).unwrap());
        assert_eq!(a.log_start_time, b.log_start_time);
        assert_eq!(
            (a.scene.clone(), a.behavior.clone(), a.adversary_track.clone()),
            (b.scene, b.behavior, b.adversary_track)
        );
        // The same entities; the 1.0 file's reference point is the box centre, the 1.2 file's
        // the rear axle, and both read back as box centres (to the files' 1 um).
        assert_eq!(a.entities.len(), b.entities.len());
        for (ea, eb) in a.entities.iter().zip(&b.entities) {
            assert_eq!((&ea.name, ea.kind, &ea.properties), (&eb.name, eb.kind, &eb.properties));
            assert_eq!(ea.bounding_box.size_lwh, eb.bounding_box.size_lwh);
            assert_eq!(ea.bounding_box.center[0], 0.0);
            let behind = if ea.kind == EntityKind::Vehicle { 0.3 * ea.bounding_box.size_lwh[0] } else { 0.0 };
            assert!(close(eb.bounding_box.center[0], behind, 1e-6), "{} {:?}", eb.name, eb.bounding_box);
            assert_eq!(ea.vertices.len(), eb.vertices.len());
            let pairs = ea.vertices.iter().zip(&eb.vertices).chain(ea.initial.iter().zip(&eb.initial));
            for (p, q) in pairs {
                assert!(p.t == q.t && p.z == q.z && p.h == q.h, "{} {p:?} {q:?}", ea.name);
                assert!(close(p.x, q.x, 3e-6) && close(p.y, q.y, 3e-6), "{} {p:?} {q:?}", ea.name);
            }
        }
    }
    assert_eq!("1.0".parse::<XoscVersion>(), Ok(XoscVersion::V1_0));
    assert!("1.1".parse::<XoscVersion>().unwrap_err().contains("1.0 or 1.2"));
}

#[test]
fn round_trip_recovers_the_case_on_the_log_clock() {
    let scene = sample_scene();
    let executed = sample_executed(&scene);
    let text = write_xosc(&scene, &executed, &opts(false)).unwrap();
    assert_eq!(text, write_xosc(&scene, &executed, &opts(false)).unwrap(), "same inputs, same bytes");
    let case = read_xosc(&text).unwrap();
    assert_eq!(case.log_start_time, executed.steps[0].t, "the log clock is exact");
    assert_eq!(case.scene.as_deref(), Some("hand-made"));
    assert_eq!(case.behavior.as_deref(), Some("sudden_cut_in"));
    assert_eq!(case.adversary_track.as_deref(), Some("adv-7"));
    assert!(case.description.contains("sudden_cut_in") && case.description.contains("hand-made"));
    assert_eq!(case.entities.len(), 2);

    let adv = case.entity(ADVERSARY).unwrap();
    assert_eq!(adv.kind, EntityKind::Vehicle);
    assert_eq!(adv.category, "car");
    assert_eq!(adv.track_id(), Some("adv-7"));
    assert_eq!(adv.bounding_box.size_lwh, [4.6, 1.9, 1.5]);
    // 1.2: the reference point is the rear axle, 0.3 length behind the box centre; the reader
    // gives box centres back.
    assert!(close(adv.bounding_box.center[0], 0.3 * 4.6, 1e-6), "{:?}", adv.bounding_box);
    assert_eq!(adv.bounding_box.center[1..], [0.0, 0.75]);
    assert_eq!(adv.vertices.len(), executed.steps.len());
    for (v, s) in adv.vertices.iter().zip(&executed.steps) {
        assert!(close(v.t, s.t, 1e-6), "t {} vs {}", v.t, s.t);
        assert!(close(v.x, s.x, 0.01) && close(v.y, s.y, 0.01), "{v:?} vs {s:?}");
        assert!(wrap_angle(v.h - s.heading).abs() < 1e-4, "{v:?} vs {s:?}");
        // Ground contact: logged centre z minus half the logged height.
        assert!(close(v.z, GROUND_Z, 1e-6), "{v:?}");
    }
    let initial = adv.initial.unwrap();
    assert!(close(initial.x, executed.steps[0].x, 1e-5) && close(initial.t, executed.steps[0].t, 1e-6));

    let ego = case.entity(EGO).unwrap();
    assert_eq!(ego.bounding_box.size_lwh, [4.5, 2.0, 1.6]);
    assert_eq!(ego.vertices.len(), executed.ego_path.len());
    for (v, p) in ego.vertices.iter().zip(&executed.ego_path) {
        assert!(close(v.t, p.t, 1e-6) && close(v.x, p.x, 0.01) && close(v.y, p.y, 0.01), "{v:?} vs {p:?}");
        assert!(wrap_angle(v.h - p.heading).abs() < 1e-4);
        // The ego origin of a scene without an ego track is on the ground.
        assert!(close(v.z, GROUND_Z, 1e-6), "{v:?}");
    }
}

#[test]
fn other_actors_follow_their_logged_poses_where_tracked() {
    let scene = sample_scene();
    let executed = sample_executed(&scene);
    let case = read_xosc(&write_xosc(&scene, &executed, &opts(true)).unwrap()).unwrap();
    let names: Vec<&str> = case.entities.iter().map(|e| e.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "ego",
            "adversary",
            "actor_car_12",
            "actor_ped_3",
            "actor_sign_9",
            "actor_bike___",
            "actor_a_b",
            "actor_a_b_2"
        ]
    );
    let step_times: Vec<f64> = executed.steps.iter().map(|s| s.t).collect();
    for e in &case.entities[2..] {
        let track = scene.track(e.track_id().unwrap()).unwrap();
        assert!(e.vertices.len() >= 2, "{}", e.name);
        for v in &e.vertices {
            assert!(step_times.iter().any(|t| close(*t, v.t, 1e-6)), "{} vertex off the step times", e.name);
            let p = scene.track_pose_at(track, v.t).unwrap();
            assert!(close(v.x, p.x, 1e-5) && close(v.y, p.y, 1e-5) && close(v.z, GROUND_Z, 1e-6), "{}", e.name);
        }
    }
    let kind = |n: &str| case.entity(n).unwrap().kind;
    assert_eq!(kind("actor_ped_3"), EntityKind::Pedestrian);
    assert_eq!(kind("actor_sign_9"), EntityKind::MiscObject);
    assert_eq!(case.entity("actor_bike___").unwrap().category, "bicycle");
    assert_eq!(case.entity("actor_bike___").unwrap().track_id(), Some("bike<&>"));
    assert_eq!(case.entity("actor_a_b").unwrap().track_id(), Some("a-b"));
    assert_eq!(case.entity("actor_a_b_2").unwrap().track_id(), Some("a_b"));
    // The car lost from 1.95 s to 4.05 s after the log start: vertices up to 1.9 s and from
    // 4.1 s (the case runs from 0.5 s to 4.5 s).
    let car = case.entity("actor_car_12").unwrap();
    let rel: Vec<f64> = car.vertices.iter().map(|v| v.t - T0).collect();
    assert!(close(rel[0], 0.5, 1e-6) && close(*rel.last().unwrap(), 4.5, 1e-6));
    assert!(!rel.iter().any(|s| (1.91..4.09).contains(s)), "{rel:?}");
    // The pedestrian appears 1 s after the log start: its Init pose is its first tracked pose.
    let ped = case.entity("actor_ped_3").unwrap();
    assert!(close(ped.vertices[0].t - T0, 1.0, 1e-6));
    assert!(close(ped.initial.unwrap().y, ped.vertices[0].y, 1e-9));
}

#[test]
fn writes_the_file_atomically() {
    let scene = sample_scene();
    let executed = sample_executed(&scene);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("out/case.xosc");
    write_xosc_file(&path, &scene, &executed, &opts(true)).unwrap();
    let text = std::fs::read_to_string(&path).unwrap();
    assert_eq!(text, write_xosc(&scene, &executed, &opts(true)).unwrap());
    assert_eq!(std::fs::read_dir(path.parent().unwrap()).unwrap().count(), 1, "no temporary file left");
}

#[test]
fn refuses_cases_it_cannot_export() {
    let scene = sample_scene();
    let executed = sample_executed(&scene);
    let mut other = scene.clone();
    other.name = "elsewhere".into();
    assert!(matches!(write_xosc(&other, &executed, &opts(false)), Err(ExportError::WrongScene { .. })));
    let mut bad = executed.clone();
    bad.steps[3].x = f64::NAN;
    let e = write_xosc(&scene, &bad, &opts(false)).unwrap_err();
    assert!(matches!(e, ExportError::InvalidCase { .. }) && e.to_string().contains("steps[3]"), "{e}");
}

#[test]
fn bad_input_gives_errors_that_name_the_element() {
    let scene = sample_scene();
    let executed = sample_executed(&scene);
    let text = write_xosc(&scene, &executed, &opts(true)).unwrap();

    // Truncated anywhere: an error (never a panic) naming an element of the document.
    for cut in [text.len() / 2, text.len() * 9 / 10, text.len() - 3, 200, 60] {
        let e = read_xosc(&text[..cut]).unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("OpenSCENARIO"), "cut at {cut}: {msg}");
    }
    let e = read_xosc(&text[..text.len() / 2]).unwrap_err();
    assert!(matches!(e, ExportError::Truncated { .. }), "{e}");
    assert!(e.to_string().contains("truncated"), "{e}");

    // A non-numeric vertex time.
    let first_time = text.find("<Vertex time=\"").unwrap();
    let bad =
        format!("{}<Vertex time=\"soon\"{}", &text[..first_time], &text[first_time + 14..].split_once('"').unwrap().1);
    let e = read_xosc(&bad).unwrap_err().to_string();
    assert!(e.contains("Vertex[0]@time") && e.contains("expected a number") && e.contains("`soon`"), "{e}");

    // Other breakage.
    let e =
        read_xosc(&text.replace("name=\"LogStartTime\"", "name=\"Other\"").replace("carla_gs.log_start_time_s", "x"))
            .unwrap_err()
            .to_string();
    assert!(e.contains("LogStartTime"), "{e}");
    let e = read_xosc(&text.replace("x=\"", "x=\"nan")).unwrap_err().to_string();
    assert!(e.contains("@x"), "{e}");
    let e = read_xosc(&text.replacen("entityRef=\"adversary\"", "entityRef=\"ghost\"", 1)).unwrap_err().to_string();
    assert!(e.contains("`ghost`"), "{e}");
    let e = read_xosc(&text.replace("\"absolute\"", "\"relative\"")).unwrap_err().to_string();
    assert!(e.contains("Timing@domainAbsoluteRelative"), "{e}");
    for junk in [
        "",
        "not xml at all",
        "<OpenSCENARIO/>",
        "<Other/>",
        "<OpenSCENARIO><FileHeader revMajor=\"2\"/></OpenSCENARIO>",
    ] {
        assert!(read_xosc(junk).is_err(), "{junk}");
    }
}
