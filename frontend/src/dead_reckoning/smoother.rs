//! Rauch-Tung-Striebel smoothing of the dead-reckoning EKF: every step's
//! state re-estimated from all DVL and attitude records, before and after
//! it (optional, `DeadReckoningConfig::smoothing`).
//!
//! With `s_{k|k}`, `P_{k|k}` the filtered state of step `k`, and
//! `s_{k+1|k}`, `P_{k+1|k}`, `F_{k+1}` the prediction to step `k+1`, from
//! the last step backwards:
//!
//! ```text
//! G_k     = P_{k|k} F_{k+1}ᵀ P_{k+1|k}⁻¹
//! s_{k|N} = s_{k|k} + G_k (s_{k+1|N} − s_{k+1|k})      (heading difference wrapped)
//! P_{k|N} = P_{k|k} + G_k (P_{k+1|N} − P_{k+1|k}) G_kᵀ
//! ```
//!
//! Given all records the smoothed errors form a Markov chain backwards in
//! time, `e_k = G_k e_{k+1} + w_k` with `w_k` independent of `e_{k+1}`, so
//! `Cov(e_a, e_b) = G_a ⋯ G_{b−1} P_{b|N}` for `a < b`: step `k + 1` stores
//! `G_k` as its transition, which [`super::Navigation::relative`] chains.
//!
//! Within one sonar rotation this is what matters: the forward filter's
//! velocity at a beam time has only seen the past, so its error is
//! integrated over the whole rotation; the smoothed velocity uses the DVL
//! samples on both sides.

use super::model::{PSI, R, U, V, X, Y, symmetric6};
use super::navigation::NavigationStep;
use echofield_graph::Se2;
use echofield_graph::se2::wrap_angle;
use nalgebra::{Matrix6, Vector2, Vector6};

/// The EKF's prediction to one step, before that step's update.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Prediction {
    /// `s_{k+1|k}`.
    pub state: Vector6<f64>,
    /// `P_{k+1|k}`.
    pub covariance: Matrix6<f64>,
    /// `F_{k+1} = ∂s_{k+1}/∂s_k`.
    pub jacobian: Matrix6<f64>,
}

/// Smooths `steps` in place; `predictions[k]` is the prediction that led
/// from step `k` to step `k + 1`.
pub(crate) fn smooth(steps: &mut [NavigationStep], predictions: &[Prediction]) {
    debug_assert_eq!(predictions.len() + 1, steps.len());
    let n = steps.len();
    let mut next_state = state_of(&steps[n - 1]);
    let mut next_cov = steps[n - 1].state_covariance;
    for k in (0..n - 1).rev() {
        let pred = &predictions[k];
        let filtered = state_of(&steps[k]);
        let p = steps[k].state_covariance;
        let Some(pred_inv) = inverse(&pred.covariance) else {
            // A degenerate prediction (no uncertainty at all): keep the
            // filtered step; its error is then not linked to the next one.
            steps[k + 1].state_transition = Matrix6::zeros();
            next_state = filtered;
            next_cov = p;
            continue;
        };
        let g = p * pred.jacobian.transpose() * pred_inv;
        let mut diff = next_state - pred.state;
        diff[PSI] = wrap_angle(diff[PSI]);
        let mut state = filtered + g * diff;
        state[PSI] = wrap_angle(state[PSI]);
        let cov = symmetric6(&(p + g * (next_cov - pred.covariance) * g.transpose()));
        steps[k + 1].state_transition = g;
        set_state(&mut steps[k], &state, &cov);
        next_state = state;
        next_cov = cov;
    }
}

fn state_of(step: &NavigationStep) -> Vector6<f64> {
    let pose = &step.world_from_vehicle;
    Vector6::new(
        pose.x(),
        pose.y(),
        pose.theta(),
        step.velocity_mps.x,
        step.velocity_mps.y,
        step.yaw_rate_radps,
    )
}

fn set_state(step: &mut NavigationStep, state: &Vector6<f64>, cov: &Matrix6<f64>) {
    step.world_from_vehicle = Se2::new(state[X], state[Y], state[PSI]);
    step.velocity_mps = Vector2::new(state[U], state[V]);
    step.yaw_rate_radps = state[R];
    step.state_covariance = *cov;
}

/// Inverse of a covariance: Cholesky, or the pseudo-inverse when it is
/// singular (e.g. no position uncertainty yet right after the start).
/// `None` for a zero or non-finite covariance: the SVD behind the
/// pseudo-inverse does not converge on infinite entries (it spun forever
/// on DVL velocities of 1e20 m/s, issue 35).
fn inverse(p: &Matrix6<f64>) -> Option<Matrix6<f64>> {
    if !p.iter().all(|v| v.is_finite()) {
        return None;
    }
    if let Some(chol) = p.cholesky() {
        return Some(chol.inverse());
    }
    let scale = p.abs().max();
    if scale <= 0.0 {
        return None;
    }
    p.pseudo_inverse(1e-12 * scale).ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_covariance_with_infinite_entries_has_no_inverse_and_ends() {
        // Issue 35: the pseudo-inverse's SVD never converged on this.
        let mut p = Matrix6::identity();
        p[(3, 3)] = f64::INFINITY;
        assert!(inverse(&p).is_none());
        p[(3, 3)] = f64::NAN;
        assert!(inverse(&p).is_none());
        assert!(inverse(&Matrix6::zeros()).is_none());
        // A singular but finite covariance gets the pseudo-inverse.
        let mut singular = Matrix6::identity();
        singular[(0, 0)] = 0.0;
        let inv = inverse(&singular).unwrap();
        assert_eq!(inv[(0, 0)], 0.0);
        assert!((inv[(1, 1)] - 1.0).abs() < 1e-12);
    }
}
