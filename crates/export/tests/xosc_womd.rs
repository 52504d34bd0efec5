//! OpenSCENARIO export of a real case: the shared WOMD scenario where the ego drives, a vehicle
//! cutting in executed by the physics stage (`sim`), every other logged actor included. The file
//! must pass the OpenSCENARIO 1.2 schema and give back the executed steps. Skips (printing
//! `SKIP: ...`) without the shared data, xmllint or the schema.

use export::xosc::{read_xosc, write_xosc, XoscOptions, ADVERSARY, EGO};
use scene::frames::wrap_angle;
use scene::plan::{Plan, PLAN_FORMAT};
use scene::{Behavior, Risk, Scene, Waypoint, Zone, ZoneLayout};
use std::path::Path;
use std::process::Command;

/// A plan for the first vehicle that moves at least 10 m in [t0, t0 + 3 s]: its logged path
/// with a smooth 2 m lateral shift (a lane-change-like reference).
fn plan_for(scene: &Scene) -> Option<Plan> {
    let t0 = scene.frames[20].timestamp_s;
    let t1 = t0 + 3.0;
    let vehicles = scene
        .tracks
        .iter()
        .filter(|t| t.class == scene::ObjectClass::Vehicle && Some(&t.id) != scene.ego.track_id.as_ref());
    for tr in vehicles {
        let (Some(a), Some(b)) = (scene.track_pose_at(tr, t0), scene.track_pose_at(tr, t1)) else { continue };
        if a.position().distance(b.position()) < 10.0 {
            continue;
        }
        let waypoints = (0..=30)
            .map(|k| {
                let t = t0 + k as f64 * 0.1;
                let p = scene.track_pose_at(tr, t)?;
                let shift = 2.0 * (0.5 - 0.5 * (std::f64::consts::PI * k as f64 / 30.0).cos());
                Some(Waypoint { t, x: p.x - shift * p.heading.sin(), y: p.y + shift * p.heading.cos() })
            })
            .collect::<Option<Vec<_>>>()?;
        return Some(Plan {
            format: PLAN_FORMAT.into(),
            scene: scene.name.clone(),
            behavior: Behavior::SuddenCutIn,
            adversary_track: tr.id.clone(),
            target_zone: Zone::Front,
            zone_layout: ZoneLayout::Adjacent,
            start_time_s: t0,
            ttc_s: 3.0,
            risk: Risk::Medium,
            agent: "test".into(),
            reasoning: "logged path with a 2 m lateral shift".into(),
            dt_s: 0.1,
            waypoints,
            target: None,
            seed: None,
            path: None,
            inserted: None,
        });
    }
    None
}

fn xmllint(text: &str) -> Option<Result<(), String>> {
    let schema = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/schemas/OpenSCENARIO_1_2.xsd");
    if !schema.exists() {
        println!("SKIP: schema validation: {} not found", schema.display());
        return None;
    }
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("case.xosc");
    std::fs::write(&file, text).unwrap();
    match Command::new("xmllint").arg("--noout").arg("--schema").arg(&schema).arg(&file).output() {
        Ok(out) if out.status.success() => Some(Ok(())),
        Ok(out) => Some(Err(String::from_utf8_lossy(&out.stderr).chars().take(4000).collect())),
        Err(e) => {
            println!("SKIP: schema validation: cannot run xmllint ({e})");
            None
        }
    }
}

#[test]
fn real_womd_case_exports_valid_openscenario() {
    let Some(path) = ingest::shared::waymo_file("womd_scenario_input.tfrecord") else { return };
    let scenes = ingest::read_scenes(&[path], ingest::Expect::Scenario, &indicatif::ProgressBar::hidden()).unwrap();
    let scene = &scenes[0];
    let plan = plan_for(scene).expect("a moving vehicle in the shared scenario");
    let executed = sim::simulate(scene, &plan, &sim::RolloutConfig::default()).unwrap();

    for include_others in [false, true] {
        let opts = XoscOptions { include_others, date: Some("2025-01-31T12:00:00Z".into()), ..Default::default() };
        let text = write_xosc(scene, &executed, &opts).unwrap();
        if let Some(Err(e)) = xmllint(&text) {
            panic!("the OpenSCENARIO 1.2 schema rejects the WOMD export (include_others={include_others}):\n{e}");
        }
        let case = read_xosc(&text).unwrap();
        assert_eq!(case.log_start_time, executed.steps[0].t);
        let adv = case.entity(ADVERSARY).unwrap();
        assert_eq!(adv.vertices.len(), executed.steps.len());
        for (v, s) in adv.vertices.iter().zip(&executed.steps) {
            assert!((v.t - s.t).abs() < 1e-6 && (v.x - s.x).abs() < 0.01 && (v.y - s.y).abs() < 0.01, "{v:?} {s:?}");
            assert!(wrap_angle(v.h - s.heading).abs() < 1e-4);
        }
        let ego = case.entity(EGO).unwrap();
        for (v, p) in ego.vertices.iter().zip(&executed.ego_path) {
            assert!((v.t - p.t).abs() < 1e-6 && (v.x - p.x).abs() < 0.01 && (v.y - p.y).abs() < 0.01);
        }
        // WOMD puts the ego origin at the sdc box centre: z is the ground below it.
        let ego_track = scene.track(scene.ego.track_id.as_deref().unwrap()).unwrap();
        let s0 = ego_track
            .valid_states()
            .find(|s| (scene.frames[s.frame].timestamp_s - executed.steps[0].t).abs() < 1e-6)
            .expect("the rollout starts on a logged frame");
        let want = s0.center.z - scene.ego.size_lwh[2] / 2.0;
        assert!((ego.vertices[0].z - want).abs() < 0.05, "{} vs {want}", ego.vertices[0].z);
        if include_others {
            println!(
                "WOMD export: {} entities, {} vertices, {} bytes",
                case.entities.len(),
                case.entities.iter().map(|e| e.vertices.len()).sum::<usize>(),
                text.len()
            );
            assert!(case.entities.len() > 20, "only {} entities", case.entities.len());
        } else {
            assert_eq!(case.entities.len(), 2);
        }
    }
}
