//! Local surface frames of a point cloud, for starting Gaussians as discs lying in the surface.
//!
//! 3DGS starts every Gaussian as an isotropic ball with the identity rotation. A Gaussian's normal
//! is the axis of its smallest scale, so a ball's normal is arbitrary, and the flattening loss then
//! squeezes whichever axis happens to shrink first: discs form standing across the road (Table III's
//! "+flat" row got worse normals than the baseline). Here each point's `k` nearest neighbours give a
//! covariance; where they are planar (smallest eigenvalue well below the middle one), the Gaussian's
//! local z axis is put along the smallest eigenvector and its z scale is shrunk, so the start is
//! already a disc in the surface. Non-planar neighbourhoods (edges, foliage, too few points) keep the
//! isotropic start.

use glam::{DMat3, DQuat, DVec3};

/// Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi rotations: eigenvalues in
/// ascending order and the matching unit eigenvectors (columns of a right-handed rotation).
pub fn symmetric_eigen(a: [[f64; 3]; 3]) -> ([f64; 3], [DVec3; 3]) {
    let mut m = a;
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _sweep in 0..32 {
        let off = m[0][1].powi(2) + m[0][2].powi(2) + m[1][2].powi(2);
        let scale = m[0][0].powi(2) + m[1][1].powi(2) + m[2][2].powi(2);
        if off <= 1e-30 * scale.max(1e-300) {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if m[p][q].abs() < 1e-300 {
                continue;
            }
            let theta = (m[q][q] - m[p][p]) / (2.0 * m[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let t = if theta == 0.0 { 1.0 } else { t };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // m <- J^T m J with J the rotation in the (p, q) plane.
            for row in m.iter_mut() {
                let (mkp, mkq) = (row[p], row[q]);
                row[p] = c * mkp - s * mkq;
                row[q] = s * mkp + c * mkq;
            }
            let (upper, lower) = m.split_at_mut(q);
            for (a, b) in upper[p].iter_mut().zip(lower[0].iter_mut()) {
                let (mpk, mqk) = (*a, *b);
                *a = c * mpk - s * mqk;
                *b = s * mpk + c * mqk;
            }
            for row in v.iter_mut() {
                let (vp, vq) = (row[p], row[q]);
                row[p] = c * vp - s * vq;
                row[q] = s * vp + c * vq;
            }
        }
    }
    let mut order = [0usize, 1, 2];
    order.sort_by(|&i, &j| m[i][i].total_cmp(&m[j][j]));
    let vals = order.map(|i| m[i][i]);
    let mut vecs = order.map(|i| DVec3::new(v[0][i], v[1][i], v[2][i]).normalize());
    if vecs[0].cross(vecs[1]).dot(vecs[2]) < 0.0 {
        vecs[2] = -vecs[2];
    }
    (vals, vecs)
}

/// The start a planar neighbourhood gives: the `frame_from_local` rotation (w x y z; the frame is
/// the one the points are in, world or box) whose local z is the surface normal, and that normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceStart {
    pub rotation: [f64; 4],
    pub normal: DVec3,
}

/// The surface frame at `p` from its neighbours (`p` itself may be among them), or `None` when there
/// are fewer than 5 points or they are not planar: the smallest spread must be at most `planarity`
/// times the middle one (both as variances).
pub fn surface_start(neighbours: &[DVec3], planarity: f64) -> Option<SurfaceStart> {
    if neighbours.len() < 5 {
        return None;
    }
    let n = neighbours.len() as f64;
    let mean = neighbours.iter().copied().sum::<DVec3>() / n;
    let mut c = [[0.0; 3]; 3];
    for q in neighbours {
        let d = (*q - mean).to_array();
        for r in 0..3 {
            for k in 0..3 {
                c[r][k] += d[r] * d[k] / n;
            }
        }
    }
    let (vals, vecs) = symmetric_eigen(c);
    if vals[1].is_nan() || vals[1] <= 0.0 || vals[0].max(0.0) > planarity * vals[1] {
        return None;
    }
    // Local axes: x along the largest spread, y the middle, z the normal (right-handed).
    let frame_from_local = DMat3::from_cols(vecs[2], vecs[1], vecs[2].cross(vecs[1]));
    let q = DQuat::from_mat3(&frame_from_local).normalize();
    let normal = frame_from_local.z_axis;
    Some(SurfaceStart { rotation: [q.w, q.x, q.y, q.z], normal })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn eigen_recovers_a_rotated_diagonal_matrix() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for _ in 0..200 {
            let axis =
                DVec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            let r = DMat3::from_axis_angle(axis.normalize_or(DVec3::Z), rng.random_range(-3.0..3.0));
            let d = [rng.random_range(0.0..1.0), rng.random_range(1.0..2.0), rng.random_range(2.0..5.0)];
            let a = r * DMat3::from_diagonal(DVec3::from(d)) * r.transpose();
            let arr: [[f64; 3]; 3] = std::array::from_fn(|i| std::array::from_fn(|j| a.col(j)[i]));
            let (vals, vecs) = symmetric_eigen(arr);
            for k in 0..3 {
                assert!((vals[k] - d[k]).abs() < 1e-10, "{vals:?} vs {d:?}");
                assert!((a * vecs[k] - vals[k] * vecs[k]).length() < 1e-9);
                assert!(vecs[k].dot(r.col(k)).abs() > 1.0 - 1e-9);
            }
            assert!((vecs[0].cross(vecs[1]).dot(vecs[2]) - 1.0).abs() < 1e-9);
        }
    }

    #[test]
    fn plane_points_give_the_plane_normal_as_local_z() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let normal = DVec3::new(0.2, -0.3, 0.93).normalize();
        let u = normal.any_orthonormal_vector();
        let v = normal.cross(u);
        let pts: Vec<DVec3> = (0..16)
            .map(|_| {
                DVec3::new(4.0, -2.0, 1.0)
                    + u * rng.random_range(-0.5..0.5)
                    + v * rng.random_range(-0.5..0.5)
                    + normal * rng.random_range(-0.005..0.005)
            })
            .collect();
        let s = surface_start(&pts, 0.1).expect("planar");
        assert!(s.normal.dot(normal).abs() > 0.999, "{:?}", s.normal);
        // The rotation the rasterizer builds from the quaternion has the normal as its third column.
        let r = splat::project::rotation(s.rotation);
        let z = DVec3::new(r[0][2], r[1][2], r[2][2]);
        assert!((z - s.normal).length() < 1e-9);
    }

    #[test]
    fn a_ball_of_points_is_not_a_surface() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let pts: Vec<DVec3> = (0..32)
            .map(|_| DVec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0)))
            .collect();
        assert!(surface_start(&pts, 0.1).is_none());
        assert!(surface_start(&pts[..4], 0.1).is_none());
    }
}
