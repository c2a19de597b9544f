//! Symmetric 3x3 matrices stored as their six distinct entries: a body's inertia tensor and its
//! inverse, kept in every body (48 bytes each against `DMat3`'s 72; at 100,000 bodies, 4.6 MiB
//! and a sixth of every pass over the bodies).

use glam::{DMat3, DVec3};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SymMat3 {
    /// `(m00, m11, m22)`.
    diagonal: DVec3,
    /// `(m01, m02, m12)`.
    off_diagonal: DVec3,
}

impl SymMat3 {
    /// The upper triangle of `m`, which must be symmetric to the bit (the inertia tensor of
    /// [`crate::sim::shape::tet_mass_properties`] and glam's inverse of it are: its cofactors
    /// pair the same products): then [`SymMat3::to_mat3`] gives `m` back exactly.
    pub fn from_mat3(m: DMat3) -> Self {
        debug_assert!(m == m.transpose() || !m.is_finite(), "not symmetric: {m:?}");
        Self {
            diagonal: DVec3::new(m.x_axis.x, m.y_axis.y, m.z_axis.z),
            off_diagonal: DVec3::new(m.y_axis.x, m.z_axis.x, m.z_axis.y),
        }
    }

    pub fn to_mat3(self) -> DMat3 {
        let (d, o) = (self.diagonal, self.off_diagonal);
        DMat3::from_cols(
            DVec3::new(d.x, o.x, o.y),
            DVec3::new(o.x, d.y, o.z),
            DVec3::new(o.y, o.z, d.z),
        )
    }

    /// Whether it is a multiple of the identity, exactly (the regular tetrahedron's and
    /// octahedron's tensors come out so; a cube's may miss by a rounding, as at side 3.7, and a
    /// near miss takes the general path, which is right for every tensor).
    pub fn is_isotropic(&self) -> bool {
        self.off_diagonal == DVec3::ZERO && self.diagonal == DVec3::splat(self.diagonal.x)
    }

    /// `M v`.
    #[inline]
    pub fn mul_vec3(&self, v: DVec3) -> DVec3 {
        let (d, o) = (self.diagonal, self.off_diagonal);
        DVec3::new(
            d.x * v.x + o.x * v.y + o.y * v.z,
            o.x * v.x + d.y * v.y + o.z * v.z,
            o.y * v.x + o.z * v.y + d.z * v.z,
        )
    }

    pub fn is_finite(&self) -> bool {
        self.diagonal.is_finite() && self.off_diagonal.is_finite()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_symmetric_matrix_and_its_inverse_come_back_to_the_bit() {
        let m = DMat3::from_cols(
            DVec3::new(2.5, 0.3, -0.7),
            DVec3::new(0.3, 1.75, 0.11),
            DVec3::new(-0.7, 0.11, 3.2),
        );
        let v = DVec3::new(0.4, -1.3, 2.2);
        assert!((SymMat3::from_mat3(m).mul_vec3(v) - m * v).length() < 1e-15);
        for m in [m, m.inverse(), DMat3::IDENTITY * 7.0] {
            assert_eq!(SymMat3::from_mat3(m).to_mat3(), m);
        }
        assert_eq!(m.inverse(), m.inverse().transpose());
        assert!(SymMat3::from_mat3(DMat3::IDENTITY * 7.0).is_isotropic());
        assert!(!SymMat3::from_mat3(m).is_isotropic());
        assert!(
            !SymMat3::from_mat3(DMat3::from_diagonal(DVec3::new(2.0, 2.0, 2.5))).is_isotropic()
        );
    }
}
