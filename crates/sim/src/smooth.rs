//! Smoothing of noisy logged paths before they become a tracking reference.
//!
//! Positions from perception tracks jitter by tens of centimetres and sometimes jump for a single
//! frame; differentiating them raw gives reference speeds of twice the true speed and headings
//! that swing from frame to frame, which the PID turns into violent steering. Each path is
//! therefore smoothed first with a **Rauch-Tung-Striebel smoother on a constant-acceleration
//! (white-noise jerk) model**, one per world axis:
//!
//! * state `[p, v, a]`, transition over `dt` (the real time between samples, irregular allowed)
//!   `F = [[1, dt, dt^2/2], [0, 1, dt], [0, 0, 1]]`, process noise
//!   `Q = q [[dt^5/20, dt^4/8, dt^3/6], [dt^4/8, dt^3/3, dt^2/2], [dt^3/6, dt^2/2, dt]]` with
//!   `q` = [`SmoothingConfig::jerk_psd`] (m^2/s^5);
//! * measurement: the position, with standard deviation `sigma` per sample (logged samples and
//!   plan waypoints can have different ones);
//! * diffuse prior (first position with sd 100 sigma, velocity sd 50 m/s, acceleration sd
//!   20 m/s^2), forward Kalman filter, backward RTS pass;
//! * robustness against single-frame jumps: `iterations` re-weighted passes; a sample whose 2D
//!   residual `r` exceeds `robust_k * sigma` gets its variance scaled by `(r / (robust_k sigma))^2`
//!   (a redescending, Cauchy-like weight), so one bad frame stops pulling the path.
//!
//! The result is kinematically consistent (position, velocity and acceleration of one motion),
//! so the initial speed and heading of a rollout are read from it, never from two raw samples.

use scene::glam::DVec2;
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SmoothingConfig {
    /// Off: the reference is the raw samples, linearly interpolated (the original behaviour).
    pub enabled: bool,
    /// Position noise of logged samples (m).
    pub log_sigma_m: f64,
    /// Position noise of a logged run that stays within `log_sigma_m` of its median point (a
    /// parked or queued car, m). Told that such a log is `log_sigma_m` noisy, the
    /// constant-acceleration smoother bends its stillness and a plan that pulls away into one
    /// parabola: the reference backs up before it drives off, which a car cannot follow.
    #[serde(default = "default_still_sigma")]
    pub still_sigma_m: f64,
    /// Position noise of a plan's waypoints (m): small, the plan is what should be driven.
    pub plan_sigma_m: f64,
    /// Power spectral density of the jerk (m^2/s^5): larger follows faster manoeuvres.
    pub jerk_psd: f64,
    /// Residuals beyond this many sigmas are down-weighted.
    pub robust_k: f64,
    /// Smoothing passes (the first unweighted).
    pub iterations: usize,
}

impl Default for SmoothingConfig {
    fn default() -> Self {
        SmoothingConfig {
            enabled: true,
            log_sigma_m: 0.3,
            still_sigma_m: default_still_sigma(),
            plan_sigma_m: 0.05,
            jerk_psd: 1.0,
            robust_k: 3.0,
            iterations: 3,
        }
    }
}

fn default_still_sigma() -> f64 {
    0.02
}

/// One measured position with its standard deviation (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub t: f64,
    pub p: DVec2,
    pub sigma: f64,
}

/// A smoothed state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Smoothed {
    pub t: f64,
    pub p: DVec2,
    pub v: DVec2,
    pub a: DVec2,
}

type V3 = [f64; 3];
type M3 = [[f64; 3]; 3];

fn mat_mul(a: &M3, b: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| (0..3).map(|k| a[i][k] * b[k][j]).sum()))
}

fn transpose(a: &M3) -> M3 {
    std::array::from_fn(|i| std::array::from_fn(|j| a[j][i]))
}

fn mat_vec(a: &M3, v: &V3) -> V3 {
    std::array::from_fn(|i| (0..3).map(|k| a[i][k] * v[k]).sum())
}

fn inverse(m: &M3) -> Option<M3> {
    let c = |i: usize, j: usize| {
        let (r0, r1) = ((i + 1) % 3, (i + 2) % 3);
        let (c0, c1) = ((j + 1) % 3, (j + 2) % 3);
        m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0]
    };
    let det = m[0][0] * c(0, 0) + m[0][1] * c(0, 1) + m[0][2] * c(0, 2);
    if !det.is_finite() || det.abs() < 1e-300 {
        return None;
    }
    // inverse = adjugate / det, adjugate[i][j] = cofactor[j][i].
    Some(std::array::from_fn(|i| std::array::from_fn(|j| c(j, i) / det)))
}

fn transition(dt: f64) -> M3 {
    [[1.0, dt, dt * dt / 2.0], [0.0, 1.0, dt], [0.0, 0.0, 1.0]]
}

fn process_noise(dt: f64, q: f64) -> M3 {
    let (d2, d3, d4, d5) = (dt * dt, dt.powi(3), dt.powi(4), dt.powi(5));
    [
        [q * d5 / 20.0, q * d4 / 8.0, q * d3 / 6.0],
        [q * d4 / 8.0, q * d3 / 3.0, q * d2 / 2.0],
        [q * d3 / 6.0, q * d2 / 2.0, q * dt],
    ]
}

/// One axis: returns `[p, v, a]` per sample. `var` is each sample's measurement variance.
fn rts_axis(t: &[f64], z: &[f64], var: &[f64], q: f64) -> Option<Vec<V3>> {
    let n = t.len();
    let mut filt: Vec<(V3, M3)> = Vec::with_capacity(n);
    let mut pred: Vec<(V3, M3)> = Vec::with_capacity(n);
    let mut x: V3 = [z[0], 0.0, 0.0];
    let mut p: M3 = [[var[0].max(1e-12) * 1e4, 0.0, 0.0], [0.0, 2500.0, 0.0], [0.0, 0.0, 400.0]];
    for k in 0..n {
        if k > 0 {
            let f = transition(t[k] - t[k - 1]);
            x = mat_vec(&f, &x);
            let fp = mat_mul(&mat_mul(&f, &p), &transpose(&f));
            let qn = process_noise(t[k] - t[k - 1], q);
            p = std::array::from_fn(|i| std::array::from_fn(|j| fp[i][j] + qn[i][j]));
        }
        pred.push((x, p));
        let s = p[0][0] + var[k];
        let gain: V3 = std::array::from_fn(|i| p[i][0] / s);
        let innovation = z[k] - x[0];
        x = std::array::from_fn(|i| x[i] + gain[i] * innovation);
        let row0 = p[0];
        p = std::array::from_fn(|i| std::array::from_fn(|j| p[i][j] - gain[i] * row0[j]));
        filt.push((x, p));
    }
    let mut out = vec![[0.0; 3]; n];
    out[n - 1] = filt[n - 1].0;
    for k in (0..n - 1).rev() {
        let f = transition(t[k + 1] - t[k]);
        let (xf, pf) = &filt[k];
        let (xp, pp) = &pred[k + 1];
        let c = mat_mul(&mat_mul(pf, &transpose(&f)), &inverse(pp)?);
        let d: V3 = std::array::from_fn(|i| out[k + 1][i] - xp[i]);
        let cd = mat_vec(&c, &d);
        out[k] = std::array::from_fn(|i| xf[i] + cd[i]);
    }
    out.iter().all(|s| s.iter().all(|v| v.is_finite())).then_some(out)
}

/// Smooths a timed path. Needs at least two samples, finite, strictly increasing in time, with
/// positive sigmas.
pub fn smooth(samples: &[Sample], cfg: &SmoothingConfig) -> Result<Vec<Smoothed>, String> {
    if samples.len() < 2 {
        return Err(format!("smoothing needs at least 2 samples, got {}", samples.len()));
    }
    for (i, s) in samples.iter().enumerate() {
        if !(s.t.is_finite() && s.p.is_finite() && s.sigma > 0.0 && s.sigma.is_finite()) {
            return Err(format!("sample {i}: time, position and a positive sigma must be finite"));
        }
        if i > 0 && s.t <= samples[i - 1].t {
            return Err(format!("sample {i}: times must increase strictly ({} after {})", s.t, samples[i - 1].t));
        }
    }
    if !(cfg.jerk_psd > 0.0 && cfg.robust_k > 0.0) {
        return Err(format!("smoothing: jerk_psd ({}) and robust_k ({}) must be positive", cfg.jerk_psd, cfg.robust_k));
    }
    let t: Vec<f64> = samples.iter().map(|s| s.t).collect();
    let zx: Vec<f64> = samples.iter().map(|s| s.p.x).collect();
    let zy: Vec<f64> = samples.iter().map(|s| s.p.y).collect();
    let mut var: Vec<f64> = samples.iter().map(|s| s.sigma * s.sigma).collect();
    let mut result = Vec::new();
    for pass in 0..cfg.iterations.max(1) {
        let fail = || "smoothing: the smoother became singular".to_string();
        let sx = rts_axis(&t, &zx, &var, cfg.jerk_psd).ok_or_else(fail)?;
        let sy = rts_axis(&t, &zy, &var, cfg.jerk_psd).ok_or_else(fail)?;
        result = (0..t.len())
            .map(|k| Smoothed {
                t: t[k],
                p: DVec2::new(sx[k][0], sy[k][0]),
                v: DVec2::new(sx[k][1], sy[k][1]),
                a: DVec2::new(sx[k][2], sy[k][2]),
            })
            .collect();
        if pass + 1 < cfg.iterations {
            for (k, s) in samples.iter().enumerate() {
                let r = s.p.distance(result[k].p) / (cfg.robust_k * s.sigma);
                var[k] = s.sigma * s.sigma * (r * r).max(1.0);
            }
        }
    }
    Ok(result)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(f: impl Fn(f64) -> DVec2, n: usize, sigma: f64) -> Vec<Sample> {
        (0..n).map(|i| i as f64 * 0.1).map(|t| Sample { t, p: f(t), sigma }).collect()
    }

    #[test]
    fn a_constant_acceleration_path_is_reproduced_exactly() {
        // The model's own motion class: p = p0 + v t + a t^2 / 2 passes through unchanged (up to
        // the pull of the finite "diffuse" prior at the start).
        let f = |t: f64| DVec2::new(3.0 + 12.0 * t + 0.5 * 1.5 * t * t, -2.0 + 4.0 * t - 0.5 * 0.8 * t * t);
        let out = smooth(&samples(f, 60, 0.3), &SmoothingConfig::default()).unwrap();
        for s in &out[..] {
            assert!((s.p - f(s.t)).length() < 1e-3, "{:?}", s);
            assert!((s.v - DVec2::new(12.0 + 1.5 * s.t, 4.0 - 0.8 * s.t)).length() < 1e-2, "{:?}", s);
            assert!((s.a - DVec2::new(1.5, -0.8)).length() < 2e-2, "{:?}", s);
        }
    }

    #[test]
    fn a_single_frame_jump_does_not_move_the_path() {
        // 15 m/s straight ahead; frame 1 jumps 3 m sideways (as in a perception track) and
        // frame 30 jumps 2.5 m back. The start speed stays near 15 m/s, the heading near 0.
        let f = |t: f64| DVec2::new(15.0 * t, 0.0);
        let mut s = samples(f, 60, 0.3);
        s[1].p.y += 3.0;
        s[30].p.x -= 2.5;
        let out = smooth(&s, &SmoothingConfig::default()).unwrap();
        assert!((out[0].v.length() - 15.0).abs() < 1.0, "start speed {}", out[0].v.length());
        assert!(out[0].v.y.atan2(out[0].v.x).abs() < 0.1, "start heading {:?}", out[0].v);
        let worst = out.iter().map(|o| (o.p - f(o.t)).length()).fold(0.0, f64::max);
        assert!(worst < 0.3, "path moved {worst} m");
        // Without the robust passes the jump pulls the path much further.
        let plain = smooth(&s, &SmoothingConfig { iterations: 1, ..Default::default() }).unwrap();
        let worst_plain = plain.iter().map(|o| (o.p - f(o.t)).length()).fold(0.0, f64::max);
        assert!(worst_plain > 2.0 * worst, "{worst_plain} vs {worst}");
    }

    #[test]
    fn rejects_bad_input() {
        let c = SmoothingConfig::default();
        assert!(smooth(&[Sample { t: 0.0, p: DVec2::ZERO, sigma: 0.1 }], &c).is_err());
        let two = |t1: f64, sigma: f64| {
            vec![Sample { t: 0.0, p: DVec2::ZERO, sigma: 0.1 }, Sample { t: t1, p: DVec2::X, sigma }]
        };
        assert!(smooth(&two(0.0, 0.1), &c).is_err());
        assert!(smooth(&two(0.1, 0.0), &c).is_err());
        assert!(smooth(&two(0.1, 0.1), &c).is_ok());
    }
}
