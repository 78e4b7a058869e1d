//! The constant-velocity motion model of the dead-reckoning EKF (Ribas et
//! al., the seed paper's reference \[10\]): the state, its prediction with
//! Jacobian, and the process noise of white accelerations.
//!
//! State `s = (x, y, ψ, u, v, r)`: `world_from_vehicle` (m, m, rad) and the
//! body velocities of the vehicle origin (surge `u` and sway `v` in m/s,
//! yaw rate `r` in rad/s). Over a step `dt` the body velocities are
//! constant and the pose moves along them, rotated at the mid-step heading:
//!
//! ```text
//! φ = ψ + r dt / 2
//! (x, y)' = (x, y) + dt R(φ) (u, v),   ψ' = ψ + r dt,   (u, v, r)' = (u, v, r)
//! ```
//!
//! The velocities change by white accelerations: surge and sway with
//! spectral density `q_a` ((m/s²)²/Hz) each, in the body frame, and the
//! yaw rate with `q_α` ((rad/s²)²/Hz). Integrated over `dt` (a velocity
//! random walk, its position integral an integrated random walk) they give
//! per body axis `Var Δv = q dt`, `Cov(Δp, Δv) = q dt²/2`,
//! `Var Δp = q dt³/3`, the position part rotated into the world frame by
//! `R(φ)`. A white heading noise `q_ψ dt` (rad²) may be added on top.

use nalgebra::{Matrix2, Matrix3, Matrix6, Rotation2, Vector2, Vector6};

/// Indices of the state vector.
pub(crate) const X: usize = 0;
pub(crate) const Y: usize = 1;
pub(crate) const PSI: usize = 2;
pub(crate) const U: usize = 3;
pub(crate) const V: usize = 4;
pub(crate) const R: usize = 5;

/// Spectral densities of the process noise.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub(crate) struct ProcessNoise {
    /// Surge and sway acceleration, (m/s²)²/Hz = m²/s³.
    pub acceleration: f64,
    /// Yaw acceleration, (rad/s²)²/Hz = rad²/s³.
    pub yaw_acceleration: f64,
    /// White heading noise, rad²/s.
    pub heading: f64,
}

/// The state after `dt` seconds (negative `dt` runs the model backwards)
/// and the Jacobian `∂s'/∂s`. The heading is not wrapped.
pub(crate) fn predict(s: &Vector6<f64>, dt: f64) -> (Vector6<f64>, Matrix6<f64>) {
    let phi = s[PSI] + 0.5 * s[R] * dt;
    let rot = Rotation2::new(phi);
    let d = rot * Vector2::new(s[U], s[V]) * dt;
    let mut next = *s;
    next[X] += d.x;
    next[Y] += d.y;
    next[PSI] += s[R] * dt;
    let mut f = Matrix6::identity();
    // ∂d/∂φ = (-d.y, d.x); φ depends on ψ (1) and r (dt / 2).
    f[(X, PSI)] = -d.y;
    f[(Y, PSI)] = d.x;
    f[(X, R)] = -0.5 * dt * d.y;
    f[(Y, R)] = 0.5 * dt * d.x;
    f.fixed_view_mut::<2, 2>(X, U)
        .copy_from(&(rot.matrix() * dt));
    f[(PSI, R)] = dt;
    (next, f)
}

/// Covariance of the state change over `|dt|` seconds caused by the process
/// noise, for a vehicle at heading `psi_mid_rad` (the mid-step heading).
pub(crate) fn process_covariance(noise: &ProcessNoise, psi_mid_rad: f64, dt: f64) -> Matrix6<f64> {
    let dt = dt.abs();
    let mut q = Matrix6::zeros();
    if dt == 0.0 {
        return q;
    }
    let (dt2, dt3) = (dt * dt, dt * dt * dt);
    let rot = *Rotation2::new(psi_mid_rad).matrix();
    let qa = noise.acceleration;
    // Position (world) and body velocity: [[q dt³/3 R Rᵀ, q dt²/2 R], [., q dt I]].
    let pos_pos: Matrix2<f64> = rot * rot.transpose() * (qa * dt3 / 3.0);
    let pos_vel: Matrix2<f64> = rot * (qa * dt2 / 2.0);
    q.fixed_view_mut::<2, 2>(X, X).copy_from(&pos_pos);
    q.fixed_view_mut::<2, 2>(X, U).copy_from(&pos_vel);
    q.fixed_view_mut::<2, 2>(U, X)
        .copy_from(&pos_vel.transpose());
    q.fixed_view_mut::<2, 2>(U, U)
        .copy_from(&(Matrix2::identity() * (qa * dt)));
    let qy = noise.yaw_acceleration;
    q[(PSI, PSI)] = qy * dt3 / 3.0 + noise.heading * dt;
    q[(PSI, R)] = qy * dt2 / 2.0;
    q[(R, PSI)] = q[(PSI, R)];
    q[(R, R)] = qy * dt;
    q
}

/// The pose block `(x, y, ψ)` of a state covariance.
pub(crate) fn pose_block(p: &Matrix6<f64>) -> Matrix3<f64> {
    p.fixed_view::<3, 3>(0, 0).into_owned()
}

pub(crate) fn symmetric6(m: &Matrix6<f64>) -> Matrix6<f64> {
    (m + m.transpose()) * 0.5
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The analytic Jacobian against central differences, at headings and
    /// yaw rates of both signs.
    #[test]
    fn jacobian_matches_central_differences() {
        for (psi, r, dt) in [(0.3, 0.05, 0.4), (-2.9, -0.2, 0.1), (3.1, 0.0, 1.3)] {
            let s = Vector6::new(1.0, -2.0, psi, 0.45, -0.07, r);
            let (_, f) = predict(&s, dt);
            for j in 0..6 {
                let h = 1e-6;
                let mut a = s;
                let mut b = s;
                a[j] += h;
                b[j] -= h;
                let column = (predict(&a, dt).0 - predict(&b, dt).0) / (2.0 * h);
                for i in 0..6 {
                    assert!(
                        (column[i] - f[(i, j)]).abs() < 1e-7,
                        "∂{i}/∂{j}: {} vs {}",
                        column[i],
                        f[(i, j)]
                    );
                }
            }
        }
    }

    /// One long step and twenty short ones, propagated, give the same
    /// process covariance (for a vehicle at rest, where heading errors do
    /// not move the position).
    #[test]
    fn process_noise_composes_over_steps() {
        let noise = ProcessNoise {
            acceleration: 0.02_f64.powi(2),
            yaw_acceleration: 0.01_f64.powi(2),
            heading: 1e-6,
        };
        let s = Vector6::new(0.0, 0.0, 0.7, 0.0, 0.0, 0.0);
        let whole = process_covariance(&noise, 0.7, 2.0);
        let mut p = Matrix6::zeros();
        let mut state = s;
        for _ in 0..20 {
            let (next, f) = predict(&state, 0.1);
            p = f * p * f.transpose() + process_covariance(&noise, 0.7, 0.1);
            state = next;
        }
        assert!((p - whole).abs().max() < 1e-12, "{p}\n{whole}");
    }
}
