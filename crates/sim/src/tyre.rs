//! Friction-limited axle forces for the single-track model.
//!
//! CommonRoad's ST model has linear tyres: the lateral force of an axle is
//! `F_lin = mu_cs * C_S * F_z * alpha` (`mu_cs` = CommonRoad's `mu`, which scales the stiffness,
//! `F_z` the axle load with load transfer, `alpha` the slip angle), with no upper bound, so
//! a large steering angle at speed gives any lateral acceleration at all. Here each axle's force
//! is limited by a friction circle of radius `mu_road * F_z` shared with the longitudinal force:
//!
//! * longitudinal force per axle, split in proportion to the load: `F_x = F_z * u2 / g`;
//! * lateral capacity `F_max = F_z * max(sqrt(mu_road^2 - (u2/g)^2), reserve * mu_road)`: the
//!   longitudinal force takes its share first, but (as with ABS) at least `reserve` of the
//!   lateral grip remains while braking or accelerating at the limit;
//! * the applied force follows the linear force exactly up to `linear_fraction * F_max` and
//!   then saturates smoothly (C1) towards `F_max`:
//!   `F = sign(F_lin) (k F_max + (1 - k) F_max tanh((|F_lin| - k F_max) / ((1 - k) F_max)))`.
//!
//! So `|F_yf + F_yr| <= mu_road * m * g`: the lateral acceleration `(F_yf + F_yr) / m` can
//! never exceed `mu_road * g`, and in the linear range the model is CommonRoad's, term for term
//! (golden tests). [`TyreModel::Linear`] keeps CommonRoad's unbounded tyres for parity tests.

use serde::{Deserialize, Serialize};

/// How the axle lateral forces are limited.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum TyreModel {
    /// CommonRoad's linear tyres, no friction limit (for parity with the package only).
    Linear,
    /// Linear up to `linear_fraction` of the friction circle's lateral capacity, then a smooth
    /// saturation to it; at least `reserve` of the lateral grip survives full longitudinal force.
    FrictionCircle { linear_fraction: f64, reserve: f64 },
}

impl Default for TyreModel {
    fn default() -> Self {
        TyreModel::FrictionCircle { linear_fraction: 0.8, reserve: 0.3 }
    }
}

/// One axle's lateral force: what the linear tyre asks for, the capacity, what is applied.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxleForce {
    pub demand: f64,
    pub capacity: f64,
    pub applied: f64,
}

impl AxleForce {
    /// The linear tyre asks for more than the axle can give: the tyre slides.
    pub fn at_limit(&self) -> bool {
        self.demand.abs() >= self.capacity
    }
}

/// Smooth saturation of `f` to `+-cap`, exact below `k * cap`.
pub fn saturate(f: f64, cap: f64, k: f64) -> f64 {
    let knee = k * cap;
    if f.abs() <= knee {
        return f;
    }
    let span = (1.0 - k) * cap;
    if span <= 0.0 {
        return f.signum() * cap;
    }
    f.signum() * (knee + span * ((f.abs() - knee) / span).tanh())
}

impl TyreModel {
    /// The lateral force of an axle with load `fz` (N) and linear demand `demand` (N) while the
    /// vehicle accelerates at `u2` (m/s^2) on a road of friction `mu_road`.
    pub fn axle(&self, demand: f64, fz: f64, u2: f64, mu_road: f64, g: f64) -> AxleForce {
        match *self {
            TyreModel::Linear => AxleForce { demand, capacity: f64::INFINITY, applied: demand },
            TyreModel::FrictionCircle { linear_fraction, reserve } => {
                let share = (mu_road * mu_road - (u2 / g).powi(2)).max(0.0).sqrt();
                let capacity = fz.max(0.0) * share.max(reserve * mu_road);
                AxleForce { demand, capacity, applied: saturate(demand, capacity, linear_fraction) }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn saturation_is_exact_below_the_knee_and_bounded_above() {
        assert_eq!(saturate(0.79, 1.0, 0.8), 0.79);
        assert_eq!(saturate(-0.5, 1.0, 0.8), -0.5);
        let big = saturate(50.0, 1.0, 0.8);
        assert!(big <= 1.0 && big > 0.999, "{big}");
        assert!(saturate(1.0, 1.0, 0.8) < 0.97);
        assert!((saturate(-50.0, 1.0, 0.8) + big).abs() < 1e-15);
        // C1 at the knee: slope 1 on both sides.
        let eps = 1e-7;
        let slope = (saturate(0.8 + eps, 1.0, 0.8) - saturate(0.8, 1.0, 0.8)) / eps;
        assert!((slope - 1.0).abs() < 1e-5, "{slope}");
        // Monotone.
        let xs: Vec<f64> = (0..200).map(|i| saturate(i as f64 * 0.01, 1.0, 0.8)).collect();
        assert!(xs.windows(2).all(|w| w[1] >= w[0]));
    }

    #[test]
    fn friction_circle_shares_grip_with_the_longitudinal_force() {
        let t = TyreModel::default();
        let g = 9.81;
        // No longitudinal force: capacity mu Fz.
        let a = t.axle(1e9, 5000.0, 0.0, 1.0, g);
        assert!((a.capacity - 5000.0).abs() < 1e-9 && a.at_limit() && a.applied <= a.capacity);
        // Braking at 0.6 g leaves sqrt(1 - 0.36) = 0.8 of it.
        let b = t.axle(0.0, 5000.0, -0.6 * g, 1.0, g);
        assert!((b.capacity - 4000.0).abs() < 1e-9 && !b.at_limit());
        // Braking at the limit keeps the 30 % reserve.
        let c = t.axle(0.0, 5000.0, -1.2 * g, 1.0, g);
        assert!((c.capacity - 1500.0).abs() < 1e-9);
        // Linear tyres are never limited.
        let l = TyreModel::Linear.axle(1e9, 5000.0, 0.0, 1.0, g);
        assert_eq!(l.applied, 1e9);
        assert!(!l.at_limit());
    }
}
