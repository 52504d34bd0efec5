//! Real-data tracking check: every vehicle of the two shared WOMD scenarios that moves more
//! than 10 m is driven along its own logged trajectory (smoothed into the timed reference, as a
//! rollout does) by the PID and vehicle model, starting on the reference's first position, speed
//! and heading. Per-vehicle RMS position error over the control steps, to the reference and to
//! the raw log; the median must be below 1 m and every rollout physically valid. The distribution
//! is printed (and recorded in BENCHMARKS.md).

use scene::glam::DVec2;
use scene::motion::sample_series;
use sim::reference::start_for_path;
use sim::tracker::Tracker;
use sim::validity::{assess, BoxSize};
use sim::RolloutConfig;

fn percentile(sorted: &[f64], q: f64) -> f64 {
    let pos = q * (sorted.len() - 1) as f64;
    let (i, f) = (pos.floor() as usize, pos.fract());
    if i + 1 < sorted.len() {
        sorted[i] * (1.0 - f) + sorted[i + 1] * f
    } else {
        sorted[i]
    }
}

#[test]
fn logged_vehicles_are_tracked_within_a_metre() {
    let Some(scenes) = ingest::shared::womd_scenes() else { return };
    let cfg = RolloutConfig::default();
    let tracker = Tracker { config: &cfg.tracker, vehicle: &cfg.vehicle, actuation: &cfg.actuation };
    let mut rms_all = Vec::new();
    let mut rms_log = Vec::new();
    let mut max_alat: f64 = 0.0;
    for scene in &scenes {
        for track in scene.tracks.iter().filter(|t| t.class == scene::ObjectClass::Vehicle) {
            for run in scene.track_segments(track) {
                let path: f64 = run.windows(2).map(|w| w[0].position().distance(w[1].position())).sum();
                if run.len() < 3 || path <= 10.0 {
                    continue;
                }
                let points: Vec<(f64, DVec2)> = run.iter().map(|p| (p.t, p.position())).collect();
                let start = start_for_path(&points, points.len(), run[0].heading, &cfg.smoothing).unwrap();
                let reference = &start.reference;
                let (t0, t1) = (run[0].t, run[run.len() - 1].t);
                let p0 = reference.position(t0);
                let x0 = [p0.x, p0.y, 0.0, start.speed, start.heading, 0.0, 0.0];
                let rec = tracker.run(reference, x0, t0, t1, |_, _| {}).unwrap();
                let [l, w, _] = track.median_size_lwh();
                let v = assess(&rec, t0, None, None, BoxSize { length: l, width: w }, &cfg.validity);
                assert!(v.valid, "scene {} track {}: {v:?}", scene.name, track.id);
                max_alat = max_alat.max(v.max_abs_accel_lat);
                let se: f64 =
                    rec.iter().map(|s| (DVec2::new(s.state[0], s.state[1]) - s.reference).length_squared()).sum();
                let se_log: f64 = rec
                    .iter()
                    .filter_map(|s| {
                        sample_series(&run, s.t)
                            .map(|q| (q.position() - DVec2::new(s.state[0], s.state[1])).length_squared())
                    })
                    .sum();
                rms_log.push((se_log / rec.len() as f64).sqrt());
                rms_all.push(((se / rec.len() as f64).sqrt(), scene.name.clone(), track.id.clone(), path));
            }
        }
    }
    let mut rms: Vec<f64> = rms_all.iter().map(|r| r.0).collect();
    rms.sort_by(f64::total_cmp);
    let median = percentile(&rms, 0.5);
    println!(
        "vehicles {} | RMS position error (m): min {:.3} p25 {:.3} median {:.3} p75 {:.3} p90 {:.3} max {:.3}",
        rms.len(),
        rms[0],
        percentile(&rms, 0.25),
        median,
        percentile(&rms, 0.75),
        percentile(&rms, 0.9),
        rms[rms.len() - 1]
    );
    rms_log.sort_by(f64::total_cmp);
    println!(
        "RMS to the raw log: median {:.3} p90 {:.3} max {:.3} m; max |a_lat| {max_alat:.2} m/s^2",
        percentile(&rms_log, 0.5),
        percentile(&rms_log, 0.9),
        rms_log[rms_log.len() - 1]
    );
    rms_all.sort_by(|a, b| b.0.total_cmp(&a.0));
    for (e, scene, id, path) in rms_all.iter().take(5) {
        println!("  worst: scene {scene} track {id}: RMS {e:.3} m over a {path:.1} m path");
    }
    assert!(rms.len() >= 30, "expected many moving vehicles, got {}", rms.len());
    assert!(median < 1.0, "median RMS tracking error {median} m");
}
