//! NeuroNCAP's score of a closed-loop episode (Ljungbergh et al., ECCV 2024): 5 when the ego
//! does not collide, else `4 * max(0, 1 - v_i / v_r)`, with `v_i` the impact speed (the
//! magnitude of the relative velocity of the two vehicles at impact, m/s) and `v_r` the
//! reference impact speed: the impact speed had the ego taken no action (its no-reaction
//! counterfactual, run in the same scenario). Avoiding the collision scores 5, a collision at
//! the reference speed or faster scores 0, and braking that halves the impact speed scores 2.
//!
//! The definition leaves open a collision the no-reaction run would not have had (`v_r` absent
//! or zero): the policy caused it, and it scores 0.

/// The score when the ego does not collide.
pub const NCAP_MAX: f64 = 5.0;

/// NeuroNCAP's score: `impact_speed` is `None` without a collision; `reference_impact_speed`
/// the no-reaction run's impact speed (`None` if that run did not collide). Speeds in m/s.
pub fn ncap_score(impact_speed: Option<f64>, reference_impact_speed: Option<f64>) -> f64 {
    let Some(v_i) = impact_speed else { return NCAP_MAX };
    match reference_impact_speed {
        Some(v_r) if v_r > 0.0 && v_r.is_finite() && v_i.is_finite() => 4.0 * (1.0 - v_i.max(0.0) / v_r).max(0.0),
        _ => 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scores_as_neuroncap_defines_them() {
        assert_eq!(ncap_score(None, Some(10.0)), 5.0);
        assert_eq!(ncap_score(None, None), 5.0);
        assert_eq!(ncap_score(Some(10.0), Some(10.0)), 0.0);
        assert_eq!(ncap_score(Some(15.0), Some(10.0)), 0.0);
        assert!((ncap_score(Some(5.0), Some(10.0)) - 2.0).abs() < 1e-12);
        assert!((ncap_score(Some(0.0), Some(10.0)) - 4.0).abs() < 1e-12);
        // A collision the no-reaction run did not have.
        assert_eq!(ncap_score(Some(3.0), None), 0.0);
        assert_eq!(ncap_score(Some(f64::NAN), Some(10.0)), 0.0);
    }
}
