//! The CommonRoad single-track model with linear tyres and load transfer ("ST"), switching to
//! the kinematic single-track model about the centre of gravity below `kinematic_below` m/s,
//! reproduced from `vehicle_dynamics_st` of commonroad-vehicle-models 3.0.2 (golden tests in
//! `tests/golden.rs` compare against that package), with friction-limited tyres added.
//!
//! State `x = [sx, sy, delta, v, psi, psi_dot, beta]`: centre-of-gravity position (m, world),
//! front steering angle (rad), speed (m/s), yaw (rad), yaw rate (rad/s), slip angle at the centre
//! of gravity (rad). Input `u = [steering velocity (rad/s), longitudinal acceleration (m/s^2)]`,
//! both passed through CommonRoad's constraint functions first.
//!
//! With `g = 9.81`, `l = a + b`, `Ff = g b - u2 h` (front load term), `Fr = g a + u2 h`:
//! ```text
//! dsx = v cos(beta + psi)            dsy = v sin(beta + psi)
//! ddelta = u1                        dv = u2                        dpsi = psi_dot
//! dpsi_dot = -mu m / (v I l) (a^2 Csf Ff + b^2 Csr Fr) psi_dot
//!            + mu m / (I l) (b Csr Fr - a Csf Ff) beta + mu m / (I l) a Csf Ff delta
//! dbeta = (mu / (v^2 l) (Csr Fr b - Csf Ff a) - 1) psi_dot
//!         - mu / (v l) (Csr Fr + Csf Ff) beta + mu / (v l) Csf Ff delta
//! ```
//! Equivalently, in force form (what the code evaluates): `I dpsi_dot = a F_yf - b F_yr`,
//! `dbeta = (F_yf + F_yr) / (m v) - psi_dot` with the axle forces of [`axle_forces`]. With
//! CommonRoad's linear tyres that is the formula above; by default the forces are limited by a
//! friction circle (`tyre.rs`), so `|a_lat| = |F_yf + F_yr| / m <= friction * g`.
//!
//! Kinematic branch (|v| < 0.1): `beta_k = atan(tan(delta) b / l)`, `dsx = v cos(beta_k + psi)`,
//! `dsy = v sin(beta_k + psi)`, `dpsi = v cos(beta_k) tan(delta) / l`, and CommonRoad's
//! expressions for `dbeta` and `dpsi_dot` (kept verbatim, including its `(tan^2 delta b / l)^2`
//! term, so that the switch matches the package).
//!
//! Integration: classic RK4 with the input held over the step. The ST branch is stiff at low
//! speed (its fastest eigenvalue grows like `1/v`, see [`spectral_radius`]), so
//! [`stable_step`] shortens sub-steps near the switch to keep RK4 stable.

use crate::params::{LongitudinalLimits, SteeringLimits, VehicleParams};
use crate::tyre::AxleForce;

pub const G: f64 = 9.81;

/// `[sx, sy, delta, v, psi, psi_dot, beta]`.
pub type State = [f64; 7];

/// CommonRoad `steering_constraints`.
pub fn steering_constraints(delta: f64, v_delta: f64, p: &SteeringLimits) -> f64 {
    if (delta <= p.min && v_delta <= 0.0) || (delta >= p.max && v_delta >= 0.0) {
        0.0
    } else if v_delta <= p.v_min {
        p.v_min
    } else if v_delta >= p.v_max {
        p.v_max
    } else {
        v_delta
    }
}

/// CommonRoad `acceleration_constraints`.
pub fn acceleration_constraints(v: f64, a: f64, p: &LongitudinalLimits) -> f64 {
    let pos_limit = if v > p.v_switch { p.a_max * p.v_switch / v } else { p.a_max };
    if (v <= p.v_min && a <= 0.0) || (v >= p.v_max && a >= 0.0) {
        0.0
    } else if a <= -p.a_max {
        -p.a_max
    } else if a >= pos_limit {
        pos_limit
    } else {
        a
    }
}

/// Right-hand side of the model (CommonRoad `vehicle_dynamics_st`).
pub fn derivative(x: &State, u_in: [f64; 2], p: &VehicleParams) -> State {
    let u0 = steering_constraints(x[2], u_in[0], &p.steering);
    let u1 = acceleration_constraints(x[3], u_in[1], &p.longitudinal);
    let (lf, lr, m, i) = (p.a, p.b, p.m, p.i_z);
    let lwb = lf + lr;
    if x[3].abs() < p.kinematic_below {
        let beta_k = (x[2].tan() * lr / lwb).atan();
        let d_beta = (lr * u0) / (lwb * x[2].cos().powi(2) * (1.0 + (x[2].tan().powi(2) * lr / lwb).powi(2)));
        let dd_psi = 1.0 / lwb
            * (u1 * x[6].cos() * x[2].tan() - x[3] * x[6].sin() * d_beta * x[2].tan()
                + x[3] * x[6].cos() * u0 / x[2].cos().powi(2));
        return [
            x[3] * (beta_k + x[4]).cos(),
            x[3] * (beta_k + x[4]).sin(),
            u0,
            u1,
            x[3] * beta_k.cos() * x[2].tan() / lwb,
            dd_psi,
            d_beta,
        ];
    }
    let v = x[3];
    let [f, r] = axle_forces(x, u1, p);
    [
        v * (x[6] + x[4]).cos(),
        v * (x[6] + x[4]).sin(),
        u0,
        u1,
        x[5],
        (lf * f.applied - lr * r.applied) / i,
        (f.applied + r.applied) / (m * v) - x[5],
    ]
}

/// Front and rear lateral forces of the ST branch (N) at state `x` with the (constrained)
/// longitudinal acceleration `u1`: slip angles `alpha_f = delta - beta - a psi_dot / v`,
/// `alpha_r = -beta + b psi_dot / v`, loads `F_zf = m (g b - u1 h) / l`,
/// `F_zr = m (g a + u1 h) / l`, linear demand `mu C_S F_z alpha`, limited by [`crate::tyre::TyreModel`].
pub fn axle_forces(x: &State, u1: f64, p: &VehicleParams) -> [AxleForce; 2] {
    let (lf, lr, h, m) = (p.a, p.b, p.h_s, p.m);
    let l = lf + lr;
    let v = x[3];
    let fz_f = m * (G * lr - u1 * h) / l;
    let fz_r = m * (G * lf + u1 * h) / l;
    let alpha_f = x[2] - x[6] - lf * x[5] / v;
    let alpha_r = -x[6] + lr * x[5] / v;
    [
        p.tyre.axle(p.mu * p.c_sf * fz_f * alpha_f, fz_f, u1, p.friction, G),
        p.tyre.axle(p.mu * p.c_sr * fz_r * alpha_r, fz_r, u1, p.friction, G),
    ]
}

/// Whether either axle's tyres slide (linear demand beyond the friction capacity) at `x` under
/// input `u_in`; never in the kinematic branch.
pub fn at_friction_limit(x: &State, u_in: [f64; 2], p: &VehicleParams) -> bool {
    if x[3].abs() < p.kinematic_below {
        return false;
    }
    let u1 = acceleration_constraints(x[3], u_in[1], &p.longitudinal);
    axle_forces(x, u1, p).iter().any(AxleForce::at_limit)
}

fn axpy(x: &State, k: &State, h: f64) -> State {
    std::array::from_fn(|i| x[i] + h * k[i])
}

/// One classic RK4 step of length `h` with the input held constant.
pub fn rk4_step(x: &State, u: [f64; 2], p: &VehicleParams, h: f64) -> State {
    let k1 = derivative(x, u, p);
    let k2 = derivative(&axpy(x, &k1, h / 2.0), u, p);
    let k3 = derivative(&axpy(x, &k2, h / 2.0), u, p);
    let k4 = derivative(&axpy(x, &k3, h), u, p);
    std::array::from_fn(|i| x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]))
}

/// Spectral radius (1/s) of the ST branch's fast `[psi_dot, beta]` block at speed `v` (> 0)
/// and longitudinal acceleration `u1`: the eigenvalues of
/// `[[-mu m (a^2 Csf Ff + b^2 Csr Fr) / (v I l), mu m (b Csr Fr - a Csf Ff) / (I l)],
///   [mu (Csr Fr b - Csf Ff a) / (v^2 l) - 1, -mu (Csr Fr + Csf Ff) / (v l)]]`.
/// It grows like `1/v` (216/v at rest, about 335/v under full acceleration for vehicle2).
pub fn spectral_radius(v: f64, u1: f64, p: &VehicleParams) -> f64 {
    let (lf, lr, l) = (p.a, p.b, p.a + p.b);
    let ff = G * lr - u1 * p.h_s;
    let fr = G * lf + u1 * p.h_s;
    let a11 = -p.mu * p.m / (v * p.i_z * l) * (lf * lf * p.c_sf * ff + lr * lr * p.c_sr * fr);
    let a12 = p.mu * p.m / (p.i_z * l) * (lr * p.c_sr * fr - lf * p.c_sf * ff);
    let a21 = p.mu / (v * v * l) * (p.c_sr * fr * lr - p.c_sf * ff * lf) - 1.0;
    let a22 = -p.mu / (v * l) * (p.c_sr * fr + p.c_sf * ff);
    let (tr, det) = (a11 + a22, a11 * a22 - a12 * a21);
    let disc = tr * tr / 4.0 - det;
    if disc >= 0.0 {
        (tr / 2.0).abs() + disc.sqrt()
    } else {
        det.abs().sqrt() // complex pair: |lambda| = sqrt(det)
    }
}

/// RK4's stability limit on the negative real axis is |h lambda| = 2.785; we keep 2.0.
const RK4_STABLE_H_LAMBDA: f64 = 2.0;

/// The longest step (at most `h_max`) that keeps RK4 stable on the ST branch at speed `v` with
/// acceleration `u1`, judged at the lowest speed the step can reach.
pub fn stable_step(v: f64, u1: f64, p: &VehicleParams, h_max: f64) -> f64 {
    let v = v.abs();
    if v < p.kinematic_below {
        return h_max;
    }
    let mut h = h_max;
    for _ in 0..3 {
        let v_low = (v - u1.abs() * h).max(p.kinematic_below);
        h = h_max.min(RK4_STABLE_H_LAMBDA / spectral_radius(v_low, u1, p));
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constraints_clip_like_commonroad() {
        let p = VehicleParams::vehicle2();
        assert_eq!(steering_constraints(0.0, 1.0, &p.steering), 0.4);
        assert_eq!(steering_constraints(1.066, 0.1, &p.steering), 0.0);
        assert_eq!(steering_constraints(1.066, -0.1, &p.steering), -0.1);
        assert_eq!(acceleration_constraints(5.0, 20.0, &p.longitudinal), 11.5);
        // Power limit above v_switch: a_max * v_switch / v.
        assert!((acceleration_constraints(14.638, 20.0, &p.longitudinal) - 5.75).abs() < 1e-12);
        assert_eq!(acceleration_constraints(50.8, 1.0, &p.longitudinal), 0.0);
        assert_eq!(acceleration_constraints(3.0, -30.0, &p.longitudinal), -11.5);
    }

    #[test]
    fn straight_line_is_exact() {
        let p = VehicleParams::vehicle2();
        let mut x: State = [0.0, 0.0, 0.0, 10.0, 0.3, 0.0, 0.0];
        for _ in 0..100 {
            x = rk4_step(&x, [0.0, 0.0], &p, 0.01);
        }
        assert!((x[0] - 10.0 * 0.3f64.cos()).abs() < 1e-9 && (x[1] - 10.0 * 0.3f64.sin()).abs() < 1e-9);
    }

    #[test]
    fn stiffness_of_vehicle2() {
        let p = VehicleParams::vehicle2();
        // Hand-checked values of v * rho: 215.9 coasting, 312.9 braking, 335.5 accelerating.
        assert!((spectral_radius(1.0, 0.0, &p) - 215.9).abs() < 0.1);
        assert!((spectral_radius(0.2, -10.29, &p) * 0.2 - 312.9).abs() < 0.1);
        assert!((spectral_radius(0.2, 10.29, &p) * 0.2 - 335.5).abs() < 0.1);
        assert!(stable_step(0.5, 0.0, &p, 0.01) < 0.005);
        assert_eq!(stable_step(70.0, 0.0, &p, 0.01), 0.01);
        assert_eq!(stable_step(0.05, 0.0, &p, 0.01), 0.01);
    }

    #[test]
    fn stopping_under_full_brake_stays_stable() {
        // Decelerate from 3 m/s to rest with a small steering angle, using stable steps.
        let p = VehicleParams::vehicle2();
        let mut x: State = [0.0, 0.0, 0.05, 3.0, 0.0, 0.0, 0.0];
        let mut t = 0.0;
        while t < 1.0 {
            let h = stable_step(x[3], -10.0, &p, 0.01);
            let a = if x[3] > 0.0 { (-10.0f64).max(-x[3] / h) } else { 0.0 };
            x = rk4_step(&x, [0.0, a], &p, h);
            t += h;
            assert!(x[5].abs() < 1.0 && x[6].abs() < 0.2, "diverged at t {t}: {x:?}");
        }
        assert!(x[3].abs() < 1e-9);
    }
}
