//! Moving a Gaussian model by a general linear map (rotation and per-axis scale) exactly.
//!
//! A Gaussian's shape is its covariance `Σ = R diag(s²) Rᵀ` (rotation `R` from the unit
//! quaternion, `s = exp(log_scale)`). Under `x' = L x + t` the covariance becomes
//! `Σ' = L Σ Lᵀ`. When `L` is a pure rotation that is the quaternion product; when `L` holds an
//! anisotropic scale, adding `log(scale)` to the log-scales is only right for Gaussians whose
//! axes are the scale's axes, so `Σ'` is formed in full and re-factored: its eigenvectors give
//! the new rotation (made proper, det +1) and the square roots of its eigenvalues the new scales.
//! The symmetric 3x3 eigenproblem is `recon::surface`'s cyclic Jacobi solver (glam has none);
//! the matrix and quaternion algebra is glam's, behind our row-major `[[f64; 3]; 3]`.
//!
//! Colour: spherical-harmonic bands 1 to 3 are rotated with the rotation part of the map (the
//! map with its scale taken out, `R_yaw` for the asset alignment) through `recon::sh_rotate`,
//! the same least-squares band mixing the compositor uses; the small change of view directions
//! that an anisotropic scale makes is not modelled.

use recon::sh_rotate::ShRotation;
use recon::surface::symmetric_eigen;
use scene::glam::{DMat3, DQuat, DVec3};
use splat::Gaussians;

pub type Mat3 = [[f64; 3]; 3];

/// Our row-major `m[row][col]` as a glam matrix.
fn to_glam(a: &Mat3) -> DMat3 {
    DMat3::from_cols_array_2d(a).transpose()
}

fn from_glam(m: DMat3) -> Mat3 {
    m.transpose().to_cols_array_2d()
}

pub fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    from_glam(to_glam(a) * to_glam(b))
}

pub fn transpose(a: &Mat3) -> Mat3 {
    from_glam(to_glam(a).transpose())
}

pub fn mat_vec(a: &Mat3, v: [f64; 3]) -> [f64; 3] {
    (to_glam(a) * DVec3::from(v)).to_array()
}

pub fn diag(d: [f64; 3]) -> Mat3 {
    from_glam(DMat3::from_diagonal(DVec3::from(d)))
}

/// Rotation about +z by `yaw` (radians).
pub fn yaw_matrix(yaw: f64) -> Mat3 {
    from_glam(DMat3::from_rotation_z(yaw))
}

/// Rotation matrix of a quaternion (w, x, y, z), normalised first.
pub fn quat_to_matrix(q: [f64; 4]) -> Mat3 {
    let [w, x, y, z] = q;
    from_glam(DMat3::from_quat(DQuat::from_xyzw(x, y, z, w).normalize()))
}

/// Unit quaternion (w, x, y, z) of a proper rotation matrix, `w >= 0`.
pub fn matrix_to_quat(r: &Mat3) -> [f64; 4] {
    let q = DQuat::from_mat3(&to_glam(r)).normalize();
    let q = if q.w < 0.0 { -q } else { q };
    [q.w, q.x, q.y, q.z]
}

/// `Σ = R diag(exp(2 log_scale)) Rᵀ`.
pub fn covariance(log_scale: [f64; 3], q: [f64; 4]) -> Mat3 {
    let r = to_glam(&quat_to_matrix(q));
    let s2 = DVec3::from(log_scale.map(|l| (2.0 * l).exp()));
    from_glam(r * DMat3::from_diagonal(s2) * r.transpose())
}

/// The smallest variance a re-factored Gaussian keeps (m²): a flat Gaussian stays renderable.
pub const MIN_VARIANCE: f64 = 1e-20;

/// Log-scales and unit quaternion of a covariance: its eigen-decomposition (the Jacobi solver of
/// `recon::surface`, whose eigenvectors form a proper rotation).
pub fn factor(cov: &Mat3) -> ([f64; 3], [f64; 4]) {
    let (vals, vecs) = symmetric_eigen(*cov);
    let r = from_glam(DMat3::from_cols(vecs[0], vecs[1], vecs[2]));
    (vals.map(|v| 0.5 * v.max(MIN_VARIANCE).ln()), matrix_to_quat(&r))
}

/// Changes the SH degree of `g` to `degree`: higher bands dropped, missing ones zero.
pub fn with_sh_degree(g: &Gaussians, degree: usize) -> Gaussians {
    let (k_in, k_out) = (g.coeffs() * 3, splat::sh::sh_coeffs(degree) * 3);
    let mut sh = Vec::with_capacity(g.len() * k_out);
    for i in 0..g.len() {
        let src = &g.sh[i * k_in..(i + 1) * k_in];
        sh.extend((0..k_out).map(|c| src.get(c).copied().unwrap_or(0.0)));
    }
    Gaussians { sh_degree: degree, sh, ..g.clone() }
}

/// `g` moved by `x' = linear x + translation`: means mapped, covariances `L Σ Lᵀ` re-factored,
/// SH bands rotated by `colour_rotation` (the rotation part of `linear`), opacities kept.
pub fn transform(g: &Gaussians, linear: &Mat3, translation: [f64; 3], colour_rotation: &Mat3) -> Gaussians {
    let lt = transpose(linear);
    let rot = ShRotation::new(g.sh_degree, *colour_rotation);
    let mut out = g.clone();
    let mut buf = vec![0.0; g.coeffs() * 3];
    for i in 0..g.len() {
        let m = mat_vec(linear, g.means[i]);
        out.means[i] = std::array::from_fn(|a| m[a] + translation[a]);
        let cov = covariance(g.log_scales[i], g.rotations[i]);
        let moved = mat_mul(&mat_mul(linear, &cov), &lt);
        let (ls, q) = factor(&moved);
        out.log_scales[i] = ls;
        out.rotations[i] = q;
        rot.to_world(g.sh_of(i), &mut buf, g.sh_degree);
        let k = buf.len();
        out.sh[i * k..(i + 1) * k].copy_from_slice(&buf);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Mat3, b: &Mat3, tol: f64) -> bool {
        let n = a.iter().flatten().map(|v| v.abs()).fold(0.0, f64::max);
        a.iter().flatten().zip(b.iter().flatten()).all(|(x, y)| (x - y).abs() <= tol * n.max(1e-12))
    }

    fn q_of(axis: [f64; 3], angle: f64) -> [f64; 4] {
        let n = axis.iter().map(|v| v * v).sum::<f64>().sqrt();
        let (s, c) = (angle / 2.0).sin_cos();
        [c, s * axis[0] / n, s * axis[1] / n, s * axis[2] / n]
    }

    #[test]
    fn factor_inverts_covariance_and_quaternions_round_trip() {
        let q = q_of([0.3, -0.7, 0.5], 1.1);
        let ls = [-1.2, -2.5, -0.4];
        let (ls2, q2) = factor(&covariance(ls, q));
        assert!(close(&covariance(ls2, q2), &covariance(ls, q), 1e-12));
        let r = quat_to_matrix(q);
        let back = matrix_to_quat(&r);
        assert!(close(&quat_to_matrix(back), &r, 1e-14));
        let mut sorted_in = ls;
        let mut sorted_out = ls2;
        sorted_in.sort_by(f64::total_cmp);
        sorted_out.sort_by(f64::total_cmp);
        for (a, b) in sorted_in.iter().zip(sorted_out) {
            assert!((a - b).abs() < 1e-12);
        }
    }

    #[test]
    fn non_axis_aligned_gaussian_keeps_its_exact_transformed_covariance() {
        // One Gaussian tilted about a skew axis, very anisotropic.
        let q = q_of([1.0, 2.0, -0.5], 0.9);
        let ls = [-0.3, -1.9, -3.0];
        let g = Gaussians {
            means: vec![[0.4, -0.2, 0.7]],
            log_scales: vec![ls],
            rotations: vec![q],
            opacity_logits: vec![0.5],
            sh_degree: 1,
            sh: vec![0.2, 0.1, -0.1, 0.3, 0.0, 0.1, -0.2, 0.4, 0.0, 0.05, 0.1, 0.2],
        };
        let r = yaw_matrix(2.2);
        let s = diag([1.4, 0.7, 1.15]);
        let l = mat_mul(&s, &r);
        let out = transform(&g, &l, [1.0, 2.0, 3.0], &r);
        let sigma = covariance(ls, q);
        let want = mat_mul(&mat_mul(&l, &sigma), &transpose(&l));
        let got = covariance(out.log_scales[0], out.rotations[0]);
        assert!(close(&got, &want, 1e-9), "{got:?} vs {want:?}");
        // Adding log(scale) to the log-scales (right only for axis-aligned Gaussians) is not.
        let naive_ls = [ls[0] + 1.4f64.ln(), ls[1] + 0.7f64.ln(), ls[2] + 1.15f64.ln()];
        let naive_q = matrix_to_quat(&mat_mul(&r, &quat_to_matrix(q)));
        assert!(!close(&covariance(naive_ls, naive_q), &want, 1e-3));
        let m = mat_vec(&l, g.means[0]);
        for a in 0..3 {
            assert!((out.means[0][a] - m[a] - [1.0, 2.0, 3.0][a]).abs() < 1e-12);
        }
        // The DC colour is kept; band 1 is rotated (it changes under a yaw of 2.2 rad).
        assert_eq!(&out.sh[..3], &g.sh[..3]);
        assert!(out.sh[3..].iter().zip(&g.sh[3..]).any(|(a, b)| (a - b).abs() > 1e-3));
    }

    #[test]
    fn pure_rotation_is_the_quaternion_product() {
        let q = q_of([0.2, 0.1, 1.0], 0.6);
        let g = Gaussians {
            means: vec![[1.0, 0.0, 0.0]],
            log_scales: vec![[-1.0, -2.0, -1.5]],
            rotations: vec![q],
            opacity_logits: vec![0.0],
            sh_degree: 0,
            sh: vec![0.1, 0.2, 0.3],
        };
        let r = yaw_matrix(-0.8);
        let out = transform(&g, &r, [0.0; 3], &r);
        let want = mat_mul(&r, &quat_to_matrix(q));
        let got_cov = covariance(out.log_scales[0], out.rotations[0]);
        let want_cov = covariance(g.log_scales[0], matrix_to_quat(&want));
        assert!(close(&got_cov, &want_cov, 1e-12));
    }

    #[test]
    fn degenerate_covariance_stays_finite() {
        let (ls, q) = factor(&diag([1.0, 0.0, 4.0]));
        assert!(ls.iter().all(|v| v.is_finite()) && q.iter().all(|v| v.is_finite()));
    }
}
