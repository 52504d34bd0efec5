//! The case search's second window on a real log (PandaSet 002): a braking lead's plan ends when it
//! stands, before the logged ego closes in, so no attempt over the plan's own end succeeds; the
//! demo's request then searches the tables' window (5 s from t0, braking to rest after the plan)
//! and finds a case that is valid, hits its zone and succeeds. Every attempt of both passes is
//! reported with its window, and the second pass runs only because the first found nothing.
//!
//! And how `run` draws an inserted adversary (`pipeline::run_library`), on PandaSet 002 where every
//! logged oncoming car's opposing drift runs into logged traffic: from the asset library named (its
//! `auto` choice, recorded), as the synthetic sedan where the directory holds no library
//! (recorded); a logged adversary is left as the model has it.

use cases::spec::{AgentName, T0Spec};
use cases::window::{Horizon, Window};
use indicatif::ProgressBar;
use pipeline::case::{rendered_window, select_case, CaseRequest, T0Choice};
use pipeline::run_library::RunLibrary;
use pipeline::synth_asset::{vehicle_asset, vehicle_of_kind, DEFAULT_VOXEL_M};
use reason::insert::InsertMode;
use recon::model::SceneModel;
use recon::sky::Sky;
use render::asset::library::{AssetSource, Library, UpAxis};
use scene::Behavior;
use scene::ObjectClass;

fn request(behavior: Behavior, fallback: Option<Window>) -> CaseRequest {
    CaseRequest {
        behavior,
        agent: AgentName::Planner,
        adversary: None,
        zone: None,
        ttc_s: None,
        insert: Default::default(),
        seed: 0,
        seeds_per_t0: 3,
        refine_rounds: 3,
        window: rendered_window(),
        fallback_window: fallback,
    }
}

#[test]
fn braking_on_pandaset_succeeds_over_the_tables_window_after_the_plans_own_end_fails() {
    let Some(src) = ingest::shared::data_path("pandaset/002") else { return };
    let scene = ingest::read_scenes(&[src], ingest::Expect::Auto, &ProgressBar::hidden()).unwrap().remove(0);
    let search = T0Choice::Search(T0Spec::Every(0.5));
    let good = |a: &pipeline::case::Attempt| a.valid && a.zone_hit && a.success;

    let plan_only = select_case(&scene, &request(Behavior::SuddenBraking, None), &search, None);
    assert!(!plan_only.attempts.is_empty() && plan_only.attempts.iter().all(|a| a.window == rendered_window()));
    assert!(
        !plan_only.attempts.iter().any(good),
        "a braking case succeeded over the plan's own end: {:?}",
        plan_only.attempts
    );

    let tables = Window::default();
    assert_eq!(tables.horizon, Horizon::Seconds(5.0));
    let both = select_case(&scene, &request(Behavior::SuddenBraking, Some(tables)), &search, None);
    let n = plan_only.attempts.len();
    assert_eq!(both.attempts[..n], plan_only.attempts[..], "the first pass is the plan-only search");
    assert!(both.attempts[n..].iter().all(|a| a.window == tables) && both.attempts.len() > n);
    let last = both.attempts.last().unwrap();
    assert!(good(last), "the search stops at the first good case: {last:?}");
    assert!(!both.attempts[n..both.attempts.len() - 1].iter().any(good));
    let (result, _, window) = both.chosen.expect("a case");
    assert_eq!(window, tables);
    let m = &result.best().unwrap().metrics;
    assert!(m.validity.valid && m.zone_hit && m.success_center && m.min_ttc_center_s < 1.0, "{m:?}");
}

#[test]
fn the_second_window_is_not_searched_once_the_first_succeeds() {
    let Some(src) = ingest::shared::data_path("pandaset/002") else { return };
    let scene = ingest::read_scenes(&[src], ingest::Expect::Auto, &ProgressBar::hidden()).unwrap().remove(0);
    // An oncoming drift succeeds over its plan's own end at the first t0s searched.
    let req = request(Behavior::OpposingDrift, Some(Window::default()));
    let sel = select_case(&scene, &req, &T0Choice::Search(T0Spec::Every(0.5)), None);
    assert!(sel.attempts.iter().all(|a| a.window == rendered_window()), "{:?}", sel.attempts);
    let last = sel.attempts.last().unwrap();
    assert!(last.valid && last.zone_hit && last.success, "{last:?}");
    assert_eq!(sel.chosen.expect("a case").2, rendered_window());
}

/// `run --insert always` reaches the case search (it was dropped between the command's flags and
/// the search, which then chose a logged car): on PandaSet 002 the sudden cut-in at t0 = 4 s is
/// made with a logged car, and with `always` by an inserted car (at some t0 of the log), marked
/// in the plan.
#[test]
fn insert_always_reaches_the_search_on_pandaset() {
    let Some(src) = ingest::shared::data_path("pandaset/002") else { return };
    let scene = ingest::read_scenes(&[src], ingest::Expect::Auto, &ProgressBar::hidden()).unwrap().remove(0);
    let at = T0Choice::At(4.0);
    let mut req = request(Behavior::SuddenCutIn, None);
    let logged = select_case(&scene, &req, &at, None);
    let (result, _, _) = logged.chosen.expect("a logged cut-in at 4 s");
    assert!(result.best().unwrap().plan.inserted.is_none());
    req.insert = reason::insert::InsertMode::Always;
    let inserted = select_case(&scene, &req, &T0Choice::Search(T0Spec::Every(0.5)), None);
    let (result, _, _) = inserted.chosen.unwrap_or_else(|| panic!("an inserted cut-in: {:?}", inserted.attempts));
    eprintln!("inserted cut-in at t0 {:.1} s: {:?}", result.spec.t0_s, result.best().unwrap().metrics.min_ttc_center_s);
    let plan = &result.best().unwrap().plan;
    assert!(plan.inserted.is_some() && plan.adversary_track.starts_with("inserted-"), "{}", plan.adversary_track);
}

fn request_inserting(behavior: Behavior, insert: InsertMode) -> CaseRequest {
    CaseRequest { insert, ..request(behavior, None) }
}

#[test]
fn an_inserted_adversary_is_drawn_from_the_library_else_as_the_sedan_and_a_logged_one_is_left() {
    let Some(src) = ingest::shared::data_path("pandaset/002") else { return };
    let scene = ingest::read_scenes(&[src], ingest::Expect::Auto, &ProgressBar::hidden()).unwrap().remove(0);
    let tmp = tempfile::tempdir().unwrap();
    let (scene_dir, model_dir) = (tmp.path().join("scene"), tmp.path().join("model"));
    // The scene on disk only names the tracks for `auto` (the images stay in the shared folder).
    let mut bare = scene.clone();
    bare.frames.iter_mut().for_each(|f| {
        f.images.clear();
        f.lidar = None;
    });
    scene::format::write_scene(&scene_dir, &bare).unwrap();
    let drift =
        select_case(&scene, &request_inserting(Behavior::OpposingDrift, InsertMode::Always), &T0Choice::At(2.0), None);
    let (_, executed, _) = drift.chosen.unwrap_or_else(|| panic!("an inserted opposing drift: {:?}", drift.attempts));
    let ins = executed.plan.inserted.clone().expect("the adversary is inserted");
    let track = executed.plan.adversary_track.clone();
    assert!(track.starts_with("inserted-"), "{track}");

    // A library of one synthetic van.
    let lib = tmp.path().join("assets");
    let van = vehicle_asset(&vehicle_of_kind("van", [0.8, 0.8, 0.8]).unwrap(), DEFAULT_VOXEL_M).unwrap();
    let source = AssetSource::Synth { vehicle: "van".into(), method: "test".into() };
    Library::add(&lib, "synth-van", ObjectClass::Vehicle, source, UpAxis::Z, &van, false).unwrap();
    let model = SceneModel {
        antialiased: false,
        background: splat::Gaussians::empty(0),
        actors: vec![],
        sky: Sky::new(4, [0.5, 0.6, 0.8]),
    };
    let with = |library| RunLibrary {
        scene: &scene,
        scene_dir: &scene_dir,
        model: &model,
        model_dir: &model_dir,
        library,
        fps: 24.0,
    };
    let drawn = |m: &SceneModel| m.actors.iter().find(|a| a.track_id == track).map_or(0, |a| a.gaussians.len());

    let (m, check) = with(&lib).swap(&executed).unwrap();
    let (m, check) = (m.expect("a model with the inserted car"), check.expect("the decision recorded"));
    assert_eq!(drawn(&m), van.len(), "the library's van, every Gaussian");
    assert_eq!(check.auto.as_ref().map(|a| a.asset.as_str()), Some("synth-van"));
    assert!(check.replaced && check.why.contains("asset library") && check.why.contains(&ins.lane), "{}", check.why);
    assert!(check.case_closest_m.is_some_and(|d| d > 0.0 && d < 30.0), "{:?}", check.case_closest_m);

    let none = tmp.path().join("no-library");
    let (m, check) = with(&none).swap(&executed).unwrap();
    let (m, check) = (m.unwrap(), check.unwrap());
    assert!(drawn(&m) > 0 && drawn(&m) != van.len(), "the synthetic sedan");
    assert!(check.why.contains("synthetic sedan") && check.auto.is_none(), "{}", check.why);

    let cut_in =
        select_case(&scene, &request_inserting(Behavior::SuddenCutIn, InsertMode::Never), &T0Choice::At(4.0), None);
    let (_, logged, _) = cut_in.chosen.expect("a logged cut-in at 4 s");
    let (m, check) = with(&lib).swap(&logged).unwrap();
    assert!(m.is_none() && check.is_none(), "a logged adversary is drawn as the model has it");
}
