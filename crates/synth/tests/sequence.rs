//! End-to-end checks of a written synthetic scene: it loads like any scene, its tracked boxes
//! cover the vehicles' instance pixels, its LiDAR points lie on the surfaces the GT maps and a
//! fresh ray cast report, and the same seed reproduces it byte for byte.

use glam::DVec3;
use scene::format::read_lidar;
use scene::frames::{box_corners, world_from_box};
use scene::{load_scene, Scene};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use synth::geometry::Ray;
use synth::{gt, raycast, Sequence, SynthConfig, SynthError};

/// One scene shared by the tests of this file: 8 frames, all 5 cameras, 480 x 320, made afresh
/// by each run of this test binary in cargo's scratch folder for it (`CARGO_TARGET_TMPDIR`): a
/// static is never dropped, so a `TempDir` here left 28 MB in /tmp behind every run.
fn fixture() -> (&'static Path, &'static SynthConfig) {
    static FIXTURE: OnceLock<(PathBuf, SynthConfig)> = OnceLock::new();
    let (dir, cfg) = FIXTURE.get_or_init(|| {
        let root = Path::new(env!("CARGO_TARGET_TMPDIR")).join("synth-sequence-fixture");
        if root.exists() {
            std::fs::remove_dir_all(&root).unwrap();
        }
        let dir = root.join("scene");
        let cfg = SynthConfig { frames: 8, cameras: 5, width: 480, height: 320, seed: 7, ..Default::default() };
        synth::synthesize(&cfg, &dir, &mut |_, _| {}).unwrap();
        (dir, cfg)
    });
    (dir, cfg)
}

fn scene() -> Scene {
    load_scene(fixture().0).unwrap()
}

#[test]
fn loads_as_a_scene_with_every_kind_of_motion() {
    let s = scene();
    assert_eq!(s.source.kind, scene::SourceKind::Synthetic);
    assert_eq!(s.frames.len(), 8);
    for (i, f) in s.frames.iter().enumerate() {
        assert!((f.timestamp_s - i as f64 * 0.1).abs() < 1e-12);
        assert_eq!(f.images.len(), 5);
        assert!(f.lidar.as_ref().unwrap().points > 10_000);
    }
    let names: Vec<&str> = s.cameras.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["FRONT", "FRONT_LEFT", "FRONT_RIGHT", "SIDE_LEFT", "SIDE_RIGHT"]);
    assert!(s.tracks.len() >= 6);
    assert!(s.map.as_ref().is_some_and(|m| m.lanes.len() == 4));
    // Classify each track from its states alone, relative to the ego.
    let ego0 = s.frames[0].world_from_ego.translation();
    let ego_speed = s.ego_distance_m() / s.duration_s();
    let (mut lead, mut follow, mut adjacent, mut oncoming, mut parked) = (0, 0, 0, 0, 0);
    for t in &s.tracks {
        assert_eq!(t.class, scene::ObjectClass::Vehicle);
        let st = &t.states[0];
        let v = st.velocity.unwrap();
        let dy = st.center.y - ego0.y;
        if v.length() == 0.0 {
            parked += 1;
        } else if v.x < 0.0 {
            oncoming += 1;
        } else if dy.abs() < 0.5 && st.center.x > ego0.x && v.x <= ego_speed {
            lead += 1;
        } else if dy.abs() < 0.5 && st.center.x < ego0.x && v.x >= ego_speed {
            follow += 1;
        } else if (dy.abs() - 3.5).abs() < 0.5 {
            adjacent += 1;
        }
    }
    let counts = [lead, follow, adjacent, oncoming, parked];
    assert!(counts.iter().all(|c| *c >= 1), "lead, follow, adjacent, oncoming, parked: {counts:?}");
}

/// The tracked 3D box, projected into a camera, against the vehicle's instance pixels.
///
/// A vehicle counts in a camera and frame when (a) all 8 box corners are in front of the camera
/// and project inside the image, (b) it is unoccluded: its instance pixels in the written map
/// are exactly the pixels it covers when ray cast alone (nothing else in the world), and (c) it
/// covers at least 300 pixels (below that, the half-pixel quantisation of each rectangle edge
/// alone costs several per cent of IoU). Then every instance pixel centre must lie inside the projected box's
/// bounding rectangle and the IoU of that rectangle with the instance pixels' rectangle must
/// exceed 0.9.
#[test]
fn projected_boxes_cover_instance_pixels() {
    let (dir, cfg) = fixture();
    let s = scene();
    let seq = Sequence::new(cfg).unwrap();
    let index: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("gt/gt.json")).unwrap()).unwrap();
    let mut checked = 0;
    for f in [0, 4, 7] {
        let frame = &s.frames[f];
        let ego_from_world = frame.world_from_ego.inverse();
        let world = seq.world_at(f);
        for cam in &s.cameras {
            let (w, h) = (cam.width as usize, cam.height as usize);
            let inst = gt::read_u16(&dir.join(gt::gt_rel_path(f, &cam.name, "instance.u16.gz"))).unwrap();
            assert_eq!(inst.len(), w * h);
            for entry in index["instances"].as_array().unwrap() {
                let k = entry["instance"].as_u64().unwrap() as u16;
                let track = s.track(entry["track_id"].as_str().unwrap()).unwrap();
                let st = track.state_at(f).unwrap();
                let world_from_box = world_from_box(st.center, st.heading);
                let uv: Option<Vec<_>> = box_corners(st.size_lwh)
                    .iter()
                    .map(|c| cam.project_ego(ego_from_world.transform_point(world_from_box.transform_point(*c))))
                    .collect();
                let Some(uv) = uv else { continue };
                if !uv.iter().all(|p| cam.contains_pixel(*p)) {
                    continue;
                }
                let (u0, u1) =
                    (uv.iter().map(|p| p.x).fold(f64::MAX, f64::min), uv.iter().map(|p| p.x).fold(f64::MIN, f64::max));
                let (v0, v1) =
                    (uv.iter().map(|p| p.y).fold(f64::MAX, f64::min), uv.iter().map(|p| p.y).fold(f64::MIN, f64::max));
                let pixels: Vec<usize> = (0..w * h).filter(|&i| inst[i] == k).collect();
                if pixels.len() < 300 {
                    continue;
                }
                let alone = raycast::instance_map(&world.only_vehicle(k as usize - 1), cam, &frame.world_from_ego);
                let alone_pixels: Vec<usize> = (0..w * h).filter(|&i| alone[i] == k).collect();
                if alone_pixels != pixels {
                    continue; // occluded
                }
                let (mut a0, mut a1, mut b0, mut b1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
                for &i in &pixels {
                    let (u, v) = ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
                    assert!(u >= u0 && u <= u1 && v >= v0 && v <= v1, "{} pixel outside its box", track.id);
                    (a0, a1, b0, b1) = (a0.min(u - 0.5), a1.max(u + 0.5), b0.min(v - 0.5), b1.max(v + 0.5));
                }
                let inter = (u1.min(a1) - u0.max(a0)).max(0.0) * (v1.min(b1) - v0.max(b0)).max(0.0);
                let union = (u1 - u0) * (v1 - v0) + (a1 - a0) * (b1 - b0) - inter;
                let iou = inter / union;
                eprintln!(
                    "{} {} frame {f}: {} px, IoU {iou:.3} box {u0:.1} {u1:.1} {v0:.1} {v1:.1} px {a0} {a1} {b0} {b1}",
                    track.id,
                    cam.name,
                    pixels.len()
                );
                assert!(iou > 0.9, "{} in {} frame {f}: IoU {iou:.3}", track.id, cam.name);
                checked += 1;
            }
        }
    }
    assert!(checked >= 5, "only {checked} unoccluded, fully visible vehicles checked");
}

/// LiDAR against two other paths:
/// 1. Every stored point (read back from `lidar/*.bin`, f32, ego frame) is re-derived: its beam
///    is identified from its direction in the documented beam table (`gt/gt.json`), the exact
///    beam ray is cast again in the world through the frame's `world_from_ego` from
///    `scene.json`, and the stored range must equal the cast range to 1e-3 m.
/// 2. Every point in the FRONT camera's view is checked against the camera: the ray from the
///    camera through the point's exact projection must not pass the point (the camera cannot
///    see through a LiDAR surface), and where it stops at the point's depth (the point is not
///    hidden from the camera) the depths agree to 1e-3 m; most points must be seen this way.
/// 3. The written GT depth at each pixel centre equals a fresh cast of that pixel-centre ray.
#[test]
fn lidar_ranges_match_ray_casts_and_gt_depth() {
    let (dir, cfg) = fixture();
    let s = scene();
    let seq = Sequence::new(cfg).unwrap();
    let index: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("gt/gt.json")).unwrap()).unwrap();
    let lidar = &index["lidar"];
    let origin = DVec3::from(
        <[f64; 3]>::try_from(
            lidar["origin_ego"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect::<Vec<_>>(),
        )
        .unwrap(),
    );
    let incl: Vec<f64> = lidar["inclinations_rad"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let azimuths = lidar["azimuths"].as_u64().unwrap() as usize;
    let cam = s.camera("FRONT").unwrap();
    for f in [0, 7] {
        let frame = &s.frames[f];
        let world = seq.world_at(f);
        let points = read_lidar(&dir.join(&frame.lidar.as_ref().unwrap().path)).unwrap();
        assert_eq!(points.len(), frame.lidar.as_ref().unwrap().points);
        let (mut seen, mut in_view, mut worst) = (0, 0, 0.0f64);
        for p in &points {
            let p_ego = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            let d = p_ego - origin;
            let range = d.length();
            let beam = incl
                .iter()
                .enumerate()
                .min_by(|a, b| (a.1 - (d.z / range).asin()).abs().total_cmp(&(b.1 - (d.z / range).asin()).abs()))
                .unwrap()
                .0;
            let step = std::f64::consts::TAU / azimuths as f64;
            let k = (d.y.atan2(d.x) / step).round().rem_euclid(azimuths as f64) as usize;
            let (inc, az) = (incl[beam], k as f64 * step);
            let dir_ego = DVec3::new(inc.cos() * az.cos(), inc.cos() * az.sin(), inc.sin());
            assert!(dir_ego.angle_between(d) < 1e-5, "point not on a beam of the table");
            let ray = Ray {
                origin: frame.world_from_ego.transform_point(origin),
                dir: frame.world_from_ego.transform_vector(dir_ego),
            };
            let hit = world.cast(&ray, 1e3).expect("beam hits something");
            worst = worst.max((hit.t - range).abs());
            // 2. The camera's view of the same point.
            let Some(uv) = cam.project_ego(p_ego) else { continue };
            if !cam.contains_pixel(uv) {
                continue;
            }
            in_view += 1;
            let world_from_camera = frame.world_from_ego * cam.ego_from_camera;
            let (ray, cos) = raycast::pixel_ray(cam, &world_from_camera, uv.x, uv.y);
            let depth_point = cam.ego_from_camera.inverse().transform_point(p_ego).x;
            let depth_cam = world.cast(&ray, 1e4).map_or(f64::INFINITY, |h| h.t * cos);
            assert!(depth_cam < depth_point + 1e-3, "camera sees through a LiDAR point: {depth_cam} vs {depth_point}");
            if (depth_cam - depth_point).abs() < 1e-3 {
                seen += 1;
            }
        }
        assert!(worst < 1e-3, "frame {f}: LiDAR range off by {worst} m");
        assert!(in_view > 1000 && seen * 10 > in_view * 7, "frame {f}: {seen} of {in_view} seen by FRONT");
        // 3. GT depth file vs pixel-centre rays.
        let depth = gt::read_f32(&dir.join(gt::gt_rel_path(f, "FRONT", "depth.f32.gz"))).unwrap();
        let world_from_camera = frame.world_from_ego * cam.ego_from_camera;
        let w = cam.width as usize;
        for (i, &d) in depth.iter().enumerate().step_by(7) {
            let (ray, cos) = raycast::pixel_ray(cam, &world_from_camera, (i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
            match world.cast(&ray, f64::INFINITY) {
                Some(h) => assert!((h.t * cos - d as f64).abs() < 1e-3),
                None => assert!(d.is_infinite()),
            }
        }
    }
}

fn files(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.push((p.strip_prefix(dir).unwrap().to_path_buf(), std::fs::read(&p).unwrap()));
            }
        }
    }
    out.sort();
    out
}

#[test]
fn same_seed_same_bytes_other_seed_differs() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg =
        SynthConfig { frames: 3, cameras: 2, width: 64, height: 48, seed: 3, preview: true, ..Default::default() };
    let run = |name: &str, cfg: &SynthConfig| {
        let dir = tmp.path().join(name);
        synth::synthesize(cfg, &dir, &mut |_, _| {}).unwrap();
        files(&dir)
    };
    let a = run("a", &cfg);
    let b = run("b", &cfg);
    assert!(a.len() > 20 && a.iter().any(|(p, _)| p.ends_with("preview.png")));
    assert_eq!(a.iter().map(|f| &f.0).collect::<Vec<_>>(), b.iter().map(|f| &f.0).collect::<Vec<_>>());
    for (x, y) in a.iter().zip(&b) {
        assert!(x.1 == y.1, "{} differs between runs of the same seed", x.0.display());
    }
    let c = run("c", &SynthConfig { seed: 4, ..cfg.clone() });
    let differ = a.iter().zip(&c).filter(|(x, y)| x.1 != y.1).count();
    assert!(differ > a.len() / 2, "only {differ} files differ for another seed");
}

#[test]
fn bad_settings_are_errors_and_leave_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("scene");
    let base = SynthConfig { frames: 1, cameras: 1, width: 32, height: 24, ..Default::default() };
    for (cfg, needle) in [
        (SynthConfig { cameras: 0, ..base.clone() }, "--cameras"),
        (SynthConfig { cameras: 6, ..base.clone() }, "--cameras"),
        (SynthConfig { width: 0, ..base.clone() }, "--width"),
        (SynthConfig { height: 100_000, ..base.clone() }, "--height"),
        (SynthConfig { frames: 0, ..base.clone() }, "--frames"),
    ] {
        let err = synth::synthesize(&cfg, &out, &mut |_, _| {}).unwrap_err();
        assert!(matches!(err, SynthError::Config(_)) && err.to_string().contains(needle), "{err}");
        assert!(!out.exists());
    }
    synth::synthesize(&base, &out, &mut |_, _| {}).unwrap();
    let err = synth::synthesize(&base, &out, &mut |_, _| {}).unwrap_err();
    assert!(err.to_string().contains("--force"), "{err}");
    synth::synthesize(&SynthConfig { force: true, ..base }, &out, &mut |_, _| {}).unwrap();
    assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 1, "staging left behind");
}
