//! Real paths at real speeds: the KITTI odometry ground-truth paths of sequences 00 (3.7 km) and
//! 06 (1.2 km), up to about 14.6 m/s, driven through smoothing + PID + vehicle model, clean and
//! with Gaussian position noise (0.1, 0.3, 0.5 m) and single-frame 2 m jumps. Each sequence is cut
//! into 20 s windows starting every 10 s, each driven from its own first logged state (as a
//! corner case starts from a log), and each whole sequence is driven once.
//!
//! Pose files (`../shared/data/kitti/poses/NN.txt`): row-major 3x4 `[R|t]` =
//! world_from_left_camera, world = left camera at frame 0, camera axes x right, y down, z
//! forward. Our world is z-up with x forward, y left: `p = (t_z, -t_x)`, heading from the camera's
//! forward axis `R[:, 2]`: `atan2(-R02, R22)`.
//!
//! Must hold for every rollout, clean or noisy: no divergence, no time at the friction limit
//! beyond the validity threshold, |a_lat| <= mu g + 0.5 at every control step; over the windows
//! of each variant, a median RMS distance to the clean path below 0.5 m and medians of the
//! executed |a_lat|95 and |kappa_dot|95 no worse than the logged path's own (+0.2 m/s^2 for
//! a_lat). The numbers are printed (recorded in BENCHMARKS.md).

mod common;

use common::{drive, percentile, perturb, Drive};
use scene::glam::DVec2;
use sim::RolloutConfig;
use std::path::PathBuf;

struct Path {
    name: String,
    points: Vec<(f64, DVec2)>,
    headings: Vec<f64>,
}

fn kitti(seq: &str) -> Option<Path> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/kitti/poses");
    let (poses, times) = (dir.join(format!("{seq}.txt")), dir.join(format!("{seq}_times.txt")));
    if !poses.is_file() || !times.is_file() {
        eprintln!("SKIP: {} not found (shared data folder absent)", poses.display());
        return None;
    }
    let read = |p: &PathBuf| std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    let nums = |line: &str| -> Vec<f64> {
        line.split_whitespace().map(|x| x.parse().unwrap_or_else(|e| panic!("{seq}: bad number {x}: {e}"))).collect()
    };
    let ts: Vec<f64> = read(&times).lines().filter(|l| !l.trim().is_empty()).map(|l| nums(l)[0]).collect();
    let rows: Vec<Vec<f64>> = read(&poses).lines().filter(|l| !l.trim().is_empty()).map(nums).collect();
    assert_eq!(ts.len(), rows.len(), "{seq}: one time per pose");
    let points = ts.iter().zip(&rows).map(|(t, m)| (*t, DVec2::new(m[11], -m[3]))).collect();
    let headings = rows.iter().map(|m| (-m[2]).atan2(m[10])).collect();
    Some(Path { name: seq.into(), points, headings })
}

const WINDOW_S: f64 = 20.0;
const STRIDE_S: f64 = 10.0;

/// `(start index, end index)` of every window.
fn windows(p: &Path) -> Vec<(usize, usize)> {
    let t = |i: usize| p.points[i].0;
    let mut out = Vec::new();
    let mut start = 0;
    while start < p.points.len() && t(start) + WINDOW_S <= t(p.points.len() - 1) {
        let end = p.points.partition_point(|(ti, _)| *ti <= t(start) + WINDOW_S);
        out.push((start, end));
        start = p.points.partition_point(|(ti, _)| *ti < t(start) + STRIDE_S);
    }
    out
}

struct Variant {
    name: &'static str,
    sigma: f64,
    jumps: bool,
}

const VARIANTS: [Variant; 5] = [
    Variant { name: "clean", sigma: 0.0, jumps: false },
    Variant { name: "noise 0.1 m", sigma: 0.1, jumps: false },
    Variant { name: "noise 0.3 m", sigma: 0.3, jumps: false },
    Variant { name: "noise 0.5 m", sigma: 0.5, jumps: false },
    Variant { name: "0.1 m + jumps", sigma: 0.1, jumps: true },
];

fn summary(name: &str, drives: &[Drive]) -> String {
    let col = |f: &dyn Fn(&Drive) -> f64| drives.iter().map(f).collect::<Vec<_>>();
    let (rms, rms_truth) = (col(&|d| d.rms_ref), col(&|d| d.rms_truth));
    let (ea, la) = (col(&|d| d.executed.a_lat_p95), col(&|d| d.logged.a_lat_p95));
    let (ek, lk) = (col(&|d| d.executed.kappa_dot_p95), col(&|d| d.logged.kappa_dot_p95));
    let max_alat = col(&|d| d.validity.max_abs_accel_lat).into_iter().fold(0.0, f64::max);
    let friction = col(&|d| d.validity.friction_limit_s).into_iter().fold(0.0, f64::max);
    format!(
        "{name:<14} n {:>3} | RMS to reference median {:.3} p95 {:.3} max {:.3} m | RMS to clean path median {:.3} p95 {:.3} m | |a_lat|95 executed {:.2} vs logged {:.2} (medians) | |kappa_dot|95 executed {:.3} vs logged {:.3} | max |a_lat| {:.2} | max time at limit {:.2} s",
        drives.len(),
        percentile(&rms, 50.0),
        percentile(&rms, 95.0),
        percentile(&rms, 100.0),
        percentile(&rms_truth, 50.0),
        percentile(&rms_truth, 95.0),
        percentile(&ea, 50.0),
        percentile(&la, 50.0),
        percentile(&ek, 50.0),
        percentile(&lk, 50.0),
        max_alat,
        friction,
    )
}

#[test]
fn kitti_paths_clean_and_noisy() {
    let (Some(p00), Some(p06)) = (kitti("00"), kitti("06")) else { return };
    let cfg = RolloutConfig::default();
    let limit = cfg.vehicle.friction * 9.81 + 0.5;
    for (k, v) in VARIANTS.iter().enumerate() {
        let mut window_drives = Vec::new();
        let mut whole = Vec::new();
        for (s, p) in [&p00, &p06].into_iter().enumerate() {
            let noisy = perturb(&p.points, v.sigma, v.jumps, 1000 * k as u64 + s as u64);
            for (a, b) in windows(p) {
                window_drives.push(drive(&noisy[a..b], p.headings[a], &p.points[a..b], &cfg));
            }
            let d = drive(&noisy, p.headings[0], &p.points, &cfg);
            println!(
                "  whole sequence {} ({}): RMS to reference {:.3} m, p95 {:.3} m, to clean path {:.3} m; |a_lat|95 executed {:.2} vs logged {:.2}; |kappa_dot|95 {:.3} vs {:.3}",
                p.name, v.name, d.rms_ref, d.p95_ref, d.rms_truth, d.executed.a_lat_p95, d.logged.a_lat_p95,
                d.executed.kappa_dot_p95, d.logged.kappa_dot_p95
            );
            whole.push(d);
        }
        println!("{}", summary(v.name, &window_drives));
        let median = |f: &dyn Fn(&Drive) -> f64| percentile(&window_drives.iter().map(f).collect::<Vec<_>>(), 50.0);
        let rms = median(&|d| d.rms_truth);
        assert!(rms < 0.5, "{}: median RMS {rms} m to the clean path", v.name);
        // The physics must not make the driver's path less comfortable than it was.
        let (ea, la) = (median(&|d| d.executed.a_lat_p95), median(&|d| d.logged.a_lat_p95));
        assert!(ea <= la + 0.2, "{}: |a_lat|95 executed {ea} vs logged {la}", v.name);
        let (ek, lk) = (median(&|d| d.executed.kappa_dot_p95), median(&|d| d.logged.kappa_dot_p95));
        assert!(ek <= lk, "{}: |kappa_dot|95 executed {ek} vs logged {lk}", v.name);
        for d in window_drives.iter().chain(&whole) {
            assert!(d.validity.valid, "{}: invalid rollout {:?}", v.name, d.validity);
            assert!(d.validity.max_abs_accel_lat <= limit, "{}: |a_lat| {}", v.name, d.validity.max_abs_accel_lat);
        }
    }
}
