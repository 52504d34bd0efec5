//! Real-data check of our camera model and frame conventions: the shared Waymo frame's 3D
//! vehicle labels (boxes upright in the vehicle = ego frame), projected with the calibration
//! that ingest stored in the scene, reproduce the frame's own `projected_lidar_labels` boxes.
//! A second test checks that the scene's world-frame tracks map back onto the labels.

use indicatif::ProgressBar;
use ingest::proto::{label, Frame, Label};
use ingest::tfrecord::TfRecordReader;
use prost::Message;
use scene::frames::{box_corners, heading_in, world_from_box, wrap_angle};
use scene::glam::{DVec2, DVec3};
use scene::Scene;
use std::path::PathBuf;

fn load() -> Option<(Scene, Frame)> {
    let path: PathBuf = ingest::shared::waymo_file("pvps_data_one_frame.tfrecord")?;
    let mut scenes =
        ingest::read_scenes(std::slice::from_ref(&path), ingest::Expect::Auto, &ProgressBar::hidden()).unwrap();
    let record = TfRecordReader::new(std::fs::File::open(&path).unwrap()).next().unwrap().unwrap();
    Some((scenes.remove(0), Frame::decode(&record.data[..]).unwrap()))
}

fn label_box(l: &Label) -> (DVec3, f64, [f64; 3]) {
    let b = l.r#box.as_ref().unwrap();
    (
        DVec3::new(b.center_x.unwrap(), b.center_y.unwrap(), b.center_z.unwrap()),
        b.heading.unwrap(),
        [b.length.unwrap(), b.width.unwrap(), b.height.unwrap()],
    )
}

#[test]
fn vehicle_labels_project_onto_waymo_projected_boxes() {
    let Some((scene, frame)) = load() else { return };
    let mut errors = Vec::new();
    let mut skipped_behind = 0;
    for cam_labels in &frame.projected_lidar_labels {
        let cam_name = ingest::waymo_frame::camera_name_str(cam_labels.name.unwrap()).unwrap();
        let camera = scene.camera(cam_name).unwrap();
        let size = DVec2::new(camera.width as f64, camera.height as f64);
        for projected in &cam_labels.labels {
            let id = projected.id.as_deref().unwrap();
            let laser_id = id.strip_suffix(&format!("_{cam_name}")).expect("projected ids are <laser id>_<CAMERA>");
            let l = frame.laser_labels.iter().find(|l| l.id.as_deref() == Some(laser_id)).unwrap();
            if l.r#type != Some(label::Type::Vehicle as i32) {
                continue;
            }
            let (center, heading, lwh) = label_box(l);
            let ego_from_box = world_from_box(center, heading); // boxes are upright in the ego frame
            let uv: Option<Vec<DVec2>> =
                box_corners(lwh).iter().map(|c| camera.project_ego(ego_from_box.transform_point(*c))).collect();
            let Some(uv) = uv else {
                skipped_behind += 1;
                continue;
            };
            // Waymo clips projected boxes to the image; so do we.
            let lo = uv.iter().fold(DVec2::splat(f64::MAX), |m, p| m.min(*p)).clamp(DVec2::ZERO, size);
            let hi = uv.iter().fold(DVec2::splat(f64::MIN), |m, p| m.max(*p)).clamp(DVec2::ZERO, size);
            let b = projected.r#box.as_ref().unwrap();
            let c = DVec2::new(b.center_x.unwrap(), b.center_y.unwrap());
            let half = DVec2::new(b.length.unwrap(), b.width.unwrap()) / 2.0;
            errors.push((lo - (c - half)).length());
            errors.push((hi - (c + half)).length());
        }
    }
    errors.sort_by(f64::total_cmp);
    let median = errors[errors.len() / 2];
    println!(
        "vehicle boxes {}, skipped (a corner behind the camera) {skipped_behind}, corner error median {median:.3} px, p75 {:.3} px",
        errors.len() / 2,
        errors[errors.len() * 3 / 4],
    );
    assert!(errors.len() / 2 >= 25, "too few vehicle boxes compared: {}", errors.len() / 2);
    assert!(median < 1.0, "median corner error {median} px");
}

#[test]
fn world_tracks_map_back_onto_vehicle_frame_labels() {
    let Some((scene, frame)) = load() else { return };
    assert_eq!(scene.tracks.len(), frame.laser_labels.len());
    let world_from_ego = scene.frames[0].world_from_ego;
    let ego_from_world = world_from_ego.inverse();
    for l in &frame.laser_labels {
        let (center, heading, lwh) = label_box(l);
        let s = scene.track(l.id.as_deref().unwrap()).unwrap().state_at(0).unwrap();
        assert!((ego_from_world.transform_point(s.center) - center).length() < 1e-6);
        // Stored upright in the world: the heading differs only by the ego's small pitch/roll.
        assert!(wrap_angle(heading_in(&ego_from_world, s.heading) - heading).abs() < 0.02, "{:?}", l.id);
        assert!(wrap_angle(s.heading - heading_in(&world_from_ego, heading)).abs() < 1e-12);
        assert_eq!(s.size_lwh, lwh);
    }
}
