//! The navigation history (the paper's "transformations history"): the
//! filter's pose and covariance at every step, queried at any time.

use super::gyro_check::YawRateCheck;
use super::model::{self, ProcessNoise, pose_block};
use crate::error::FrontendError;
use echofield_graph::Se2;
use echofield_graph::se2::wrap_angle;
use nalgebra::{Matrix3, Matrix6, Vector2, Vector3, Vector6};

/// One step of the history: the filter state just after processing one
/// record.
#[derive(Clone, Debug, PartialEq)]
pub struct NavigationStep {
    pub stamp_s: f64,
    /// `world_from_vehicle` after this step.
    pub world_from_vehicle: Se2,
    /// Velocity of the vehicle origin in the vehicle frame (m/s) and yaw
    /// rate (rad/s) estimated at this step; used to extrapolate.
    pub velocity_mps: Vector2<f64>,
    pub yaw_rate_radps: f64,
    /// Covariance of the whole filter state `(x, y, θ, u, v, r)` (m, rad,
    /// m/s, rad/s).
    pub state_covariance: Matrix6<f64>,
    /// How this step's state error is linked to the previous step's, for
    /// the covariance of relative motions; identity for the first step.
    /// Filtered: `e_k = T e_{k-1} + w` (`(I - K H) F` of the EKF).
    /// Smoothed: `e_{k-1} = T e_k + w` (the smoother gain `G_{k-1}`). In both
    /// `w` is independent of the error on the right.
    pub state_transition: Matrix6<f64>,
}

impl NavigationStep {
    /// Covariance of `(x, y, θ)` in m², m·rad, rad²: the pose block of
    /// `state_covariance` (not stored apart: a long mission's navigation
    /// holds a few hundred thousand steps).
    pub fn covariance(&self) -> Matrix3<f64> {
        pose_block(&self.state_covariance)
    }
}

/// An interval without valid DVL samples longer than the configured limit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DvlGap {
    /// Stamp of the last valid sample before the gap.
    pub start_s: f64,
    /// Stamp of the first valid sample after it (or the end of the data).
    pub end_s: f64,
}

/// The vehicle trajectory estimated by dead reckoning: pose and covariance
/// at every filter step, with interpolation in between.
///
/// Times between two steps are interpolated linearly (x, y, and θ along the
/// shorter arc; covariance element-wise). Times up to `max_extrapolation_s`
/// before the first or after the last step are extrapolated with the
/// velocity and yaw rate of that step (the constant-velocity model), the
/// covariance growing with the model's process noise; beyond that, queries
/// fail with [`FrontendError::OutsideNavigation`].
#[derive(Clone, Debug, PartialEq)]
pub struct Navigation {
    steps: Vec<NavigationStep>,
    /// The step stamps and `(x, y, θ)` again, contiguous, so that lookups
    /// stay in cache and interpolation needs no `atan2`.
    stamps_s: Vec<f64>,
    vectors: Vec<Vector3<f64>>,
    dvl_gaps: Vec<DvlGap>,
    max_extrapolation_s: f64,
    noise: ProcessNoise,
    /// The steps are RTS-smoothed (changes the meaning of
    /// `state_transition`, see [`NavigationStep`]).
    smoothed: bool,
    /// Valid DVL samples the filter's innovation gate rejected.
    dvl_gated: usize,
    /// The heading unit's wandering error, outside the filter.
    heading_bias: HeadingBias,
    /// The yaw-rate noise the filter used, rad/s, and the check that set it.
    yaw_rate_noise_radps: f64,
    yaw_rate_check: Option<YawRateCheck>,
}

/// A Gauss-Markov heading error the filter does not estimate (see
/// [`Navigation::relative`]); zero for navigations from known poses.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct HeadingBias {
    /// Standard deviation, rad.
    pub sigma_rad: f64,
    /// Correlation time, s.
    pub time_constant_s: f64,
}

impl HeadingBias {
    /// Variance of the error's change over `dt_s`: `2σ²(1 − e^{−|dt|/τ})`.
    pub fn change_variance(&self, dt_s: f64) -> f64 {
        if self.sigma_rad == 0.0 || self.time_constant_s <= 0.0 {
            return 0.0;
        }
        2.0 * self.sigma_rad * self.sigma_rad * (1.0 - (-dt_s.abs() / self.time_constant_s).exp())
    }
}

enum Location {
    /// Between step `k` and `k + 1` at fraction `f` in [0, 1); `f = 0` at the last step.
    Between(usize, f64),
    /// `dt` seconds (signed) from step `k`, outside the span.
    Outside(usize, f64),
}

impl Navigation {
    pub(crate) fn from_steps(
        steps: Vec<NavigationStep>,
        dvl_gaps: Vec<DvlGap>,
        max_extrapolation_s: f64,
        noise: ProcessNoise,
        smoothed: bool,
    ) -> Self {
        debug_assert!(!steps.is_empty());
        Self {
            stamps_s: steps.iter().map(|s| s.stamp_s).collect(),
            vectors: steps
                .iter()
                .map(|s| s.world_from_vehicle.to_vector())
                .collect(),
            steps,
            dvl_gaps,
            max_extrapolation_s,
            noise,
            smoothed,
            dvl_gated: 0,
            heading_bias: HeadingBias::default(),
            yaw_rate_noise_radps: 0.0,
            yaw_rate_check: None,
        }
    }

    /// Appends a filter step (the causal filter's history growing). The
    /// step must not be earlier than the last one.
    pub(crate) fn push_step(&mut self, step: NavigationStep) {
        debug_assert!(step.stamp_s >= self.end_s());
        self.stamps_s.push(step.stamp_s);
        self.vectors.push(step.world_from_vehicle.to_vector());
        self.steps.push(step);
    }

    /// Gives back the room the history grew into (a finished navigation
    /// is held for the rest of a run: on a long mission a few hundred
    /// thousand steps of several hundred bytes each).
    pub(crate) fn shrink_to_fit(&mut self) {
        self.steps.shrink_to_fit();
        self.stamps_s.shrink_to_fit();
        self.vectors.shrink_to_fit();
    }

    /// The steps, giving up the history.
    pub(crate) fn into_steps(self) -> Vec<NavigationStep> {
        self.steps
    }

    /// Replaces the DVL gaps (the causal filter's list, with a gap still
    /// open at its latest sample).
    pub(crate) fn set_dvl_gaps(&mut self, gaps: Vec<DvlGap>) {
        self.dvl_gaps = gaps;
    }

    /// A navigation that follows known poses exactly (zero covariance), e.g.
    /// ground truth for a test or a vehicle known to be still. Velocities for
    /// extrapolation come from finite differences. Errors when the slices
    /// differ in length or are empty, or a stamp is non-finite or not
    /// increasing, or a pose is not finite.
    pub fn from_poses(
        stamps_s: &[f64],
        poses: &[Se2],
        max_extrapolation_s: f64,
    ) -> Result<Self, FrontendError> {
        check_poses(stamps_s, poses)?;
        let twist = |k: usize| -> (Vector2<f64>, f64) {
            if stamps_s.len() < 2 {
                return (Vector2::zeros(), 0.0);
            }
            let k = k.min(stamps_s.len() - 2);
            let xi = poses[k].between(&poses[k + 1]).log() / (stamps_s[k + 1] - stamps_s[k]);
            (Vector2::new(xi.x, xi.y), xi.z)
        };
        let steps = stamps_s
            .iter()
            .zip(poses)
            .enumerate()
            .map(|(k, (&stamp_s, pose))| {
                let (velocity_mps, yaw_rate_radps) = twist(k);
                NavigationStep {
                    stamp_s,
                    world_from_vehicle: *pose,
                    velocity_mps,
                    yaw_rate_radps,
                    state_covariance: Matrix6::zeros(),
                    state_transition: Matrix6::identity(),
                }
            })
            .collect();
        Ok(Self::from_steps(
            steps,
            Vec::new(),
            max_extrapolation_s,
            ProcessNoise::default(),
            false,
        ))
    }

    /// A vehicle that does not move: identity pose, zero covariance, valid at
    /// every time (the span `[start_s, end_s]` is informative only).
    pub fn stationary(start_s: f64, end_s: f64) -> Self {
        let step = |stamp_s| NavigationStep {
            stamp_s,
            world_from_vehicle: Se2::identity(),
            velocity_mps: Vector2::zeros(),
            yaw_rate_radps: 0.0,
            state_covariance: Matrix6::zeros(),
            state_transition: Matrix6::identity(),
        };
        let mut steps = vec![step(start_s)];
        if end_s > start_s {
            steps.push(step(end_s));
        }
        Self::from_steps(
            steps,
            Vec::new(),
            f64::INFINITY,
            ProcessNoise::default(),
            false,
        )
    }

    /// Stamp of the first filter step, s.
    pub fn start_s(&self) -> f64 {
        self.steps[0].stamp_s
    }

    /// Stamp of the last filter step, s.
    pub fn end_s(&self) -> f64 {
        self.steps[self.steps.len() - 1].stamp_s
    }

    /// Every filter step, in time order (e.g. to export the dead-reckoning
    /// trajectory).
    pub fn steps(&self) -> &[NavigationStep] {
        &self.steps
    }

    /// Intervals without valid DVL samples longer than `max_dvl_gap_s`.
    pub fn dvl_gaps(&self) -> &[DvlGap] {
        &self.dvl_gaps
    }

    /// How many valid DVL samples the innovation gate rejected
    /// (`DeadReckoningConfig::dvl_gate_chi2`).
    pub fn dvl_gated(&self) -> usize {
        self.dvl_gated
    }

    pub(crate) fn set_dvl_gated(&mut self, count: usize) {
        self.dvl_gated = count;
    }

    /// Standard deviation of one yaw-rate sample that the filter used,
    /// rad/s: `DeadReckoningConfig::yaw_rate_noise_radps`, or more when the
    /// yaw-rate check measured more (0 for navigations from known poses).
    pub fn yaw_rate_noise_radps(&self) -> f64 {
        self.yaw_rate_noise_radps
    }

    /// What the yaw-rate check measured (`None` when it was off or had
    /// too few samples with yaw rates).
    pub fn yaw_rate_check(&self) -> Option<&YawRateCheck> {
        self.yaw_rate_check.as_ref()
    }

    pub(crate) fn set_yaw_rate_noise(&mut self, noise_radps: f64, check: Option<YawRateCheck>) {
        self.yaw_rate_noise_radps = noise_radps;
        self.yaw_rate_check = check;
    }

    pub(crate) fn set_heading_bias(&mut self, bias: HeadingBias) {
        self.heading_bias = bias;
    }

    /// `world_from_vehicle` at `stamp_s` (see the type doc for interpolation
    /// and extrapolation).
    pub fn pose_at(&self, stamp_s: f64) -> Result<Se2, FrontendError> {
        Ok(match self.locate(stamp_s)? {
            Location::Between(k, f) => self.interpolate_pose(k, f),
            Location::Outside(k, dt) => self.extrapolate(k, dt).0,
        })
    }

    /// Covariance of `(x, y, θ)` of [`Navigation::pose_at`] at `stamp_s`.
    pub fn covariance_at(&self, stamp_s: f64) -> Result<Matrix3<f64>, FrontendError> {
        Ok(match self.locate(stamp_s)? {
            Location::Between(k, f) if f > 0.0 => {
                self.steps[k].covariance() * (1.0 - f) + self.steps[k + 1].covariance() * f
            }
            Location::Between(k, _) => self.steps[k].covariance(),
            Location::Outside(k, dt) => self.extrapolate(k, dt).1,
        })
    }

    /// The motion from `from_s` to `to_s`: `from_from_to = ⊖ pose_at(from_s)
    /// ⊕ pose_at(to_s)`, and the covariance of its vector form.
    ///
    /// The covariance is that of the relative error, not a difference of
    /// absolute covariances: with `P_a`, `P_b` the absolute covariances and
    /// `C = Cov(e_b, e_a)` the cross-covariance of the pose errors (from the
    /// state transitions of the steps nearest `from_s` to the one nearest
    /// `to_s`: `Φ P_a` for the filter, `(G P_b)ᵀ` after smoothing, see
    /// [`NavigationStep::state_transition`]), it is
    /// `[J_a J_b] [[P_a, Cᵀ], [C, P_b]] [J_a J_b]ᵀ` with the Jacobians of
    /// `between`. Uncertainty common to both ends (everything accumulated
    /// before `from_s`) cancels, which is what an odometry edge of a pose
    /// graph needs.
    ///
    /// The heading unit's wandering error ([`HeadingBias`], not in the
    /// filter) then adds the variance `q` of its change over the interval,
    /// `2σ²(1 − e^{−Δt/τ})`, along `J = (−y/2, x/2, 1)` for the relative
    /// translation `(x, y)`: the heading error grows through the interval,
    /// and the path turns with it by half the change on average. Without
    /// it, the simulated marina's odometry claimed 0.25° over a node
    /// interval against 0.49° RMS of actual error.
    pub fn relative(&self, from_s: f64, to_s: f64) -> Result<(Se2, Matrix3<f64>), FrontendError> {
        if from_s > to_s {
            let (to_from_from, cov) = self.relative(to_s, from_s)?;
            let (from_from_to, j) = to_from_from.inverse_with_jacobian();
            return Ok((from_from_to, symmetric(j * cov * j.transpose())));
        }
        let pose_a = self.pose_at(from_s)?;
        let pose_b = self.pose_at(to_s)?;
        let p_a = self.covariance_at(from_s)?;
        let p_b = self.covariance_at(to_s)?;
        let (a, b) = (self.nearest_step(from_s), self.nearest_step(to_s));
        let cross = if a == b {
            // Both ends at one step: their errors are the same error.
            p_a
        } else if self.smoothed {
            // Cov(e_a, e_b) = G_a ⋯ G_{b-1} P_b.
            let chain = self.steps[a + 1..=b]
                .iter()
                .rev()
                .fold(Matrix6::identity(), |g, step| step.state_transition * g);
            pose_block(&(chain * self.steps[b].state_covariance)).transpose()
        } else {
            // Cov(e_b, e_a) = Φ_b ⋯ Φ_{a+1} P_a.
            let phi = self.steps[a + 1..=b]
                .iter()
                .fold(Matrix6::identity(), |phi, step| step.state_transition * phi);
            pose_block(&(phi * self.steps[a].state_covariance))
        };
        // `cross` is Cov(e_b, e_a) of the poses.
        let (rel, j_a, j_b) = pose_a.between_with_jacobians(&pose_b);
        let mixed = j_b * cross * j_a.transpose();
        let cov =
            j_a * p_a * j_a.transpose() + j_b * p_b * j_b.transpose() + mixed + mixed.transpose();
        let bias = Vector3::new(-0.5 * rel.y(), 0.5 * rel.x(), 1.0);
        let cov = cov + bias * bias.transpose() * self.heading_bias.change_variance(to_s - from_s);
        Ok((rel, symmetric(cov)))
    }

    fn locate(&self, stamp_s: f64) -> Result<Location, FrontendError> {
        if !stamp_s.is_finite() {
            return Err(FrontendError::input(
                "navigation query",
                "stamp_s",
                "not finite",
            ));
        }
        let (start_s, end_s) = (self.start_s(), self.end_s());
        if stamp_s < start_s - self.max_extrapolation_s
            || stamp_s > end_s + self.max_extrapolation_s
        {
            return Err(FrontendError::OutsideNavigation {
                stamp_s,
                start_s,
                end_s,
                max_extrapolation_s: self.max_extrapolation_s,
            });
        }
        let last = self.steps.len() - 1;
        let idx = self.stamps_s.partition_point(|&s| s <= stamp_s);
        Ok(if idx == 0 {
            Location::Outside(0, stamp_s - start_s)
        } else if idx > last {
            if stamp_s == end_s {
                Location::Between(last, 0.0)
            } else {
                Location::Outside(last, stamp_s - end_s)
            }
        } else {
            let (s0, s1) = (&self.steps[idx - 1], &self.steps[idx]);
            Location::Between(idx - 1, (stamp_s - s0.stamp_s) / (s1.stamp_s - s0.stamp_s))
        })
    }

    /// Index of the step nearest in time to `stamp_s` (clamped to the span).
    fn nearest_step(&self, stamp_s: f64) -> usize {
        let idx = self.stamps_s.partition_point(|&s| s <= stamp_s);
        if idx == 0 {
            return 0;
        }
        let before = idx - 1;
        match self.steps.get(idx) {
            Some(after) if after.stamp_s - stamp_s < stamp_s - self.steps[before].stamp_s => idx,
            _ => before,
        }
    }

    fn interpolate_pose(&self, k: usize, f: f64) -> Se2 {
        if f == 0.0 {
            return self.steps[k].world_from_vehicle;
        }
        let (v0, v1) = (&self.vectors[k], &self.vectors[k + 1]);
        let theta = v0.z + f * wrap_angle(v1.z - v0.z);
        Se2::new(v0.x + f * (v1.x - v0.x), v0.y + f * (v1.y - v0.y), theta)
    }

    /// Pose and covariance `dt` seconds (signed) from step `k`, moving with
    /// that step's velocity and yaw rate (the constant-velocity model run
    /// forwards or backwards; the process noise grows with `|dt|`).
    fn extrapolate(&self, k: usize, dt: f64) -> (Se2, Matrix3<f64>) {
        let step = &self.steps[k];
        let pose = &step.world_from_vehicle;
        let state = Vector6::new(
            pose.x(),
            pose.y(),
            pose.theta(),
            step.velocity_mps.x,
            step.velocity_mps.y,
            step.yaw_rate_radps,
        );
        let (next, f) = model::predict(&state, dt);
        let psi_mid = pose.theta() + 0.5 * step.yaw_rate_radps * dt;
        let q = model::process_covariance(&self.noise, psi_mid, dt);
        let p = f * step.state_covariance * f.transpose() + q;
        (
            Se2::new(next[0], next[1], wrap_angle(next[2])),
            symmetric(pose_block(&p)),
        )
    }
}

pub(crate) fn symmetric(m: Matrix3<f64>) -> Matrix3<f64> {
    (m + m.transpose()) * 0.5
}

/// The input of [`Navigation::from_poses`]: as many stamps as poses, at
/// least one; stamps finite and increasing, poses finite. Errors name the
/// pose and field.
fn check_poses(stamps_s: &[f64], poses: &[Se2]) -> Result<(), FrontendError> {
    if stamps_s.len() != poses.len() || stamps_s.is_empty() {
        return Err(FrontendError::insufficient(
            "navigation from poses",
            format!("{} stamps and {} poses", stamps_s.len(), poses.len()),
        ));
    }
    for (i, (&t, pose)) in stamps_s.iter().zip(poses).enumerate() {
        if !t.is_finite() || (i > 0 && t <= stamps_s[i - 1]) {
            return Err(FrontendError::input(
                format!("pose {i}"),
                "stamp_s",
                "not finite or not increasing",
            ));
        }
        if !pose.is_finite() {
            return Err(FrontendError::input(
                format!("pose {i}"),
                "pose",
                "not finite",
            ));
        }
    }
    Ok(())
}
