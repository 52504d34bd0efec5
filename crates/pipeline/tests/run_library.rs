//! How `run` draws an inserted adversary (`pipeline::run_library`), on PandaSet 002 where every
//! logged oncoming car's opposing drift runs into logged traffic: the inserted car is drawn from
//! the asset library named (its `auto` choice, recorded), as the synthetic sedan where the
//! directory holds no library (recorded), and a logged adversary is left as the model has it.
//! Skips with a printed reason where `../shared/data` is absent.

use cases::spec::AgentName;
use indicatif::ProgressBar;
use pipeline::case::{rendered_window, select_case, CaseRequest, T0Choice};
use pipeline::run_library::RunLibrary;
use pipeline::synth_asset::{vehicle_asset, vehicle_of_kind, DEFAULT_VOXEL_M};
use reason::insert::InsertMode;
use recon::model::SceneModel;
use recon::sky::Sky;
use render::asset::library::{AssetSource, Library, UpAxis};
use scene::{Behavior, ObjectClass};

fn request(behavior: Behavior, insert: InsertMode) -> CaseRequest {
    CaseRequest {
        behavior,
        agent: AgentName::Planner,
        adversary: None,
        zone: None,
        ttc_s: None,
        insert,
        seed: 0,
        seeds_per_t0: 3,
        refine_rounds: 3,
        window: rendered_window(),
        fallback_window: None,
    }
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
    let drift = select_case(&scene, &request(Behavior::OpposingDrift, InsertMode::Always), &T0Choice::At(2.0), None);
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

    let cut_in = select_case(&scene, &request(Behavior::SuddenCutIn, InsertMode::Never), &T0Choice::At(4.0), None);
    let (_, logged, _) = cut_in.chosen.expect("a logged cut-in at 4 s");
    let (m, check) = with(&lib).swap(&logged).unwrap();
    assert!(m.is_none() && check.is_none(), "a logged adversary is drawn as the model has it");
}
