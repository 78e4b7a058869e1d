//! Property suite for `Se2` on the real type: group identities, exp/log, and
//! every analytic Jacobian against central differences. Angles are drawn
//! from the whole circle plus the places where bugs hide: θ < 0, θ ≈ 0 and
//! θ ≈ ±π.

use echofield_graph::{Se2, wrap_angle};
use nalgebra::{Matrix3, Vector3};
use proptest::prelude::*;
use std::f64::consts::PI;

fn angle() -> impl Strategy<Value = f64> {
    prop_oneof![
        -PI..PI,
        -PI..0.0,
        -1e-7..1e-7,
        (PI - 1e-7)..PI,
        -PI..(-PI + 1e-7),
        Just(0.0),
        Just(PI),
        Just(-PI),
    ]
}

fn pose() -> impl Strategy<Value = Se2> {
    (-50.0..50.0, -50.0..50.0, angle()).prop_map(|(x, y, t)| Se2::new(x, y, t))
}

/// A tangent vector with |ω| < π so that log(exp ξ) = ξ holds.
fn tangent() -> impl Strategy<Value = Vector3<f64>> {
    let omega = prop_oneof![
        (-PI + 1e-6)..(PI - 1e-6),
        -1e-7..1e-7,
        (-PI + 1e-6)..(-PI + 1e-3),
        (PI - 1e-3)..(PI - 1e-6),
    ];
    (-20.0..20.0, -20.0..20.0, omega).prop_map(|(x, y, w)| Vector3::new(x, y, w))
}

/// Difference of two vector-form poses with the angle wrapped.
fn vec_diff(a: &Vector3<f64>, b: &Vector3<f64>) -> Vector3<f64> {
    Vector3::new(a.x - b.x, a.y - b.y, wrap_angle(a.z - b.z))
}

fn assert_pose_eq(a: &Se2, b: &Se2, tol: f64) {
    let d = vec_diff(&a.to_vector(), &b.to_vector());
    assert!(d.norm() <= tol, "{a:?} != {b:?} (diff {d:?})");
}

/// Central-difference Jacobian of `f` (vector form to vector form) at `x`.
fn numeric_jacobian(f: impl Fn(&Vector3<f64>) -> Vector3<f64>, x: &Vector3<f64>) -> Matrix3<f64> {
    let h = 1e-6;
    let mut j = Matrix3::zeros();
    for k in 0..3 {
        let mut plus = *x;
        let mut minus = *x;
        plus[k] += h;
        minus[k] -= h;
        let column = vec_diff(&f(&plus), &f(&minus)) / (2.0 * h);
        j.set_column(k, &column);
    }
    j
}

fn assert_jacobian(analytic: &Matrix3<f64>, numeric: &Matrix3<f64>) {
    let err = (analytic - numeric).abs().max();
    let scale = 1.0 + numeric.abs().max();
    assert!(
        err <= 1e-6 * scale,
        "analytic\n{analytic}\nnumeric\n{numeric}"
    );
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn exp_of_log_is_identity(t in pose()) {
        assert_pose_eq(&Se2::exp(&t.log()), &t, 1e-9);
    }

    #[test]
    fn log_of_exp_is_identity(xi in tangent()) {
        let back = Se2::exp(&xi).log();
        prop_assert!((back - xi).norm() < 1e-9 * (1.0 + xi.norm()), "{xi:?} -> {back:?}");
    }

    /// exp(ξ) is the flow of the constant body twist ξ for unit time:
    /// compare with composing many small first-order steps. Independent of
    /// the closed form, so a sign error for negative ω cannot hide.
    #[test]
    fn exp_matches_integrated_twist(xi in tangent()) {
        let steps = 20_000;
        let dt = 1.0 / steps as f64;
        let step = Se2::new(xi.x * dt, xi.y * dt, xi.z * dt);
        let mut integrated = Se2::identity();
        for _ in 0..steps {
            integrated = integrated.compose(&step);
        }
        assert_pose_eq(&Se2::exp(&xi), &integrated, 1e-3 * (1.0 + xi.norm()));
    }

    #[test]
    fn exp_is_a_one_parameter_subgroup(xi in tangent()) {
        let half = Se2::exp(&(xi * 0.5));
        assert_pose_eq(&half.compose(&half), &Se2::exp(&xi), 1e-9 * (1.0 + xi.norm()));
    }

    #[test]
    fn compose_is_associative(a in pose(), b in pose(), c in pose()) {
        assert_pose_eq(&a.compose(&b).compose(&c), &a.compose(&b.compose(&c)), 1e-9);
    }

    #[test]
    fn inverse_identities(a in pose(), b in pose()) {
        assert_pose_eq(&a.compose(&a.inverse()), &Se2::identity(), 1e-9);
        assert_pose_eq(&a.inverse().compose(&a), &Se2::identity(), 1e-9);
        assert_pose_eq(&a.compose(&b).inverse(), &b.inverse().compose(&a.inverse()), 1e-9);
        assert_pose_eq(&a.between(&b), &a.inverse().compose(&b), 1e-9);
        assert_pose_eq(&a.compose(&a.between(&b)), &b, 1e-9);
    }

    #[test]
    fn theta_is_wrapped(a in pose()) {
        prop_assert!(a.theta() > -PI && a.theta() <= PI);
    }

    #[test]
    fn transform_point_matches_compose(a in pose(), x in -10.0..10.0f64, y in -10.0..10.0f64) {
        let p = a.transform_point(&nalgebra::Point2::new(x, y));
        let q = a.compose(&Se2::new(x, y, 0.0));
        prop_assert!((p.x - q.x()).abs() < 1e-9 && (p.y - q.y()).abs() < 1e-9);
        let (tx, ty) = a.transform_xy(x, y);
        prop_assert!((p.x - tx).abs() < 1e-9 && (p.y - ty).abs() < 1e-9);
    }

    #[test]
    fn adjoint_moves_tangents_across(t in pose(), xi in tangent()) {
        let lhs = t.compose(&Se2::exp(&xi)).compose(&t.inverse());
        let rhs = Se2::exp(&(t.adjoint() * xi));
        assert_pose_eq(&lhs, &rhs, 1e-8 * (1.0 + t.translation().norm()) * (1.0 + xi.norm()));
    }

    #[test]
    fn compose_jacobians(a in pose(), b in pose()) {
        let (ab, ja, jb) = a.compose_with_jacobians(&b);
        assert_pose_eq(&ab, &a.compose(&b), 0.0);
        let na = numeric_jacobian(|v| Se2::from_vector(v).compose(&b).to_vector(), &a.to_vector());
        let nb = numeric_jacobian(|v| a.compose(&Se2::from_vector(v)).to_vector(), &b.to_vector());
        assert_jacobian(&ja, &na);
        assert_jacobian(&jb, &nb);
    }

    #[test]
    fn inverse_jacobian(a in pose()) {
        let (inv, j) = a.inverse_with_jacobian();
        assert_pose_eq(&inv, &a.inverse(), 0.0);
        let n = numeric_jacobian(|v| Se2::from_vector(v).inverse().to_vector(), &a.to_vector());
        assert_jacobian(&j, &n);
    }

    #[test]
    fn between_jacobians(a in pose(), b in pose()) {
        let (d, ja, jb) = a.between_with_jacobians(&b);
        assert_pose_eq(&d, &a.between(&b), 0.0);
        let na = numeric_jacobian(|v| Se2::from_vector(v).between(&b).to_vector(), &a.to_vector());
        let nb = numeric_jacobian(|v| a.between(&Se2::from_vector(v)).to_vector(), &b.to_vector());
        assert_jacobian(&ja, &na);
        assert_jacobian(&jb, &nb);
    }

    #[test]
    fn serde_round_trip(a in pose()) {
        let json = serde_json::to_string(&a).unwrap();
        let back: Se2 = serde_json::from_str(&json).unwrap();
        assert_pose_eq(&a, &back, 1e-12);
    }
}

#[test]
fn exp_of_negative_rotation_turns_clockwise() {
    // Driving forward 1 m while turning by -90°: the arc ends to the right
    // (negative y), at (2/π, -2/π).
    let t = Se2::exp(&Vector3::new(1.0, 0.0, -PI / 2.0));
    assert!((t.x() - 2.0 / PI).abs() < 1e-12, "{t:?}");
    assert!((t.y() + 2.0 / PI).abs() < 1e-12, "{t:?}");
    assert!((t.theta() + PI / 2.0).abs() < 1e-12);
}
