//! Shared by the real-path and high-speed tests: drive a timed path through smoothing, PID and
//! vehicle model like a rollout does ("PID from frame 0"), and measure the result.
#![allow(dead_code)]

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use scene::glam::DVec2;
use scene::motion::Pose2;
use sim::reference::start_for_path;
use sim::tracker::Tracker;
use sim::validity::{assess, BoxSize};
use sim::RolloutConfig;

/// What one drive did.
#[derive(Clone, Debug)]
pub struct Drive {
    /// RMS and 95th percentile of the distance to the (smoothed) reference (m).
    pub rms_ref: f64,
    pub p95_ref: f64,
    /// RMS distance to the noise-free path at the same times (m).
    pub rms_truth: f64,
    pub validity: scene::executed::Validity,
    /// Comfort of the executed path and of the noise-free path, 0.1 s grid.
    pub executed: metrics::Comfort,
    pub logged: metrics::Comfort,
}

pub fn percentile(v: &[f64], q: f64) -> f64 {
    metrics::kinematics::percentile(v, q).unwrap_or(f64::NAN)
}

/// Drives `observed` (what the log says, perhaps noisy) with its first logged heading;
/// `truth` is the noise-free path at the same times.
pub fn drive(observed: &[(f64, DVec2)], heading0: f64, truth: &[(f64, DVec2)], cfg: &RolloutConfig) -> Drive {
    let start = start_for_path(observed, observed.len(), heading0, &cfg.smoothing).expect("reference");
    let r = &start.reference;
    let (t0, t1) = (r.start_time(), r.end_time());
    let p0 = r.position(t0);
    let x0 = [p0.x, p0.y, 0.0, start.speed, start.heading, 0.0, 0.0];
    let tracker = Tracker { config: &cfg.tracker, vehicle: &cfg.vehicle, actuation: &cfg.actuation };
    let rec = tracker.run(r, x0, t0, t1, |_, _| {}).expect("finite rollout");
    let size = BoxSize { length: cfg.vehicle.length, width: cfg.vehicle.width };
    let validity = assess(&rec, t0, None, None, size, &cfg.validity);
    let errs: Vec<f64> = rec.iter().map(|s| DVec2::new(s.state[0], s.state[1]).distance(s.reference)).collect();
    let rms = |e: &[f64]| (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt();
    let truth_pose: Vec<Pose2> = truth.iter().map(|(t, p)| Pose2 { t: *t, x: p.x, y: p.y, heading: 0.0 }).collect();
    let truth_errs: Vec<f64> = rec
        .iter()
        .filter_map(|s| {
            scene::motion::sample_series(&truth_pose, s.t)
                .map(|q| q.position().distance(DVec2::new(s.state[0], s.state[1])))
        })
        .collect();
    let exec_pose: Vec<Pose2> =
        rec.iter().map(|s| Pose2 { t: s.t, x: s.state[0], y: s.state[1], heading: s.state[4] }).collect();
    let dt = metrics::kinematics::METRIC_DT_S;
    let grid_end = t1.min(truth_pose[truth_pose.len() - 1].t);
    let comfort = |p: &[Pose2]| {
        metrics::comfort::comfort(&metrics::kinematics::uniform(p, t0, grid_end, dt), dt).expect("long enough path")
    };
    Drive {
        rms_ref: rms(&errs),
        p95_ref: percentile(&errs, 95.0),
        rms_truth: rms(&truth_errs),
        validity,
        executed: comfort(&exec_pose),
        logged: comfort(&truth_pose),
    }
}

/// Gaussian noise of `sigma` on every position, and (with `jumps`) about one sample in 100
/// displaced by 2 m in a random direction for a single frame. Deterministic for a seed.
pub fn perturb(path: &[(f64, DVec2)], sigma: f64, jumps: bool, seed: u64) -> Vec<(f64, DVec2)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut gauss = move || {
        // Box-Muller.
        let (u1, u2): (f64, f64) = (rng.random::<f64>().max(1e-300), rng.random::<f64>());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    };
    let mut jump_rng = ChaCha8Rng::seed_from_u64(seed ^ 0x5eed);
    path.iter()
        .map(|(t, p)| {
            let mut q = *p + DVec2::new(gauss(), gauss()) * sigma;
            if jumps && jump_rng.random::<f64>() < 0.01 {
                let a = jump_rng.random::<f64>() * std::f64::consts::TAU;
                q += DVec2::new(a.cos(), a.sin()) * 2.0;
            }
            (*t, q)
        })
        .collect()
}
