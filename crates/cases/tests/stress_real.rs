//! The stress perturbations (`cases::stress`) on the real WOMD scenes: mirroring twice is the
//! identity, noise stays within 0.3 m, added parked cars touch no logged road user at any frame,
//! a bend keeps the ego's path length, faster traffic keeps the ego's log. Skips with a printed
//! reason where `../shared/data` is absent.

use cases::stress::box2::Box2;
use cases::stress::{bend, mirror, noise, parked, speed};
use scene::Scene;
use std::path::PathBuf;

fn womd() -> Option<Vec<Scene>> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/waymo");
    let files: Vec<PathBuf> =
        ["motion_data_one_scenario.tfrecord", "womd_scenario_input.tfrecord"].iter().map(|f| dir.join(f)).collect();
    if let Some(f) = files.iter().find(|f| !f.is_file()) {
        println!("SKIP: {} not found (shared data folder absent)", f.display());
        return None;
    }
    let pb = indicatif::ProgressBar::hidden();
    Some(
        files
            .iter()
            .flat_map(|f| ingest::read_scenes(std::slice::from_ref(f), ingest::Expect::Scenario, &pb).unwrap())
            .collect(),
    )
}

#[test]
fn perturbations_hold_on_real_scenes() {
    let Some(scenes) = womd() else { return };
    for s in &scenes {
        let mut twice = mirror::mirror(&mirror::mirror(s));
        twice.name = s.name.clone();
        assert_eq!(&twice, s, "{}: mirror twice", s.name);

        let n = noise::noise(s, noise::MAX_NOISE_M, 11);
        for (a, b) in s.tracks.iter().zip(&n.tracks) {
            for (x, y) in a.states.iter().zip(&b.states) {
                assert!((x.center - y.center).length() <= noise::MAX_NOISE_M + 1e-9);
            }
        }

        let p = parked::add_parked(s, &parked::ParkedConfig::default(), 4);
        let logged = parked::occupied(s);
        let added: Vec<_> = p.tracks.iter().filter(|t| t.id.starts_with("parked-")).collect();
        println!("{}: {} parked cars added", s.name, added.len());
        assert!(!added.is_empty(), "{}: a real street has room for a parked car", s.name);
        for t in added {
            let st = &t.states[0];
            let b = Box2::new(st.center.truncate(), st.heading, st.size_lwh[0], st.size_lwh[1]);
            assert!(logged.iter().all(|o| !o.overlaps(&b)), "{} overlaps a logged road user", t.id);
        }

        let bent = bend::bend(s, bend::CORPUS_RADIUS_M).unwrap();
        let (d0, d1) = (s.ego_distance_m(), bent.ego_distance_m());
        assert!((d1 - d0).abs() <= 0.02 * d0 + 0.05, "{}: ego path {d0} m became {d1} m", s.name);

        let f = speed::speed_up(s, speed::CORPUS_FACTOR).unwrap();
        assert_eq!(f.frames.len(), s.frames.len());
        assert!(f.frames.iter().zip(&s.frames).all(|(a, b)| a.world_from_ego == b.world_from_ego));
    }
}
