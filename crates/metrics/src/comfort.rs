//! Ride comfort and feasibility of a path, on a 0.1 s grid of real time (REFERENCE.md §4):
//! `v = gradient(p)`, `a = gradient(v)` (numpy.gradient), `a_lat = (vx ay - vy ax) / |v|`,
//! `kappa = (vx ay - vy ax) / |v|^3` (0 where `|v| <= 1 m/s`), `kappa_dot` = forward difference
//! of `kappa`. Reported: 95th percentiles of `|a_lat|` and `|kappa_dot|`, and ComfortViol = the
//! percentage of samples with `|a_lat| > 3 m/s^2`.

use crate::kinematics::{gradient, percentile, velocities};
use scene::motion::Pose2;
use serde::{Deserialize, Serialize};

pub const COMFORT_A_LAT_LIMIT: f64 = 3.0;
pub const KAPPA_MIN_SPEED: f64 = 1.0;

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Comfort {
    pub a_lat_p95: f64,
    pub kappa_dot_p95: f64,
    pub comfort_viol_pct: f64,
    pub samples: usize,
}

/// Comfort of a path already sampled every `dt` seconds; `None` with fewer than 3 samples.
pub fn comfort(path: &[Pose2], dt: f64) -> Option<Comfort> {
    if path.len() < 3 {
        return None;
    }
    let v = velocities(path, dt);
    let ax = gradient(&v.iter().map(|v| v.x).collect::<Vec<_>>(), dt);
    let ay = gradient(&v.iter().map(|v| v.y).collect::<Vec<_>>(), dt);
    let mut a_lat = Vec::with_capacity(v.len());
    let mut kappa = Vec::with_capacity(v.len());
    for i in 0..v.len() {
        let cross = v[i].x * ay[i] - v[i].y * ax[i];
        let s = v[i].length();
        a_lat.push(if s > 0.0 { (cross / s).abs() } else { 0.0 });
        kappa.push(if s > KAPPA_MIN_SPEED { cross / (s * s * s) } else { 0.0 });
    }
    let kappa_dot: Vec<f64> = kappa.windows(2).map(|w| ((w[1] - w[0]) / dt).abs()).collect();
    let viol = a_lat.iter().filter(|a| **a > COMFORT_A_LAT_LIMIT).count();
    Some(Comfort {
        a_lat_p95: percentile(&a_lat, 95.0)?,
        kappa_dot_p95: percentile(&kappa_dot, 95.0)?,
        comfort_viol_pct: 100.0 * viol as f64 / a_lat.len() as f64,
        samples: a_lat.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn circle(speed: f64, radius: f64, n: usize) -> Vec<Pose2> {
        (0..n)
            .map(|i| {
                let a = speed / radius * i as f64 * 0.1;
                Pose2 { t: i as f64 * 0.1, x: radius * a.sin(), y: radius * (1.0 - a.cos()), heading: a }
            })
            .collect()
    }

    #[test]
    fn constant_turn() {
        // 10 m/s on a 25 m radius: a_lat = v^2 / R = 4 m/s^2 > 3 everywhere, kappa constant.
        let c = comfort(&circle(10.0, 25.0, 60), 0.1).unwrap();
        assert!((c.a_lat_p95 - 4.0).abs() < 0.05, "{c:?}");
        // Two samples at each end use one-sided differences (as numpy does) and under-estimate
        // a_lat: 56 of 60 samples violate.
        assert!((c.comfort_viol_pct - 100.0 * 56.0 / 60.0).abs() < 1e-9, "{c:?}");
        // kappa is constant except where the one-sided end differences bend it (4 values):
        // on a longer run those fall outside the 95th percentile.
        let long = comfort(&circle(10.0, 25.0, 200), 0.1).unwrap();
        assert!(long.kappa_dot_p95 < 1e-9, "{long:?}");
        // Gentle: 5 m/s on 50 m is 0.5 m/s^2, no violation.
        let g = comfort(&circle(5.0, 50.0, 60), 0.1).unwrap();
        assert!((g.a_lat_p95 - 0.5).abs() < 0.01 && g.comfort_viol_pct == 0.0);
    }

    #[test]
    fn straight_and_slow() {
        let line: Vec<Pose2> =
            (0..30).map(|i| Pose2 { t: i as f64 * 0.1, x: i as f64, y: 0.0, heading: 0.0 }).collect();
        let c = comfort(&line, 0.1).unwrap();
        assert_eq!((c.a_lat_p95, c.kappa_dot_p95, c.comfort_viol_pct), (0.0, 0.0, 0.0));
        // Below 1 m/s curvature is not defined: kappa (and kappa_dot) are 0.
        let crawl = comfort(&circle(0.5, 2.0, 30), 0.1).unwrap();
        assert_eq!(crawl.kappa_dot_p95, 0.0);
        assert!(comfort(&line[..2], 0.1).is_none());
    }
}
