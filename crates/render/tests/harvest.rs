//! `render::asset::harvest` on a log built by hand, where every statistic can be worked out on
//! paper: the ego drives along +x at 5 m/s for 24 frames (10 Hz), one forward camera 1 m up
//! (160 x 120, focal 100 px, principal point in the middle), the model's split holding out
//! frames 0, 8 and 16. Its vehicles:
//!
//! * `lead` drives 10 m ahead at the ego's speed, its centre at the camera's height: always its
//!   back face, 2 m x 1.5 m at 8 m, a 25 x 18.75 px rectangle; 21 views, one azimuth sector;
//! * `parked` stands 3.6 m to the left at x = 12: passed on the left, seen from x_c = 0.5 to
//!   10.5 m (at 11 m its near side leaves the image: u = 80 - 100 * 2.7 / 3.25 < 0), 19 views,
//!   closest 2.7 m (its near side, once the camera is level with it), azimuths from
//!   atan2(-3.6, -11.5) to atan2(-3.6, -1.5): sectors 0, 1 and 2;
//! * `far` stands at (40, 15): closest sqrt(26.25^2 + 14.1^2) = 29.80 m, one sector;
//! * `behind` stands 30 m behind the start: never in view;
//! * and a pedestrian, not harvested.
//!
//! The model is written by hand (box-filling Gaussians of known colour), so the colours and the
//! mirror are exact too. The test checks the numbers, the kept/skipped decisions under three
//! sets of thresholds, the library (foreign assets untouched or refused, re-harvests replacing
//! and dropping their own entries) and `auto`, which then prefers the real vehicles to the
//! synthetic one and never takes a track's own asset.
//!
//! A second test harvests a briefly trained model of a synthetic street and holds its statistics
//! to a brute-force reference (pixel counts, a sampled box surface) and its assets to the mirror.

use recon::model::{Actor, SceneModel};
use recon::model_io::{write_model, ModelRecord};
use render::asset::align::AlignOptions;
use render::asset::harvest::{harvest, HarvestReport, Thresholds};
use render::asset::library::{AssetSource, Library, UpAxis};
use render::asset::replace::replace_specs;
use scene::glam::DVec3;
use scene::{
    Ego, EgoSizeSource, Frame, ImageRef, ObjectClass, Scene, Source, SourceKind, Track, TrackState, Transform3,
};
use std::path::{Path, PathBuf};

const FRAMES: usize = 24;
const SPEED: f64 = 5.0;

fn track(id: &str, class: ObjectClass, size: [f64; 3], centre: impl Fn(usize) -> [f64; 3]) -> Track {
    let states = (0..FRAMES)
        .map(|k| TrackState {
            frame: k,
            center: DVec3::from(centre(k)),
            heading: 0.0,
            size_lwh: size,
            velocity: None,
            valid: true,
            motion: None,
        })
        .collect();
    Track { id: id.into(), class, states }
}

fn write_scene(dir: &Path) -> Scene {
    let camera = scene::Camera {
        name: "FRONT".into(),
        width: 160,
        height: 120,
        intrinsics: scene::Intrinsics { fx: 100.0, fy: 100.0, cx: 80.0, cy: 60.0 },
        distortion: Default::default(),
        ego_from_camera: Transform3::from_yaw_translation(0.0, DVec3::new(0.0, 0.0, 1.0)),
        rolling_shutter: Default::default(),
    };
    let grey = image::RgbImage::from_pixel(160, 120, image::Rgb([128, 128, 128]));
    let frames = (0..FRAMES)
        .map(|k| {
            let path = scene::format::image_rel_path_ext(k, "FRONT", "png");
            std::fs::create_dir_all(dir.join(&path).parent().unwrap()).unwrap();
            grey.save(dir.join(&path)).unwrap();
            Frame {
                index: k,
                timestamp_s: 0.1 * k as f64,
                world_from_ego: Transform3::from_yaw_translation(0.0, DVec3::new(SPEED * 0.1 * k as f64, 0.0, 0.0)),
                images: vec![ImageRef::at_frame_time("FRONT", path)],
                lidar: None,
            }
        })
        .collect();
    let v = ObjectClass::Vehicle;
    let car = [4.5, 1.8, 1.5];
    let scene = Scene {
        format: scene::SCENE_FORMAT.into(),
        name: "street".into(),
        source: Source { kind: SourceKind::Synthetic, files: vec![], id: "hand".into() },
        ego: Ego { size_lwh: [4.5, 2.0, 1.8], size_source: EgoSizeSource::Default, track_id: None },
        cameras: vec![camera],
        frames,
        tracks: vec![
            track("lead", v, [4.0, 2.0, 1.5], |k| [SPEED * 0.1 * k as f64 + 10.0, 0.0, 1.0]),
            track("parked", v, car, |_| [12.0, 3.6, 1.0]),
            track("far", v, car, |_| [40.0, 15.0, 1.0]),
            track("behind", v, car, |_| [-30.0, 0.0, 1.0]),
            track("walker", ObjectClass::Pedestrian, [0.6, 0.6, 1.8], |_| [15.0, -3.0, 0.9]),
        ],
        map: None,
    };
    scene::format::write_scene(dir, &scene).unwrap();
    scene
}

/// Opaque Gaussians on a 6 x 4 x 4 grid filling a box of `size`, SH degree 1 (DC `dc`, the
/// first band non-zero so the mirror has something to flip), and a few transparent ones.
fn box_gaussians(size: [f64; 3], dc: [f64; 3]) -> splat::Gaussians {
    let mut g = splat::Gaussians::empty(1);
    let n = [6, 4, 4];
    for i in 0..n[0] {
        for j in 0..n[1] {
            for k in 0..n[2] {
                let at = |a: usize, n: usize, s: f64| (a as f64 + 0.5) / n as f64 * s - s / 2.0;
                g.means.push([at(i, n[0], size[0]), at(j, n[1], size[1]), at(k, n[2], size[2])]);
                g.log_scales.push([(size[0] / 12.0).ln(); 3]);
                g.rotations.push([1.0, 0.0, 0.0, 0.0]);
                // Every 8th nearly transparent: left out of the asset.
                g.opacity_logits.push(if (i + j + k) % 8 == 0 { -6.0 } else { 3.0 });
                g.sh.extend(dc);
                g.sh.extend([0.1, 0.05, 0.0, 0.0, 0.0, 0.0, -0.1, 0.0, 0.02]);
            }
        }
    }
    g
}

fn write_model_dir(dir: &Path, scene_dir: &Path, scene: &Scene) -> PathBuf {
    let colours =
        [("lead", [0.5, -0.3, -0.3]), ("parked", [-0.8, -0.8, -0.7]), ("far", [0.0; 3]), ("behind", [0.0; 3])];
    let actors = scene
        .tracks
        .iter()
        .map(|t| {
            let dc = colours.iter().find(|c| c.0 == t.id).map_or([0.0; 3], |c| c.1);
            Actor {
                track_id: t.id.clone(),
                size_lwh: t.median_size_lwh(),
                gaussians: box_gaussians(t.median_size_lwh(), dc),
            }
        })
        .collect();
    let model = SceneModel {
        antialiased: false,
        background: box_gaussians([1.0; 3], [0.0; 3]),
        actors,
        sky: recon::sky::Sky::new(2, [0.5, 0.6, 0.8]),
    };
    let mut record: ModelRecord = serde_json::from_value(serde_json::json!({
        "format": "", "scene_name": scene.name, "scene_dir": scene_dir, "backend": "cpu", "iterations": 0,
        "held_out_every": 8, "scale": 1.0, "extent": 10.0, "background_file": "", "background_gaussians": 0,
        "actors": [], "sky_res": 2, "train_seconds": 0.0, "iterations_per_second": 0.0,
        "last_loss": recon::loss::LossParts::default(),
    }))
    .unwrap();
    let out = dir.join("model");
    write_model(&out, &model, &mut record, &recon::TrainConfig::default(), None).unwrap();
    // Training already mirrored `parked` (the flag a mirroring training run writes).
    let file = out.join("model.json");
    let mut v: serde_json::Value = serde_json::from_slice(&std::fs::read(&file).unwrap()).unwrap();
    for a in v["actors"].as_array_mut().unwrap() {
        if a["track_id"] == "parked" {
            a["mirrored"] = serde_json::Value::Bool(true);
        }
    }
    std::fs::write(&file, serde_json::to_vec_pretty(&v).unwrap()).unwrap();
    out
}

fn kept(r: &HarvestReport) -> Vec<&str> {
    r.vehicles.iter().filter(|v| v.kept).map(|v| v.track_id.as_str()).collect()
}

#[test]
fn harvest_measures_the_log_by_hand_keeps_the_well_seen_and_auto_prefers_them() {
    let tmp = tempfile::tempdir().unwrap();
    let scene_dir = tmp.path().join("scene");
    let scene = write_scene(&scene_dir);
    let model = write_model_dir(tmp.path(), &scene_dir, &scene);
    let lib = tmp.path().join("assets");
    let synth = AssetSource::Synth { vehicle: "van".into(), method: "test".into() };
    let van = box_gaussians([5.0, 2.0, 2.2], [0.0; 3]);
    Library::add(&lib, "synth-van", ObjectClass::Vehicle, synth, UpAxis::Z, &van, false).unwrap();

    let strict = Thresholds { max_closest_m: 12.0, min_azimuth_bins: 3, min_hull_px: 400.0 };
    let r = harvest(&scene_dir, &model, &lib, &strict, false).unwrap();
    let ids: Vec<&str> = r.vehicles.iter().map(|v| v.track_id.as_str()).collect();
    assert_eq!(ids, ["lead", "parked", "far", "behind"], "every vehicle actor, in the model's order");
    assert_eq!(r.other_actors, 1, "the pedestrian");
    assert_eq!(r.held_out_every, 8);

    let v = |id: &str| r.vehicle(id).unwrap();
    let lead = &v("lead").observed;
    assert_eq!(lead.views, 21);
    assert!((lead.closest_m.unwrap() - 8.0).abs() < 1e-9, "{lead:?}");
    assert_eq!(lead.azimuth_sectors.len(), 1, "{lead:?}");
    assert!((lead.max_hull_px - 25.0 * 18.75).abs() < 1e-6, "{lead:?}");
    assert!((lead.total_hull_px - 21.0 * 25.0 * 18.75).abs() < 1e-6, "{lead:?}");
    assert!(lead.azimuth_span_deg < 1e-6, "{lead:?}");

    let parked = &v("parked").observed;
    assert_eq!(parked.views, 19, "{parked:?}");
    assert!((parked.closest_m.unwrap() - 2.7).abs() < 1e-9, "{parked:?}");
    assert_eq!(parked.azimuth_sectors, [0, 1, 2]);
    let span = (-3.6f64).atan2(-1.5) - (-3.6f64).atan2(-11.5);
    assert!((parked.azimuth_span_deg - span.to_degrees()).abs() < 1e-9, "{parked:?}");
    assert!(parked.max_hull_px > 500.0 && parked.max_hull_px < 160.0 * 120.0, "{parked:?}");

    let far = &v("far").observed;
    assert_eq!(far.views, 21);
    assert!((far.closest_m.unwrap() - (26.25f64.powi(2) + 14.1f64.powi(2)).sqrt()).abs() < 1e-9, "{far:?}");
    assert_eq!(far.azimuth_sectors, [0]);
    assert_eq!(v("behind").observed.views, 0);

    // The decisions, each failed criterion named.
    assert_eq!(kept(&r), ["parked"]);
    assert_eq!(v("lead").why_not, ["1 azimuth sector(s) < 3"]);
    assert_eq!(v("far").why_not.len(), 3, "{:?}", v("far").why_not);
    assert!(v("far").why_not[0].starts_with("closest 29.8 m > 12.0 m"), "{:?}", v("far").why_not);
    assert_eq!(v("behind").why_not, ["never in view of a training image"]);

    // Colours: the median of 0.5 + C0 * dc over the opaque Gaussians.
    let c = v("parked").colour.unwrap();
    for (got, dc) in c.iter().zip([-0.8, -0.8, -0.7]) {
        assert!((got - (0.5 + splat::sh::C0 * dc)).abs() < 1e-6, "{c:?}");
    }

    // The library: `synth-van` untouched, `parked` stored as it is (training mirrored it).
    let l = Library::load(&lib).unwrap();
    assert_eq!(l.assets.iter().map(|a| a.name.as_str()).collect::<Vec<_>>(), ["synth-van", "street-parked"]);
    let e = l.get("street-parked").unwrap();
    let opaque = 96 - (0..96).filter(|n| (n / 16 + (n / 4) % 4 + n % 4) % 8 == 0).count();
    assert_eq!(e.gaussians, opaque, "not mirrored twice");
    let h = e.harvest.as_ref().unwrap();
    assert!(h.mirrored_in_model && h.scene == "street" && h.observed == *parked, "{h:?}");
    assert_eq!(e.source, AssetSource::Model { model_dir: model.clone(), track_id: "parked".into() });

    // Looser sectors: `lead` is kept unless its 469-pixel view must reach 500; it is mirrored by
    // the harvest (twice its opaque Gaussians, the mirror's y the original's negated).
    let loose = Thresholds { min_azimuth_bins: 1, ..strict };
    let r = harvest(&scene_dir, &model, &lib, &loose, false).unwrap();
    assert_eq!(kept(&r), ["lead", "parked"]);
    let l = Library::load(&lib).unwrap();
    let lead_asset = l.read(&lib, l.get("street-lead").unwrap()).unwrap();
    assert_eq!(lead_asset.len(), 2 * opaque);
    assert_eq!(lead_asset.means[opaque][1], -lead_asset.means[0][1]);
    assert_eq!(lead_asset.sh[opaque * 12 + 3], -lead_asset.sh[3], "the y-odd band flips");
    assert!(r.removed.is_empty());

    // `auto` for `lead` takes the real `parked` over the synthetic van, never itself; for
    // `parked`, the real `lead`.
    let (mut m, _) = recon::model_io::load_model(&model).unwrap();
    let pairs = [("lead".to_string(), "auto".to_string()), ("parked".to_string(), "auto".to_string())];
    let done =
        replace_specs(&mut m, &scene_dir, Some(&model), &pairs, &lib, UpAxis::Z, &AlignOptions::default()).unwrap();
    let chosen: Vec<&str> = done.iter().map(|d| d.auto.as_ref().unwrap().asset.as_str()).collect();
    assert_eq!(chosen, ["street-parked", "street-lead"]);
    assert!(done.iter().all(|d| d.auto.as_ref().unwrap().real));

    let tight = Thresholds { min_azimuth_bins: 1, min_hull_px: 500.0, ..strict };
    let r = harvest(&scene_dir, &model, &lib, &tight, false).unwrap();
    assert_eq!(kept(&r), ["parked"]);
    assert_eq!(r.vehicle("lead").unwrap().why_not, ["largest view 469 px < 500 px"]);
    assert_eq!(r.removed, ["street-lead"], "the earlier harvest's own entry is dropped");
    assert!(!lib.join("street-lead.ply").exists());
    // With `lead` gone, `parked`'s only candidate besides itself is the synthetic van.
    let (mut m, _) = recon::model_io::load_model(&model).unwrap();
    let done = replace_specs(&mut m, &scene_dir, Some(&model), &pairs[1..], &lib, UpAxis::Z, &AlignOptions::default())
        .unwrap();
    let a = done[0].auto.as_ref().unwrap();
    assert!(a.asset == "synth-van" && !a.real && a.why.contains("no real vehicle asset"), "{a:?}");

    // An asset of another source under a harvested name is refused, and taken over with force.
    let user = AssetSource::User { path: "mine.ply".into() };
    Library::add(&lib, "street-parked", ObjectClass::Vehicle, user, UpAxis::Z, &van, true).unwrap();
    let e = harvest(&scene_dir, &model, &lib, &strict, false).unwrap_err().to_string();
    assert!(e.contains("asset `street-parked`") && e.contains("already in"), "{e}");
    harvest(&scene_dir, &model, &lib, &strict, true).unwrap();
    assert!(Library::load(&lib).unwrap().get("street-parked").unwrap().is_real());

    // Bad thresholds are refused before anything is read.
    let e = harvest(&scene_dir, &model, &lib, &Thresholds { min_hull_px: -1.0, ..strict }, false).unwrap_err();
    assert!(e.to_string().contains("--min-hull-px"), "{e}");
}

/// The distance from `p` to the nearest of points spaced `step` over the faces of a box of
/// `size` at `pose`: the closest approach by brute force (at most `step / sqrt(2)` too long).
fn sampled_distance(p: DVec3, pose: &recon::pose::BoxPose, size: [f64; 3], step: f64) -> f64 {
    let world_from_box = pose.world_from_box();
    let n: [usize; 3] = std::array::from_fn(|k| (size[k] / step).ceil() as usize);
    let at = |k: usize, i: usize| size[k] * (i as f64 / n[k] as f64 - 0.5);
    let mut best = f64::INFINITY;
    for ax in 0..3 {
        let (u, v) = ((ax + 1) % 3, (ax + 2) % 3);
        for side in [-0.5, 0.5] {
            for i in 0..=n[u] {
                for j in 0..=n[v] {
                    let mut q = [0.0; 3];
                    q[ax] = side * size[ax];
                    q[u] = at(u, i);
                    q[v] = at(v, j);
                    best = best.min((world_from_box.transform_point(DVec3::from(q)) - p).length());
                }
            }
        }
    }
    best
}

#[test]
fn a_trained_models_harvest_agrees_with_a_brute_force_count_and_mirrors_its_assets() {
    // A synthetic street, trained briefly: the statistics come from the scene, the assets from
    // the model. The reference counts, for every training image that has the whole box in front
    // of the camera, the pixel centres inside the projected box (`placement::box_mask`) and takes
    // the camera centre from the scene's extrinsics and the box surface by sampling.
    let tmp = tempfile::tempdir().unwrap();
    let scene_dir = tmp.path().join("scene");
    let synth_cfg = synth::SynthConfig { frames: 60, cameras: 3, width: 96, height: 64, seed: 4, ..Default::default() };
    synth::synthesize(&synth_cfg, &scene_dir, &mut |_, _| {}).unwrap();
    let mut cfg = recon::TrainConfig { iterations: 10, scale: 1.0, checkpoint_interval: 0, ..Default::default() };
    cfg.init.max_points = 2000;
    cfg.init.actor_points = 200;
    cfg.sky_res = 4;
    let model = tmp.path().join("model");
    let none = |_: &recon::data::View| Ok(None);
    let req = recon::session::TrainRequest {
        scene_dir: &scene_dir,
        out_dir: &model,
        cfg,
        resume: false,
        force: recon::out_dir::ForceMode::Refuse,
        stop_after: None,
        priors: &none,
    };
    recon::session::train(req, recon::backend::CpuF32, &indicatif::ProgressBar::hidden()).unwrap();
    let scene = scene::load_scene(&scene_dir).unwrap();
    let (trained, _) = recon::model_io::load_model(&model).unwrap();
    let lib = tmp.path().join("assets");
    let t = Thresholds { max_closest_m: 15.0, min_azimuth_bins: 2, min_hull_px: 150.0 };
    let r = harvest(&scene_dir, &model, &lib, &t, false).unwrap();
    let vehicles = scene.tracks.iter().filter(|t| t.class == ObjectClass::Vehicle).count();
    assert_eq!(r.vehicles.len(), vehicles);

    let mut compared = 0;
    for v in &r.vehicles {
        let track = scene.track(&v.track_id).unwrap();
        let size = track.median_size_lwh();
        let (mut views, mut closest, mut largest) = (0, f64::INFINITY, 0usize);
        for f in scene.frames.iter().filter(|f| f.index % 8 != 0) {
            let Some(pose) = recon::pose::box_pose_at(&scene, track, f.timestamp_s) else { continue };
            for im in &f.images {
                let cam = scene.camera(&im.camera).unwrap();
                let world_from_ego = scene.world_from_ego_of_image(f, im);
                let sc = recon::camera::splat_camera(cam, &world_from_ego, 1.0).unwrap();
                let Some(mask) = render::placement::box_mask(&sc, &pose, size) else { continue };
                let count = mask.iter().filter(|&&b| b).count();
                if count == 0 {
                    continue;
                }
                views += 1;
                largest = largest.max(count);
                let centre = (world_from_ego * cam.ego_from_camera).translation();
                closest = closest.min(sampled_distance(centre, &pose, size, 0.05));
            }
        }
        let o = &v.observed;
        println!("{}: {o:?}; reference {views} views, closest {closest:.3} m, largest {largest} px", v.track_id);
        assert!(o.views >= views, "{}: {} views, the reference {views}", v.track_id, o.views);
        if views > 0 {
            let c = o.closest_m.unwrap();
            assert!(c <= closest + 1e-9 && c > closest - 0.04, "{}: closest {c} vs {closest}", v.track_id);
            // Counting pixel centres is off by up to about the hull's perimeter for small hulls.
            let (got, want) = (o.max_hull_px, largest as f64);
            let tol = 0.03 * want + 2.0 * want.sqrt() + 4.0;
            assert!(got >= want - tol, "{}: largest {got} px vs {want} counted", v.track_id);
            compared += 1;
        }
        assert_eq!(v.kept, v.why_not.is_empty());
    }
    assert!(compared >= 3, "the street's vehicles are in view");
    let kept: Vec<_> = r.vehicles.iter().filter(|v| v.kept).collect();
    assert!(!kept.is_empty() && kept.len() < r.vehicles.len(), "{:?}", r.vehicles);
    // Each kept vehicle is stored with its mirror image: twice its non-transparent Gaussians.
    let l = Library::load(&lib).unwrap();
    for v in kept {
        let actor = trained.actors.iter().find(|a| a.track_id == v.track_id).unwrap();
        let e = l.get(v.asset.as_deref().unwrap()).unwrap();
        assert_eq!(e.gaussians, 2 * render::asset::library::without_transparent(&actor.gaussians).len());
        assert!(!e.harvest.as_ref().unwrap().mirrored_in_model);
    }
}
