//! The moving-vehicle masks and the protocols' pairs on a real log (PandaSet 002), and the mask
//! files' round trip and refusals.

use indicatif::ProgressBar;
use recon::data::{view_stubs, View};
use recon::eval::vehicle_masks_of;
use recon::protocol::{pairs, sightings, Protocol, FAR_M, NEAR_M, SIDE_DEG};

fn pandaset() -> Option<(tempfile::TempDir, scene::Scene)> {
    let src = ingest::shared::data_path("pandaset/002")?;
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("scene");
    let w = ingest::ingest(&[src], &dir, ingest::Expect::Pandaset, false, &ProgressBar::hidden()).unwrap();
    let scene = w[0].scene.clone();
    Some((tmp, scene))
}

#[test]
fn moving_vehicles_of_the_held_out_views_at_full_and_quarter_size() {
    let Some((_tmp, scene)) = pandaset() else { return };
    let held = |scale: f64| -> Vec<View> {
        view_stubs(&scene, scale, 8, &|f| f.is_multiple_of(8)).unwrap().into_iter().filter(|v| v.held_out).collect()
    };
    let (full, quarter) = (held(1.0), held(0.25));
    assert_eq!(full.len(), 30);
    let count = |m: &[bool]| m.iter().filter(|x| **x).count();
    let mut with_cars = 0;
    for (f, q) in full.iter().zip(&quarter) {
        let (mf, mq) = (vehicle_masks_of(&scene, f), vehicle_masks_of(&scene, q));
        // The same vehicles at both sizes (a pair is kept where either mask covers a pixel, and a
        // car a few pixels wide at full size can cover none at a quarter).
        assert!(mq.vehicles.len() <= mf.vehicles.len());
        // Every vehicle's rectangle holds its hull; the unions hold every vehicle's masks.
        for (_, _, h, r) in &mf.vehicles {
            assert!(h.iter().zip(r).all(|(a, b)| !a || *b));
            assert!(h.iter().zip(&mf.hull).all(|(a, b)| !a || *b));
        }
        if count(&mf.hull) > 0 {
            with_cars += 1;
            // A quarter of the size, a sixteenth of the pixels (to the edges' rounding).
            let (a, b) = (count(&mf.rect) as f64, count(&mq.rect) as f64 * 16.0);
            assert!((a - b).abs() <= 0.25 * a + 400.0, "frame {} {}: {a} vs {b}", f.frame, f.camera);
        }
    }
    // The log's moving cars are in most held-out images (20 of 30 at the quarter size, 2026-12-07).
    assert!(with_cars >= 15, "{with_cars} held-out images show a moving vehicle");
}

#[test]
fn the_protocols_choose_near_and_side_views_of_cars_also_seen_far_and_end_on() {
    let Some((_tmp, scene)) = pandaset() else { return };
    let views = view_stubs(&scene, 0.25, 8, &|_| true).unwrap();
    let seen = sightings(&scene, &views);
    let close = pairs(Protocol::CloseUp, &seen);
    let turned = pairs(Protocol::Turned, &seen);
    assert!(close.iter().all(|s| s.distance_m < NEAR_M) && turned.iter().all(|s| s.angle_deg > SIDE_DEG));
    for p in &close {
        assert!(seen.iter().any(|s| s.track == p.track && s.distance_m > FAR_M), "{} is also seen far", p.track);
    }
    let tracks = |ps: &[recon::protocol::Sighting]| {
        ps.iter().map(|s| s.track.clone()).collect::<std::collections::BTreeSet<_>>()
    };
    println!(
        "close-up: {} pairs of {} vehicles; turned: {} pairs of {} vehicles",
        close.len(),
        tracks(&close).len(),
        turned.len(),
        tracks(&turned).len()
    );
    // A street drive passes parked and moving cars: both protocols have something to score.
    assert!(tracks(&close).len() >= 3 && tracks(&turned).len() >= 3);
    // No held-out view is ever left out of training: they are scored as they are.
    assert!(close.iter().chain(&turned).all(|s| !s.frame.is_multiple_of(8)));
}

#[test]
fn mask_files_round_trip_and_refuse_what_does_not_fit() {
    let cam = splat::Camera::at_origin(12, 8, 10.0);
    let view = |frame: usize| View {
        frame,
        camera: "C".into(),
        time: 0.0,
        image_time: 0.0,
        cam,
        targets: Default::default(),
        held_out: true,
    };
    let (a, b) = (view(0), view(8));
    let mask = |k: usize| (0..96).map(|i| (i + k).is_multiple_of(5)).collect::<Vec<bool>>();
    let ma = recon::eval_vehicle::ViewMasks {
        vehicles: vec![("car".into(), 7.5, mask(1), mask(2))],
        hull: mask(1),
        rect: mask(2),
    };
    let mb = recon::eval_vehicle::ViewMasks { vehicles: vec![], hull: mask(3), rect: mask(4) };
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("masks");
    recon::vehicle_masks::write(&dir, "s", &[(&a, &ma), (&b, &mb)]).unwrap();
    let back = recon::vehicle_masks::read(&dir, "s", &[&a, &b]).unwrap();
    let ra = &back[&(0, "C".to_string())];
    assert_eq!((&ra.hull, &ra.rect), (&ma.hull, &ma.rect));
    assert_eq!(ra.vehicles[0].0, "car");
    assert_eq!((ra.vehicles[0].1, &ra.vehicles[0].2, &ra.vehicles[0].3), (7.5, &mask(1), &mask(2)));
    // Another scene, a view the folder does not hold, another size: refused, naming what.
    let e = recon::vehicle_masks::read(&dir, "t", &[&a]).unwrap_err().to_string();
    assert!(e.contains("masks.json") && e.contains("\"t\""), "{e}");
    let e = recon::vehicle_masks::read(&dir, "s", &[&view(16)]).unwrap_err().to_string();
    assert!(e.contains("no masks for frame 16 camera C"), "{e}");
    let mut big = view(0);
    big.cam = splat::Camera::at_origin(24, 16, 20.0);
    let e = recon::vehicle_masks::read(&dir, "s", &[&big]).unwrap_err().to_string();
    assert!(e.contains("masks of 12x8, the view is 24x16"), "{e}");
    // An index naming a file outside the folder is refused, not followed.
    let index = std::fs::read_to_string(dir.join("masks.json")).unwrap().replace("v0000-hull.png", "../outside.png");
    std::fs::write(dir.join("masks.json"), index).unwrap();
    let e = recon::vehicle_masks::read(&dir, "s", &[&a]).unwrap_err().to_string();
    assert!(e.contains("not a file name inside the folder"), "{e}");
    // Writing over an existing folder is refused (a new folder, or read).
    assert!(recon::vehicle_masks::write(&dir, "s", &[(&a, &ma)]).is_err());
}
