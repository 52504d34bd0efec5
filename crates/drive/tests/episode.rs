//! The closed loop on a tiny synthetic street (CPU, seconds):
//! * the `log` policy's frames are the open-loop video's, pixel for pixel;
//! * `idm-aeb` collides less than `log` and `constant` over the showcased behaviours;
//! * an episode directory holds what it says.

mod common;

use common::*;
use drive::builtin::builtin;
use drive::cameras::Cameras;
use drive::episode::{EpisodeSettings, Loop};
use recon::backend::CpuF32;
use render::canvas::Canvas;
use render::video::CaseView;
use scene::Behavior;

#[test]
fn replaying_the_log_draws_the_open_loop_frames() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = synth_scene(&tmp.path().join("scene"));
    let model = box_model(&scene);
    let executed = case(&scene, Behavior::SuddenBraking).expect("a sudden-braking case");
    let settings = EpisodeSettings { cameras: front3(&scene), scale: 1.0, ..Default::default() };
    let cams = Cameras::new(&CpuF32, &model, &scene, &settings.cameras, settings.scale).unwrap();
    let lp = Loop { scene: &scene, executed: &executed, settings: &settings, draw: Some(&cams), frames_dir: None };
    let mut frames: Vec<(f64, Vec<Canvas>)> = Vec::new();
    let mut policy = builtin("log").unwrap();
    let run = lp
        .run(policy.as_mut(), &mut |_, ego, pictures| {
            frames.push((ego.t, pictures.to_vec()));
            Ok(())
        })
        .unwrap();
    assert!(frames.len() > 10, "{} ticks", frames.len());
    let open_loop = CaseView::new(&CpuF32, &model, &scene, &executed).unwrap();
    // The open-loop video ends at the last executed step; the episode may run on (its tail).
    let video_end = executed.steps.last().unwrap().t;
    let mut compared = 0;
    for (t, pictures) in frames.iter().filter(|(t, _)| *t <= video_end) {
        for (cam, picture) in settings.cameras.iter().zip(pictures) {
            let expected = open_loop.view(cam, *t, 1.0, true).unwrap();
            assert_eq!((picture.width, picture.height), (expected.width, expected.height));
            let differing = picture.rgb.iter().zip(&expected.rgb).filter(|(a, b)| a != b).count();
            assert_eq!(differing, 0, "t = {t:.2} {cam}: {differing} bytes differ from the open-loop render");
            compared += 1;
        }
    }
    // The pictures are pictures (not all sky): the lead car is in the front camera.
    let front = &frames[0].1[1];
    let distinct: std::collections::BTreeSet<&[u8]> = front.rgb.chunks(3).collect();
    assert!(distinct.len() > 20, "only {} colours in the front view", distinct.len());
    assert!(compared >= 3 * (frames.len() - 1), "{compared} views compared of {} ticks", frames.len());
    println!("{compared} views over {} ticks equal the open-loop render; contact {:?}", frames.len(), run.contact);
}

#[test]
fn idm_aeb_collides_less_than_log_and_constant() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = synth_scene(&tmp.path().join("scene"));
    let settings = EpisodeSettings::default();
    let mut collisions = std::collections::BTreeMap::new();
    let mut rows = Vec::new();
    let mut cases_found = 0;
    for behavior in SHOWCASED {
        let Some(executed) = case(&scene, behavior) else {
            println!("{}: no case on this street", behavior.as_str());
            continue;
        };
        cases_found += 1;
        let reference = drive::output::reference_contact(&scene, &executed, &settings).unwrap();
        for name in drive::builtin::BUILTINS {
            let lp = Loop { scene: &scene, executed: &executed, settings: &settings, draw: None, frames_dir: None };
            let mut policy = builtin(name).unwrap();
            let run = lp.run(policy.as_mut(), &mut |_, _, _| Ok(())).unwrap();
            let s = drive::scores::score(&run, reference.as_ref());
            *collisions.entry(name).or_insert(0) += s.collision as usize;
            rows.push(format!(
                "{:<16} {:<9} collision {:<5} with {:<8} impact {:>5} m/s NCAP {:.2} MinTTC {:>5} gap {:>5} m max decel {:.1}",
                behavior.as_str(),
                name,
                s.collision,
                s.contact.as_ref().map_or("-", |c| c.other.as_str()),
                s.contact.as_ref().map_or("-".into(), |c| format!("{:.1}", c.impact_speed)),
                s.ncap_score,
                s.min_ttc_s.map_or("-".into(), |v| format!("{v:.2}")),
                s.min_gap_m.map_or("-".into(), |v| format!("{v:.2}")),
                s.max_decel
            ));
        }
    }
    for r in &rows {
        println!("{r}");
    }
    assert_eq!(cases_found, 3, "every showcased behaviour has a case on the synthetic street");
    let (log, constant, idm) = (collisions["log"], collisions["constant"], collisions["idm-aeb"]);
    assert!(idm < log && idm < constant, "collisions: log {log}, constant {constant}, idm-aeb {idm}");
}

#[test]
fn an_episode_directory_holds_its_record_and_video() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = synth_scene(&tmp.path().join("scene"));
    let model = box_model(&scene);
    let executed = case(&scene, Behavior::SuddenCutIn).expect("a cut-in case");
    let settings = EpisodeSettings { cameras: front3(&scene), scale: 1.0, ..Default::default() };
    let cams = Cameras::new(&CpuF32, &model, &scene, &settings.cameras, settings.scale).unwrap();
    let out = tmp.path().join("episode");
    let req = drive::Request {
        scene: &scene,
        executed: &executed,
        settings: &settings,
        case: drive::output::case_info(&executed, None),
        policy_command: None,
        draw: Some((&cams, "cpu-f32".into())),
        video: true,
        png_only: true,
        out: &out,
        force: false,
    };
    let file = drive::drive(&req, builtin("idm-aeb").unwrap().as_mut()).unwrap();
    assert!(out.join("episode.json").is_file());
    let back: drive::EpisodeFile = scene::format::read_json(&out.join("episode.json")).unwrap();
    assert_eq!(back.ticks.len(), file.ticks.len());
    assert!(back.ground_truth, "idm-aeb asks for the ground truth");
    assert!(back.ticks[0].ground_truth_objects.is_some_and(|n| n > 0));
    let video = back.video.as_ref().expect("a video");
    assert_eq!(video.frames, back.ticks.len(), "one video frame a tick");
    assert!(render::encode::png_dir(&out.join("video.mp4")).is_dir());
    assert!(back.timing.render_s_mean > 0.0 && back.timing.step_hz.is_some());
    // Not twice without --force; with it, over our own episode only.
    assert!(drive::drive(&req, builtin("log").unwrap().as_mut()).is_err());
    let again = drive::Request { force: true, ..req };
    drive::drive(&again, builtin("log").unwrap().as_mut()).unwrap();
}
