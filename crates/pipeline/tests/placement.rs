//! The adversary in the rendered video is where the executed trajectory says, and `run` writes a
//! case other simulators can replay.
//!
//! A synthetic street is generated and a real corner case made on it (planner, vehicle dynamics,
//! PID). The model's actors are boxes of opaque Gaussians filling their tracked boxes, so what
//! is measured is the placement chain (executed steps -> back-projection -> composition ->
//! camera at an interpolated ego pose), not how completely training saw a vehicle. The box of the
//! executed pose, projected, must match the actor-only render's alpha (IoU > 0.8) at several
//! instants, one of them more than 3 m from the logged box; the logged box at that instant must
//! not (a check that can fail).

use cases::spec::{AgentName, T0Spec};
use pipeline::case::{select_case, CaseRequest, T0Choice};
use recon::backend::Cpu;
use recon::model::{Actor, SceneModel};
use recon::sky::Sky;
use render::backproject::Backprojection;
use render::placement::{box_mask, check_best_camera, check_times, iou};
use scene::Behavior;
use splat::Gaussians;
use std::path::Path;

/// A `n x n x n` grid of opaque Gaussians filling a box of `size` (box frame, centred).
fn box_of_gaussians(size: [f64; 3], colour: [f64; 3]) -> Gaussians {
    let n = 10;
    let mut g = splat::Gaussians::empty(0);
    for i in 0..n {
        for j in 0..n {
            for k in 0..n {
                let f = |a: usize, s: f64| (a as f64 + 0.5) / n as f64 * s - s / 2.0;
                g.means.push([f(i, size[0]), f(j, size[1]), f(k, size[2])]);
                g.log_scales.push(std::array::from_fn(|a| (size[a] / n as f64 * 0.35).ln()));
                g.rotations.push([1.0, 0.0, 0.0, 0.0]);
                g.opacity_logits.push(6.0);
                // Degree-0 SH of a colour: c = 0.5 + C0 * dc.
                g.sh.extend(colour.map(|c| (c - 0.5) / 0.282_094_791_773_878_14));
            }
        }
    }
    g
}

fn synth_scene(dir: &Path) -> scene::Scene {
    let cfg =
        synth::SynthConfig { frames: 60, cameras: 3, width: 192, height: 128, seed: 4, force: true, preview: false };
    synth::synthesize(&cfg, dir, &mut |_, _| {}).expect("synthesize");
    scene::load_scene(dir).expect("load scene")
}

fn box_model(scene: &scene::Scene) -> SceneModel {
    let actors = scene
        .tracks
        .iter()
        .map(|t| {
            let size = t.median_size_lwh();
            Actor { track_id: t.id.clone(), size_lwh: size, gaussians: box_of_gaussians(size, [0.8, 0.2, 0.2]) }
        })
        .collect();
    SceneModel { antialiased: false, background: splat::Gaussians::empty(0), actors, sky: Sky::new(4, [0.5, 0.6, 0.8]) }
}

#[test]
fn the_adversary_is_drawn_at_its_executed_pose() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = synth_scene(&tmp.path().join("scene"));
    let model = box_model(&scene);
    let req = CaseRequest {
        behavior: Behavior::SuddenBraking,
        agent: AgentName::Planner,
        adversary: None,
        zone: None,
        ttc_s: None,
        insert: Default::default(),
        seed: 0,
        seeds_per_t0: 1,
        refine_rounds: 0,
        window: pipeline::case::rendered_window(),
        fallback_window: None,
    };
    let sel = select_case(&scene, &req, &T0Choice::Search(T0Spec::Every(0.5)), None);
    let (result, executed, _) = sel.chosen.expect("a sudden-braking case on the synthetic street");
    assert!(result.best().unwrap().metrics.validity.valid, "the case is physically valid");
    let adversary = Backprojection::new(&scene, &executed).unwrap();
    let times = check_times(&scene, &adversary, executed.plan.start_time_s, 5);
    let mut judged = 0;
    let mut far = None;
    for &t in &times {
        let Some((p, _picture)) = check_best_camera(&Cpu, &model, &scene, &adversary, t, 2.0).unwrap() else {
            continue;
        };
        println!(
            "t={:.2} {} IoU {:.3} box {} px, {:?} m from the log",
            p.t, p.camera, p.iou, p.box_pixels, p.offset_from_log_m
        );
        assert!(p.iou > 0.8, "t = {t:.2}: IoU {:.3} <= 0.8", p.iou);
        judged += 1;
        if p.offset_from_log_m.is_some_and(|d| d > 3.0) {
            far = Some(p);
        }
    }
    assert!(judged >= 3, "only {judged} of {} instants could be judged", times.len());
    let far = far.expect("an instant more than 3 m from the logged box");
    // Control: at that instant the logged box does not match what was drawn.
    let cam = render::video::camera_at(&scene, &far.camera, far.t, 2.0).unwrap();
    let track = scene.track(&adversary.track_id).unwrap();
    let logged = recon::pose::box_pose_at(&scene, track, far.t).unwrap();
    let drawn = adversary.pose_at(&scene, far.t).unwrap();
    let size = model.actors.iter().find(|a| a.track_id == adversary.track_id).unwrap().size_lwh;
    let (a, b) = (box_mask(&cam, &logged, size).unwrap(), box_mask(&cam, &drawn, size).unwrap());
    let control = iou(&a, &b);
    println!("logged vs executed box at t={:.2}: IoU {control:.3}", far.t);
    assert!(control < 0.6, "the logged box overlaps the executed one too much ({control:.3}) to tell them apart");
}

#[test]
fn run_writes_a_replayable_case() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = synth_scene(&tmp.path().join("scene"));
    let model = box_model(&scene);
    let out = tmp.path().join("run");
    let render = pipeline::run::RenderSettings {
        layouts: vec!["compare:FRONT".into()],
        fps: 10.0,
        scale: 0.5,
        ..Default::default()
    };
    let inputs = pipeline::run::RunInputs { scene: &scene, model: &model, backend: &Cpu, render: &render, out: &out };
    let req = CaseRequest {
        behavior: Behavior::SuddenBraking,
        agent: AgentName::Planner,
        adversary: Some("lead-1".into()),
        zone: None,
        ttc_s: None,
        insert: Default::default(),
        seed: 0,
        seeds_per_t0: 1,
        refine_rounds: 0,
        window: pipeline::case::rendered_window(),
        fallback_window: None,
    };
    let s = pipeline::run::run(&inputs, &req, &T0Choice::At(0.5), None, &indicatif::ProgressBar::hidden()).unwrap();
    let plan = &s.result.as_ref().expect("a case").best().unwrap().plan;
    assert_eq!(plan.adversary_track, "lead-1", "--adversary is respected");
    for f in ["scenario.json", "executed.json", "metrics.json", "scenario.xosc", "scenario.xodr", "run.json"] {
        assert!(out.join(f).is_file(), "{f} written");
    }
    // The OpenSCENARIO file names the OpenDRIVE file written beside it, which reads back.
    let xosc = std::fs::read_to_string(out.join("scenario.xosc")).unwrap();
    assert!(xosc.contains("<LogicFile filepath=\"scenario.xodr\"/>"), "RoadNetwork names the roads");
    export::read_xodr(&std::fs::read_to_string(out.join("scenario.xodr")).unwrap()).expect("the roads read back");
    let v = &s.videos[0].output;
    assert!(v.frames > 10 && v.path.exists(), "video {v:?}");
    // The OpenSCENARIO file re-read gives back the executed adversary within 1 cm.
    let executed = scene::executed::load_executed(&out.join("executed.json")).unwrap();
    let text = std::fs::read_to_string(out.join("scenario.xosc")).unwrap();
    let case = export::read_xosc(&text).unwrap();
    let adv = case.entity(export::xosc::ADVERSARY).expect("adversary entity");
    assert_eq!(adv.vertices.len(), executed.steps.len());
    for (v, s) in adv.vertices.iter().zip(&executed.steps) {
        assert!((v.t - s.t).abs() < 1e-6 && (v.x - s.x).hypot(v.y - s.y) < 0.01, "{v:?} vs {s:?}");
    }
    // A second --adversary that is no vehicle near the ego gives no case, with the reason kept.
    let req2 = CaseRequest { adversary: Some("no-such-track".into()), ..req };
    let s2 = pipeline::run::run(&inputs, &req2, &T0Choice::At(0.5), None, &indicatif::ProgressBar::hidden()).unwrap();
    assert!(s2.result.is_none());
    assert!(s2.attempts[0].detail.as_deref().unwrap_or("").contains("no-such-track"), "{:?}", s2.attempts);
}

#[test]
fn run_refuses_bad_settings_and_foreign_outputs_before_any_work() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = synth_scene(&tmp.path().join("scene"));
    let model = box_model(&scene);
    let out = tmp.path().join("run");
    let req = CaseRequest {
        behavior: Behavior::SuddenBraking,
        agent: AgentName::Planner,
        adversary: Some("lead-1".into()),
        zone: None,
        ttc_s: None,
        insert: Default::default(),
        seed: 0,
        seeds_per_t0: 1,
        refine_rounds: 0,
        window: pipeline::case::rendered_window(),
        fallback_window: None,
    };
    let bar = indicatif::ProgressBar::hidden();
    let good = pipeline::run::RenderSettings {
        layouts: vec!["single:FRONT".into()],
        fps: 5.0,
        scale: 0.25,
        ..Default::default()
    };
    // Settings that would only fail at the render stage are refused before --out is touched.
    for bad in [
        pipeline::run::RenderSettings { fps: 0.0, ..good.clone() },
        pipeline::run::RenderSettings { fps: f64::NAN, ..good.clone() },
        pipeline::run::RenderSettings { fps: 1e6, ..good.clone() },
        pipeline::run::RenderSettings { scale: 1e3, ..good.clone() },
        pipeline::run::RenderSettings { lead_in_s: f64::NAN, ..good.clone() },
    ] {
        let inputs = pipeline::run::RunInputs { scene: &scene, model: &model, backend: &Cpu, render: &bad, out: &out };
        assert!(pipeline::run::run(&inputs, &req, &T0Choice::At(0.5), None, &bar).is_err(), "{bad:?}");
        assert!(!out.exists(), "{bad:?}: nothing written");
    }
    let inputs = pipeline::run::RunInputs { scene: &scene, model: &model, backend: &Cpu, render: &good, out: &out };
    for t in [f64::NAN, 1e308, -1.0] {
        assert!(pipeline::run::run(&inputs, &req, &T0Choice::At(t), None, &bar).is_err(), "t0 {t}");
        assert!(!out.exists(), "t0 {t}: nothing written");
    }
    // The adversary's actor missing from the model is refused before planning.
    let mut no_actor = model.clone();
    no_actor.actors.retain(|a| a.track_id != "lead-1");
    let i2 = pipeline::run::RunInputs { scene: &scene, model: &no_actor, backend: &Cpu, render: &good, out: &out };
    let e = pipeline::run::run(&i2, &req, &T0Choice::At(0.5), None, &bar).expect_err("refused").to_string();
    assert!(e.contains("lead-1") && !out.exists(), "{e}");
    // A person's files under videos/ or placement/ of a run directory are never deleted.
    std::fs::create_dir_all(out.join("videos")).unwrap();
    std::fs::write(out.join("videos/notes.txt"), b"keep").unwrap();
    let e = pipeline::run::run(&inputs, &req, &T0Choice::At(0.5), None, &bar).expect_err("refused").to_string();
    assert!(e.contains("notes.txt"), "{e}");
    assert_eq!(std::fs::read(out.join("videos/notes.txt")).unwrap(), b"keep");
    assert!(!out.join("run.json").exists());
    std::fs::remove_file(out.join("videos/notes.txt")).unwrap();
    // Into an empty directory the run goes through; nothing is left beside it.
    let s = pipeline::run::run(&inputs, &req, &T0Choice::At(0.5), None, &bar).unwrap();
    assert!(s.videos[0].output.path.starts_with(&out) && s.videos[0].output.path.exists(), "{:?}", s.videos);
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 2, "scene and run only");
}
