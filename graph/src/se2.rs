//! Rigid transforms of the plane, SE(2), on top of nalgebra's `Isometry2`.
//!
//! A pose `a_from_b` maps coordinates expressed in frame `b` into frame `a`.
//! Composition (the stochastic-mapping operator ⊕) is `a_from_b ⊕ b_from_c =
//! a_from_c`, inversion (⊖) is `b_from_a = ⊖ a_from_b`.
//!
//! Two parametrisations are used:
//! - the *vector* form `(x, y, θ)` with θ wrapped to (-π, π], which is what the
//!   g2o error, trajectory files and the backend's additive update use;
//! - the *tangent* form `ξ = (v_x, v_y, ω)` of the Lie algebra se(2), reached
//!   with [`Se2::exp`] and [`Se2::log`].

use nalgebra::{Isometry2, Matrix2, Matrix3, Point2, UnitComplex, Vector2, Vector3};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::f64::consts::PI;
use std::ops::Mul;

/// Wraps an angle to (-π, π].
pub fn wrap_angle(angle_rad: f64) -> f64 {
    let wrapped = angle_rad.rem_euclid(2.0 * PI); // [0, 2π)
    if wrapped > PI {
        wrapped - 2.0 * PI
    } else {
        wrapped
    }
}

/// An element of SE(2): a rotation by θ followed by a translation (x, y).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Se2 {
    iso: Isometry2<f64>,
}

impl Default for Se2 {
    fn default() -> Self {
        Self::identity()
    }
}

impl Se2 {
    /// The pose with translation `(x_m, y_m)` and heading `theta_rad`.
    pub fn new(x_m: f64, y_m: f64, theta_rad: f64) -> Self {
        Self {
            iso: Isometry2::new(Vector2::new(x_m, y_m), theta_rad),
        }
    }

    pub fn identity() -> Self {
        Self {
            iso: Isometry2::identity(),
        }
    }

    /// Builds a pose from the vector form `(x, y, θ)`.
    pub fn from_vector(v: &Vector3<f64>) -> Self {
        Self::new(v.x, v.y, v.z)
    }

    pub fn from_isometry(iso: Isometry2<f64>) -> Self {
        Self { iso }
    }

    pub fn isometry(&self) -> &Isometry2<f64> {
        &self.iso
    }

    pub fn x(&self) -> f64 {
        self.iso.translation.x
    }

    pub fn y(&self) -> f64 {
        self.iso.translation.y
    }

    /// Heading in (-π, π].
    pub fn theta(&self) -> f64 {
        wrap_angle(self.iso.rotation.angle())
    }

    pub fn translation(&self) -> Vector2<f64> {
        self.iso.translation.vector
    }

    pub fn rotation(&self) -> UnitComplex<f64> {
        self.iso.rotation
    }

    /// The 2x2 rotation matrix R(θ).
    pub fn rotation_matrix(&self) -> Matrix2<f64> {
        *self.iso.rotation.to_rotation_matrix().matrix()
    }

    /// The vector form `(x, y, θ)`, θ in (-π, π].
    pub fn to_vector(&self) -> Vector3<f64> {
        Vector3::new(self.x(), self.y(), self.theta())
    }

    /// `self ⊕ other`: if `self` is `a_from_b` and `other` is `b_from_c`, the
    /// result is `a_from_c`.
    pub fn compose(&self, other: &Se2) -> Se2 {
        Se2 {
            iso: self.iso * other.iso,
        }
    }

    /// `⊖ self`: `b_from_a` for `self = a_from_b`.
    pub fn inverse(&self) -> Se2 {
        Se2 {
            iso: self.iso.inverse(),
        }
    }

    /// `⊖ self ⊕ other`: the pose of `other` seen from `self`. For two world
    /// poses `world_from_i`, `world_from_j` this is `i_from_j`.
    pub fn between(&self, other: &Se2) -> Se2 {
        Se2 {
            iso: self.iso.inv_mul(&other.iso),
        }
    }

    /// Maps a point of frame `b` into frame `a` (`self = a_from_b`).
    pub fn transform_point(&self, p: &Point2<f64>) -> Point2<f64> {
        self.iso.transform_point(p)
    }

    /// Applies the pose to a point given as `(x, y)`.
    pub fn transform_xy(&self, x: f64, y: f64) -> (f64, f64) {
        // The unit complex number holds (cos θ, sin θ): no atan2 and
        // sin_cos per point (1.5% of a St Pere run's instructions).
        let (c, s) = (self.iso.rotation.cos_angle(), self.iso.rotation.sin_angle());
        let t = &self.iso.translation.vector;
        (c * x - s * y + t.x, s * x + c * y + t.y)
    }

    /// The group exponential of `ξ = (v_x, v_y, ω)`.
    pub fn exp(xi: &Vector3<f64>) -> Se2 {
        let omega = xi.z;
        let v = Vector2::new(xi.x, xi.y);
        let t = v_matrix(omega) * v;
        Se2::new(t.x, t.y, omega)
    }

    /// The group logarithm `ξ = (v_x, v_y, ω)` with ω in (-π, π].
    pub fn log(&self) -> Vector3<f64> {
        let omega = self.theta();
        let v = v_matrix_inverse(omega) * self.translation();
        Vector3::new(v.x, v.y, omega)
    }

    /// The adjoint matrix: `Ad(T) ξ = log(T exp(ξ) T⁻¹)` to first order,
    /// with tangent order `(v_x, v_y, ω)`.
    pub fn adjoint(&self) -> Matrix3<f64> {
        let r = self.rotation_matrix();
        let t = self.translation();
        Matrix3::new(
            r[(0, 0)],
            r[(0, 1)],
            t.y,
            r[(1, 0)],
            r[(1, 1)],
            -t.x,
            0.0,
            0.0,
            1.0,
        )
    }

    /// Jacobians of the vector form of `self ⊕ other` with respect to the
    /// vector forms of `self` and `other` (additive perturbation of
    /// `(x, y, θ)`). Returns `(self ⊕ other, d/d self, d/d other)`.
    pub fn compose_with_jacobians(&self, other: &Se2) -> (Se2, Matrix3<f64>, Matrix3<f64>) {
        let r = self.rotation_matrix();
        // dR/dθ · t_other = R · [-y, x]
        let dr_t = r * Vector2::new(-other.y(), other.x());
        let j_self = Matrix3::new(1.0, 0.0, dr_t.x, 0.0, 1.0, dr_t.y, 0.0, 0.0, 1.0);
        let mut j_other = Matrix3::identity();
        j_other.fixed_view_mut::<2, 2>(0, 0).copy_from(&r);
        (self.compose(other), j_self, j_other)
    }

    /// Jacobian of the vector form of `⊖ self` with respect to the vector
    /// form of `self`. Returns `(⊖ self, d/d self)`.
    pub fn inverse_with_jacobian(&self) -> (Se2, Matrix3<f64>) {
        let rt = self.rotation_matrix().transpose();
        let t = self.translation();
        // t_inv = -Rᵀ t, so d t_inv / dθ = -(dRᵀ/dθ) t = Rᵀ [-t_y, t_x]ᵀ.
        let d_theta = rt * Vector2::new(-t.y, t.x);
        let mut j = Matrix3::zeros();
        j.fixed_view_mut::<2, 2>(0, 0).copy_from(&(-rt));
        j[(0, 2)] = d_theta.x;
        j[(1, 2)] = d_theta.y;
        j[(2, 2)] = -1.0;
        (self.inverse(), j)
    }

    /// Jacobians of the vector form of `self.between(other) = ⊖ self ⊕ other`
    /// with respect to the vector forms of `self` and `other`.
    /// Returns `(⊖ self ⊕ other, d/d self, d/d other)`.
    pub fn between_with_jacobians(&self, other: &Se2) -> (Se2, Matrix3<f64>, Matrix3<f64>) {
        let rt = self.rotation_matrix().transpose();
        let dt = other.translation() - self.translation();
        // d(Rᵀ dt)/dθ = Rᵀ [dt_y, -dt_x]ᵀ
        let d_theta = rt * Vector2::new(dt.y, -dt.x);
        let mut j_self = Matrix3::zeros();
        j_self.fixed_view_mut::<2, 2>(0, 0).copy_from(&(-rt));
        j_self[(0, 2)] = d_theta.x;
        j_self[(1, 2)] = d_theta.y;
        j_self[(2, 2)] = -1.0;
        let mut j_other = Matrix3::identity();
        j_other.fixed_view_mut::<2, 2>(0, 0).copy_from(&rt);
        (self.between(other), j_self, j_other)
    }

    /// Checks all components are finite.
    pub fn is_finite(&self) -> bool {
        self.x().is_finite() && self.y().is_finite() && self.iso.rotation.angle().is_finite()
    }
}

impl Mul for Se2 {
    type Output = Se2;
    fn mul(self, rhs: Se2) -> Se2 {
        self.compose(&rhs)
    }
}

impl Mul<&Se2> for &Se2 {
    type Output = Se2;
    fn mul(self, rhs: &Se2) -> Se2 {
        self.compose(rhs)
    }
}

/// `V(ω) = (1/ω) [[sin ω, -(1 - cos ω)], [1 - cos ω, sin ω]]`, the matrix that
/// maps the translational part of ξ to the translation of exp(ξ).
pub fn v_matrix(omega: f64) -> Matrix2<f64> {
    let (a, b) = sinc_terms(omega);
    Matrix2::new(a, -b, b, a)
}

/// Inverse of [`v_matrix`].
pub fn v_matrix_inverse(omega: f64) -> Matrix2<f64> {
    let (a, b) = sinc_terms(omega);
    let det = a * a + b * b;
    Matrix2::new(a, b, -b, a) / det
}

/// `(sin ω / ω, (1 - cos ω) / ω)` with Taylor series near zero.
fn sinc_terms(omega: f64) -> (f64, f64) {
    if omega.abs() < 1e-6 {
        let w2 = omega * omega;
        (1.0 - w2 / 6.0, omega / 2.0 - omega * w2 / 24.0)
    } else {
        (omega.sin() / omega, (1.0 - omega.cos()) / omega)
    }
}

impl Serialize for Se2 {
    /// Serialised as `[x, y, theta]`.
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        [self.x(), self.y(), self.theta()].serialize(serializer)
    }
}

impl<'de> Deserialize<'de> for Se2 {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let [x, y, theta] = <[f64; 3]>::deserialize(deserializer)?;
        Ok(Se2::new(x, y, theta))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_angle_range() {
        assert_eq!(wrap_angle(PI), PI);
        assert_eq!(wrap_angle(-PI), PI);
        assert!((wrap_angle(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-12);
        assert!((wrap_angle(-0.1) + 0.1).abs() < 1e-15);
    }

    #[test]
    fn between_is_inverse_compose() {
        let a = Se2::new(1.0, -2.0, 0.7);
        let b = Se2::new(-0.5, 3.0, -2.9);
        let d = a.between(&b);
        let expected = a.inverse().compose(&b);
        assert!((d.to_vector() - expected.to_vector()).norm() < 1e-12);
        assert!((a.compose(&d).to_vector() - b.to_vector()).norm() < 1e-12);
    }
}
