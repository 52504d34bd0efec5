//! A parked car that pulls away: the failure found on the shared WOMD scenes (a stationary
//! vehicle whose logged heading points along -y, jittering by millimetres, asked to drive off
//! along its body). The smoother, told the log was 0.3 m noisy, bent the stillness and the plan
//! into one parabola; the car started 0.5 m from its parked spot at 1.2 m/s **backwards**, turned
//! round and left the road. Now: a still log keeps the car at its spot, at rest, facing its body,
//! the reference never backs up, and the rollout is valid. Checked for several body headings and
//! plan directions up to 30 degrees off the body.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use scene::glam::DVec2;
use sim::reference::start_for_path;
use sim::tracker::Tracker;
use sim::validity::{assess, BoxSize};
use sim::RolloutConfig;

/// 1 s parked with `jitter` m of noise, then 3 s of a plan from rest at 2 m/s^2, turning
/// gradually from the body heading by `turn` rad.
fn parked_then_pull_away(body: f64, turn: f64, jitter: f64, seed: u64) -> (Vec<(f64, DVec2)>, usize) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let spot = DVec2::new(6412.0, 821.9);
    let mut points: Vec<(f64, DVec2)> = (0..10)
        .map(|k| {
            (k as f64 * 0.1, spot + DVec2::new(rng.random_range(-jitter..=jitter), rng.random_range(-jitter..=jitter)))
        })
        .collect();
    let n_logged = points.len();
    let (mut p, mut v, mut psi) = (spot, 0.0f64, body);
    let h = 0.01;
    for k in 0..=300 {
        let s = k as f64 * h;
        if k % 10 == 0 {
            points.push((1.0 + s, p));
        }
        v += 2.0 * h;
        psi += turn / 3.0 * h;
        p += DVec2::new(psi.cos(), psi.sin()) * v * h;
    }
    (points, n_logged)
}

#[test]
fn a_parked_car_starts_at_its_spot_at_rest_and_never_backs_up() {
    let cfg = RolloutConfig::default();
    for (i, body) in [-1.574, 0.0, 2.5, 10.0045].into_iter().enumerate() {
        for turn in [0.0, 0.3, -0.5] {
            for jitter in [0.0, 0.003, 0.05] {
                let (points, n_logged) = parked_then_pull_away(body, turn, jitter, i as u64);
                let spot = points[0].1;
                let start = start_for_path(&points, n_logged, body, &cfg.smoothing).unwrap();
                let r = &start.reference;
                let (t0, t1) = (r.start_time(), r.end_time());
                let label = format!("body {body} turn {turn} jitter {jitter}");
                assert!(start.speed < 0.3, "{label}: starts at {} m/s", start.speed);
                assert!((start.heading - body).abs() < 1e-12, "{label}: heading {}", start.heading);
                assert!(r.position(t0).distance(spot) < 0.1, "{label}: starts {} m off", r.position(t0).distance(spot));
                // The reference never moves backwards along the body while the car is parked.
                let dir = DVec2::new(body.cos(), body.sin());
                let back = (0..=20).map(|k| (r.position(t0 + 0.05 * k as f64) - spot).dot(dir)).fold(0.0, f64::min);
                assert!(back > -0.05, "{label}: reference backs up {back} m");

                let x0 = [r.position(t0).x, r.position(t0).y, 0.0, start.speed, start.heading, 0.0, 0.0];
                let tracker = Tracker { config: &cfg.tracker, vehicle: &cfg.vehicle, actuation: &cfg.actuation };
                let rec = tracker.run(r, x0, t0, t1, |_, _| {}).unwrap();
                let size = BoxSize { length: cfg.vehicle.length, width: cfg.vehicle.width };
                let validity = assess(&rec, t0, None, None, size, &cfg.validity);
                assert!(validity.valid, "{label}: {validity:?}");
                assert!(validity.max_tracking_error_m < 1.5, "{label}: {validity:?}");
            }
        }
    }
}
