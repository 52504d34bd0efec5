//! LiDAR for every image of a real log (PandaSet 002: 71 of 80 frames have no sweep): the nearest
//! sweeps' static points, and the moving objects' points carried with their boxes to each image's
//! own time.

use indicatif::ProgressBar;
use recon::init::ACTOR_FLOOR_M;
use recon::pose::box_pose_at;
use recon::priors::sweeps::{Sweeps, BORROWED_SWEEPS};
use scene::frames::world_from_box;
use scene::glam::DVec3;
use scene::LoggedMotion;

fn world(pose: &scene::Transform3, p: &[f32; 4]) -> DVec3 {
    pose.transform_point(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64))
}

#[test]
fn every_image_gets_the_street_and_the_moving_cars_where_they_are_then() {
    let Some(src) = ingest::shared::data_path("pandaset/002") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("scene");
    let w = ingest::ingest(&[src], &dir, ingest::Expect::Pandaset, false, &ProgressBar::hidden()).unwrap();
    let scene = &w[0].scene;
    let sweeps = Sweeps::new(&dir, scene);
    assert!(sweeps.any());
    // Frame 8 has its own sweep; frame 12 borrows the nearest three (8, 16 and 0 or 24).
    assert_eq!(sweeps.sources(8), vec![8]);
    let borrowed = sweeps.sources(12);
    assert_eq!(borrowed.len(), BORROWED_SWEEPS);
    let mut nearest = borrowed[..2].to_vec();
    nearest.sort();
    assert_eq!(nearest, [8, 16]);
    let l = sweeps.load(8).unwrap();
    let on_movers: usize = l.movers.iter().map(|m| m.1.len()).sum();
    assert!(l.movers.len() > 10 && on_movers > 500 && on_movers < l.len() / 5, "{on_movers} of {}", l.len());
    // No still point lies inside the box (above its road band) of a car the log labels Moving at
    // the sweep's frame.
    let moving: Vec<_> = scene
        .tracks
        .iter()
        .filter_map(|t| t.state_at(8))
        .filter(|s| s.motion == Some(LoggedMotion::Moving))
        .map(|s| (world_from_box(s.center, s.heading).inverse(), s.size_lwh))
        .collect();
    assert!(moving.len() > 10);
    for p in &l.still {
        let w = world(&l.world_from_ego, p);
        for (box_from_world, size) in &moving {
            let b = box_from_world.transform_point(w);
            let inside = b.x.abs() < size[0] / 2.0 && b.y.abs() < size[1] / 2.0 && b.z.abs() < size[2] / 2.0;
            assert!(!(inside && b.z > -size[2] / 2.0 + ACTOR_FLOOR_M), "a point of a moving car at {w} is still");
        }
    }
    // At an image of frame 12 (its own time): the still points are the same world points, and
    // every carried point of a car is inside that car's box at the image's time.
    let f = &scene.frames[12];
    let im = &f.images[0];
    let t = im.timestamp_s.unwrap();
    let world_from_image_ego = scene.world_from_ego_of_image(f, im);
    let at_image = sweeps.in_image_ego(f, im, std::slice::from_ref(&l));
    for (a, b) in l.still.iter().zip(&at_image) {
        assert!((world(&l.world_from_ego, a) - world(&world_from_image_ego, b)).length() < 1e-3);
    }
    let mut carried = 0;
    let mut rest = &at_image[l.still.len()..];
    for (track, pts) in &l.movers {
        let Some(pose) = box_pose_at(scene, track, t) else { continue };
        let box_from_world = pose.world_from_box().inverse();
        let size = track.state_at(12).or(track.state_at(8)).unwrap().size_lwh;
        for p in &rest[..pts.len()] {
            let b = box_from_world.transform_point(world(&world_from_image_ego, p));
            // Inside the box grown as the points were picked (label slack and a sweep's travel).
            assert!(b.y.abs() <= size[1] * 0.56 && b.z.abs() <= size[2] * 0.56, "{} at {b}", track.id);
            carried += 1;
        }
        rest = &rest[pts.len()..];
    }
    assert!(rest.is_empty() && carried > 500, "{carried} carried");
}
