//! `Transform3`: a rigid transform in f64, named by the `target_from_source` rule.
//!
//! A value called `world_from_ego` maps ego-frame points into the world frame:
//! `p_world = world_from_ego * p_ego`, and composition reads right to left
//! (`world_from_camera = world_from_ego * ego_from_camera`). On disk it is a 4x4 row-major
//! matrix, the layout Waymo uses, so a person can compare it with the source data.

use glam::{DAffine3, DMat3, DQuat, DVec3};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A rigid (rotation + translation) transform. The rotation part is kept exactly as read
/// (Waymo's float matrices are orthonormal only to ~1e-7); `validate` checks it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform3(pub DAffine3);

/// How far a rotation block may be from orthonormal (max |R^T R - I| entry) and still load.
pub const ORTHONORMAL_TOLERANCE: f64 = 1e-3;

impl Transform3 {
    pub const IDENTITY: Self = Self(DAffine3::IDENTITY);

    pub fn from_rotation_translation(rotation: DMat3, translation: DVec3) -> Self {
        Self(DAffine3::from_mat3_translation(rotation, translation))
    }

    /// A transform whose rotation is a yaw about +z (right-handed, counter-clockwise seen from above).
    pub fn from_yaw_translation(yaw: f64, translation: DVec3) -> Self {
        Self::from_rotation_translation(DMat3::from_rotation_z(yaw), translation)
    }

    /// Builds from a 4x4 row-major matrix; `None` if the last row is not `0 0 0 1`.
    pub fn from_row_major(m: &[[f64; 4]; 4]) -> Option<Self> {
        if m[3] != [0.0, 0.0, 0.0, 1.0] {
            return None;
        }
        let rotation = DMat3::from_cols(
            DVec3::new(m[0][0], m[1][0], m[2][0]),
            DVec3::new(m[0][1], m[1][1], m[2][1]),
            DVec3::new(m[0][2], m[1][2], m[2][2]),
        );
        Some(Self::from_rotation_translation(rotation, DVec3::new(m[0][3], m[1][3], m[2][3])))
    }

    /// Builds from 16 row-major values (Waymo's `Transform.transform`).
    pub fn from_row_major_slice(v: &[f64]) -> Option<Self> {
        if v.len() != 16 {
            return None;
        }
        let mut m = [[0.0; 4]; 4];
        for (i, x) in v.iter().enumerate() {
            m[i / 4][i % 4] = *x;
        }
        Self::from_row_major(&m)
    }

    pub fn to_row_major(&self) -> [[f64; 4]; 4] {
        let r = self.0.matrix3;
        let t = self.0.translation;
        [
            [r.x_axis.x, r.y_axis.x, r.z_axis.x, t.x],
            [r.x_axis.y, r.y_axis.y, r.z_axis.y, t.y],
            [r.x_axis.z, r.y_axis.z, r.z_axis.z, t.z],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }

    pub fn rotation(&self) -> DMat3 {
        self.0.matrix3
    }

    pub fn translation(&self) -> DVec3 {
        self.0.translation
    }

    pub fn transform_point(&self, p: DVec3) -> DVec3 {
        self.0.transform_point3(p)
    }

    pub fn transform_vector(&self, v: DVec3) -> DVec3 {
        self.0.transform_vector3(v)
    }

    /// The inverse of a rigid transform (transpose of the rotation), e.g. `ego_from_world`
    /// from `world_from_ego`.
    pub fn inverse(&self) -> Self {
        let rt = self.0.matrix3.transpose();
        Self::from_rotation_translation(rt, -(rt * self.0.translation))
    }

    /// Heading of the source frame's +x axis in the target frame's xy plane (radians).
    pub fn yaw(&self) -> f64 {
        let x = self.0.matrix3.x_axis;
        x.y.atan2(x.x)
    }

    /// Largest entry of |R^T R - I|, and whether every value is finite.
    pub fn orthonormality_error(&self) -> f64 {
        let r = self.0.matrix3;
        let e = r.transpose() * r - DMat3::IDENTITY;
        e.to_cols_array().iter().fold(0.0_f64, |m, x| m.max(x.abs()))
    }

    pub fn is_finite(&self) -> bool {
        self.0.is_finite()
    }

    /// The rigid transform a fraction `w` of the way from `self` (0) to `other` (1): translation
    /// linear, rotation slerped along the shorter arc (stays a rotation, unlike a matrix blend).
    pub fn interpolate(&self, other: &Transform3, w: f64) -> Transform3 {
        let qa = DQuat::from_mat3(&self.rotation()).normalize();
        let mut qb = DQuat::from_mat3(&other.rotation()).normalize();
        if qa.dot(qb) < 0.0 {
            qb = -qb;
        }
        let rotation = DMat3::from_quat(qa.slerp(qb, w));
        Self::from_rotation_translation(rotation, self.translation().lerp(other.translation(), w))
    }

    /// A transform from a unit quaternion `(w, x, y, z)` and a translation; `None` unless the
    /// values are finite and the quaternion's norm is within 1e-3 of 1 (it is then normalised).
    pub fn from_quaternion_translation(wxyz: [f64; 4], translation: DVec3) -> Option<Self> {
        let q = DQuat::from_xyzw(wxyz[1], wxyz[2], wxyz[3], wxyz[0]);
        let ok = q.is_finite() && translation.is_finite() && (q.length() - 1.0).abs() <= 1e-3;
        ok.then(|| Self::from_rotation_translation(DMat3::from_quat(q.normalize()), translation))
    }
}

impl std::ops::Mul for Transform3 {
    type Output = Transform3;
    fn mul(self, rhs: Transform3) -> Transform3 {
        Transform3(self.0 * rhs.0)
    }
}

impl Serialize for Transform3 {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.to_row_major().serialize(s)
    }
}

impl<'de> Deserialize<'de> for Transform3 {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let m = <[[f64; 4]; 4]>::deserialize(d)?;
        Transform3::from_row_major(&m)
            .ok_or_else(|| serde::de::Error::custom("expected a rigid 4x4 row-major matrix with last row [0, 0, 0, 1]"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn row_major_round_trip_and_inverse() {
        let t = Transform3::from_rotation_translation(
            DMat3::from_euler(glam::EulerRot::ZYX, 0.7, -0.1, 0.05),
            DVec3::new(10.0, -3.0, 1.5),
        );
        let back = Transform3::from_row_major(&t.to_row_major()).unwrap();
        assert!((back.0.matrix3 - t.0.matrix3).abs_diff_eq(DMat3::ZERO, 1e-15));
        let p = DVec3::new(1.0, 2.0, 3.0);
        let q = t.inverse().transform_point(t.transform_point(p));
        assert!((q - p).length() < 1e-12);
        assert!(t.orthonormality_error() < 1e-12);
        // Row-major layout: translation sits in the last column.
        assert_eq!(t.to_row_major()[0][3], 10.0);
    }

    #[test]
    fn rejects_projective_last_row() {
        let mut m = Transform3::IDENTITY.to_row_major();
        m[3][0] = 0.5;
        assert!(Transform3::from_row_major(&m).is_none());
        assert!(Transform3::from_row_major_slice(&[1.0; 15]).is_none());
    }

    #[test]
    fn yaw_of_yaw_transform() {
        let t = Transform3::from_yaw_translation(1.2, DVec3::ZERO);
        assert!((t.yaw() - 1.2).abs() < 1e-12);
    }
}
