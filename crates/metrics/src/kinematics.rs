//! Time-series helpers shared by every metric: uniform resampling, numpy-style gradients and
//! percentiles, so that numbers compare with the paper's Python evaluation.

use scene::glam::DVec2;
use scene::motion::{sample_series, Pose2};

/// The sampling period of every metric (s of real time).
pub const METRIC_DT_S: f64 = 0.1;

/// Samples `series` at `t0, t0 + dt, ...` up to `t1` (inclusive within 1e-9).
pub fn uniform(series: &[Pose2], t0: f64, t1: f64, dt: f64) -> Vec<Pose2> {
    let n = ((t1 - t0) / dt + 1e-9).floor().max(0.0) as usize;
    (0..=n).filter_map(|k| sample_series(series, t0 + k as f64 * dt)).collect()
}

/// `numpy.gradient` for uniform spacing: central differences inside, one-sided at the ends.
pub fn gradient(f: &[f64], dt: f64) -> Vec<f64> {
    let n = f.len();
    match n {
        0 => Vec::new(),
        1 => vec![0.0],
        _ => (0..n)
            .map(|i| match i {
                0 => (f[1] - f[0]) / dt,
                i if i == n - 1 => (f[n - 1] - f[n - 2]) / dt,
                i => (f[i + 1] - f[i - 1]) / (2.0 * dt),
            })
            .collect(),
    }
}

/// Velocities of a uniformly sampled path.
pub fn velocities(path: &[Pose2], dt: f64) -> Vec<DVec2> {
    let vx = gradient(&path.iter().map(|p| p.x).collect::<Vec<_>>(), dt);
    let vy = gradient(&path.iter().map(|p| p.y).collect::<Vec<_>>(), dt);
    vx.into_iter().zip(vy).map(|(x, y)| DVec2::new(x, y)).collect()
}

/// `numpy.percentile` with linear interpolation; `None` for no values.
pub fn percentile(values: &[f64], q: f64) -> Option<f64> {
    if values.is_empty() {
        return None;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let pos = q / 100.0 * (v.len() - 1) as f64;
    let (i, frac) = (pos.floor() as usize, pos.fract());
    Some(if i + 1 < v.len() { v[i] + frac * (v[i + 1] - v[i]) } else { v[i] })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradient_matches_numpy() {
        // numpy.gradient([1, 2, 4, 7, 11], 0.5) = [2, 3, 5, 7, 8]
        assert_eq!(gradient(&[1.0, 2.0, 4.0, 7.0, 11.0], 0.5), vec![2.0, 3.0, 5.0, 7.0, 8.0]);
    }

    #[test]
    fn percentile_matches_numpy() {
        // numpy.percentile([1, 2, 3, 4], 95) = 3.85
        assert!((percentile(&[4.0, 1.0, 3.0, 2.0], 95.0).unwrap() - 3.85).abs() < 1e-12);
        assert_eq!(percentile(&[5.0], 95.0), Some(5.0));
        assert_eq!(percentile(&[], 95.0), None);
    }
}
