//! LiDAR for the frames of a real log that have no sweep (PandaSet 002: 71 of 80): borrowed from the
//! nearest sweeps with the moving objects cut out, and placed at each image's own time.

use indicatif::ProgressBar;
use recon::priors::sweeps::{Sweeps, BORROWED_SWEEPS};
use scene::frames::world_from_box;
use scene::glam::DVec3;
use scene::LoggedMotion;

#[test]
fn frames_without_lidar_borrow_the_static_part_of_the_nearest_sweeps() {
    let Some(src) = ingest::shared::data_path("pandaset/002") else { return };
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("scene");
    let w = ingest::ingest(&[src], &dir, ingest::Expect::Pandaset, false, &ProgressBar::hidden()).unwrap();
    let scene = &w[0].scene;
    let sweeps = Sweeps::new(&dir, scene);
    assert!(sweeps.any());
    // Frame 8 has its own sweep, used whole; frame 12 borrows the nearest three (8, 16 and 0 or 24).
    assert_eq!(sweeps.sources(8), vec![(8, false)]);
    let borrowed = sweeps.sources(12);
    assert_eq!(borrowed.len(), BORROWED_SWEEPS);
    assert!(borrowed.iter().all(|(_, static_only)| *static_only));
    let mut nearest: Vec<usize> = borrowed[..2].iter().map(|b| b.0).collect();
    nearest.sort();
    assert_eq!(nearest, [8, 16]);
    let (whole_pose, whole) = sweeps.load(8, false).unwrap();
    let (pose, kept) = sweeps.load(8, true).unwrap();
    assert_eq!(whole_pose, pose);
    let dropped = whole.len() - kept.len();
    assert!(dropped > 500 && dropped < whole.len() / 5, "{dropped} of {} points dropped", whole.len());
    // No kept point lies inside the box of a car the log labels Moving at the sweep's frame.
    let moving: Vec<_> = scene
        .tracks
        .iter()
        .filter_map(|t| t.state_at(8))
        .filter(|s| s.motion == Some(LoggedMotion::Moving))
        .map(|s| (world_from_box(s.center, s.heading).inverse(), s.size_lwh))
        .collect();
    assert!(moving.len() > 10);
    for p in &kept {
        let w = pose.transform_point(DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64));
        for (box_from_world, size) in &moving {
            let b = box_from_world.transform_point(w);
            assert!(
                !(b.x.abs() < size[0] / 2.0 && b.y.abs() < size[1] / 2.0 && b.z.abs() < size[2] / 2.0),
                "a point of a moving car at {w} was kept"
            );
        }
    }
    // Carried to an image of frame 12 taken at its own time: the same world points.
    let f = &scene.frames[12];
    let im = &f.images[0];
    let loaded = vec![(pose, kept[..10].to_vec())];
    let at_image = sweeps.in_image_ego(f, im, &loaded);
    let world_from_image_ego = scene.world_from_ego_of_image(f, im);
    for (a, b) in kept[..10].iter().zip(&at_image) {
        let wa = pose.transform_point(DVec3::new(a[0] as f64, a[1] as f64, a[2] as f64));
        let wb = world_from_image_ego.transform_point(DVec3::new(b[0] as f64, b[1] as f64, b[2] as f64));
        assert!((wa - wb).length() < 1e-3);
    }
}
