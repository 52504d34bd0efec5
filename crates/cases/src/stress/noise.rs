//! Track position noise: every valid state of every track but the ego's own moves by an
//! independent offset drawn uniformly from the disc of radius `max_m` in the ground plane (so the
//! error is bounded, unlike a Gaussian: the "up to 0.3 m"). Box headings stay as logged
//! (a detector's box yaw is not derived from its centre); velocities, where the source gives
//! them, are recomputed from the noisy centres by central differences over the real timestamps,
//! the way `reason::world` estimates them, so positions and velocities stay consistent. The
//! ego's poses and its own track are the log's clock and reference and are not perturbed.

use super::copy::{seed_for, without_sensors, SplitMix};
use scene::glam::DVec3;
use scene::{Scene, Track};

/// The corpus's noise bound (m).
pub const MAX_NOISE_M: f64 = 0.3;

/// A copy of `s` with every non-ego track's centres moved by at most `max_m` (a non-finite or
/// negative bound is treated as 0).
pub fn noise(s: &Scene, max_m: f64, seed: u64) -> Scene {
    let max_m = if max_m.is_finite() { max_m.max(0.0) } else { 0.0 };
    let mut out = without_sensors(s, "noise");
    let ego_id = s.ego.track_id.clone();
    for t in &mut out.tracks {
        if ego_id.as_deref() == Some(t.id.as_str()) {
            continue;
        }
        let mut rng = SplitMix::new(seed_for(seed, &t.id));
        for st in &mut t.states {
            // Uniform in the disc: radius sqrt(u) * max, angle uniform.
            let (r, a) = (max_m * rng.unit().sqrt(), rng.range(0.0, std::f64::consts::TAU));
            if st.valid {
                st.center += DVec3::new(r * a.cos(), r * a.sin(), 0.0);
            }
        }
        recompute_velocities(t, &s.frames);
    }
    out
}

/// Central-difference velocities from the track's valid centres (one-sided at the ends of a run;
/// left as they are where the source gave none). Neighbours further than 1 s apart are not used.
pub fn recompute_velocities(t: &mut Track, frames: &[scene::Frame]) {
    let time = |k: usize| frames.get(t.states[k].frame).map(|f| f.timestamp_s);
    let valid: Vec<usize> = (0..t.states.len()).filter(|k| t.states[*k].valid).collect();
    let mut new = Vec::with_capacity(valid.len());
    for (j, &k) in valid.iter().enumerate() {
        let near = |i: Option<&usize>| {
            i.copied().filter(|i| matches!((time(*i), time(k)), (Some(a), Some(b)) if (a - b).abs() <= 1.0))
        };
        let prev = j.checked_sub(1).and_then(|p| near(valid.get(p)));
        let next = near(valid.get(j + 1));
        let (a, b) = match (prev, next) {
            (Some(a), Some(b)) => (a, b),
            (Some(a), None) => (a, k),
            (None, Some(b)) => (k, b),
            (None, None) => {
                new.push(None);
                continue;
            }
        };
        let v = match (time(a), time(b)) {
            (Some(ta), Some(tb)) if tb - ta > 1e-6 => {
                let d = t.states[b].center - t.states[a].center;
                Some(DVec3::new(d.x, d.y, 0.0) / (tb - ta))
            }
            _ => None,
        };
        new.push(v);
    }
    for (&k, v) in valid.iter().zip(new) {
        if t.states[k].velocity.is_some() {
            if let Some(v) = v {
                t.states[k].velocity = Some(v);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stress::fixture::street;

    #[test]
    fn bounded_deterministic_and_ego_untouched() {
        let s = street();
        let a = noise(&s, MAX_NOISE_M, 7);
        assert_eq!(a, noise(&s, MAX_NOISE_M, 7));
        assert_ne!(a, noise(&s, MAX_NOISE_M, 8));
        let mut largest: f64 = 0.0;
        for (t0, t1) in s.tracks.iter().zip(&a.tracks) {
            for (x, y) in t0.states.iter().zip(&t1.states) {
                let d = (x.center - y.center).length();
                assert!(d <= MAX_NOISE_M + 1e-12, "{} moved {d}", t0.id);
                assert_eq!(x.heading, y.heading);
                largest = largest.max(d);
            }
        }
        assert!(largest > 0.2, "the noise should use its range, got {largest}");
        assert_eq!(s.track("sdc"), a.track("sdc"));
        assert_eq!(
            s.frames.iter().map(|f| f.world_from_ego).collect::<Vec<_>>(),
            a.frames.iter().map(|f| f.world_from_ego).collect::<Vec<_>>()
        );
        assert_eq!(a.name, "street-noise");
    }

    #[test]
    fn velocities_follow_the_noisy_positions() {
        let s = street();
        let a = noise(&s, MAX_NOISE_M, 1);
        let t = a.track("left").unwrap();
        let (p, q, r) = (&t.states[9], &t.states[10], &t.states[11]);
        let v = (r.center - p.center) / (2.0 * 0.1);
        assert!((q.velocity.unwrap() - DVec3::new(v.x, v.y, 0.0)).length() < 1e-9);
        // Mean velocity over the run stays the logged 11 m/s (noise averages out).
        let mean = t.states.iter().map(|s| s.velocity.unwrap().x).sum::<f64>() / t.states.len() as f64;
        assert!((mean - 11.0).abs() < 0.2, "{mean}");
    }

    #[test]
    fn zero_and_bad_bounds_change_nothing_but_the_name() {
        let s = street();
        for m in [0.0, -1.0, f64::NAN] {
            let a = noise(&s, m, 3);
            for (t0, t1) in s.tracks.iter().zip(&a.tracks) {
                for (x, y) in t0.states.iter().zip(&t1.states) {
                    assert!((x.center - y.center).length() < 1e-12);
                }
            }
        }
    }
}
