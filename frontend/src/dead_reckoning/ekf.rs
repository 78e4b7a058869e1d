//! The dead-reckoning EKF: record checks, the constant-velocity prediction
//! and the DVL, heading and yaw-rate updates (the model is documented in the
//! parent module and in [`super::model`]).

use super::DeadReckoningConfig;
use super::model::{self, PSI, ProcessNoise, R, U, V, X, Y, symmetric6};
use super::navigation::NavigationStep;
use super::smoother::Prediction;
use crate::error::FrontendError;
use crate::screening;
use crate::sensors::{Attitude, DvlVelocity, Mission, SensorMounting};
use echofield_graph::Se2;
use echofield_graph::se2::wrap_angle;
use nalgebra::{Matrix2, Matrix2x6, Matrix6, RowVector6, Vector2, Vector6};

/// Checks every record the filter will use: finite and plausible values
/// ([`crate::screening`]), stamps non-decreasing within each stream, at
/// least one valid DVL sample and one attitude sample.
pub(super) fn check_records(
    mission: &Mission,
    config: &DeadReckoningConfig,
) -> Result<(), FrontendError> {
    let mut last_s = f64::NEG_INFINITY;
    for (i, s) in mission.dvl.iter().enumerate() {
        check_dvl(i, s, last_s, config)?;
        last_s = s.stamp_s;
    }
    let mut last_s = f64::NEG_INFINITY;
    for (i, a) in mission.attitude.iter().enumerate() {
        check_attitude(i, a, last_s)?;
        last_s = a.stamp_s;
    }
    if !mission.dvl.iter().any(|s| s.valid) {
        return Err(FrontendError::insufficient(
            "dead reckoning",
            format!(
                "no valid DVL sample ({} samples, all invalid or none)",
                mission.dvl.len()
            ),
        ));
    }
    if mission.attitude.is_empty() {
        return Err(FrontendError::insufficient(
            "dead reckoning",
            "no heading: the mission has no attitude samples",
        ));
    }
    Ok(())
}

/// Checks DVL sample `i` (the `i`-th of its stream) whose predecessor in
/// the stream has stamp `last_s`: a finite stamp not earlier than `last_s`
/// and, when valid, a finite, plausible velocity and covariance.
pub(super) fn check_dvl(
    i: usize,
    s: &DvlVelocity,
    last_s: f64,
    config: &DeadReckoningConfig,
) -> Result<(), FrontendError> {
    let record = || format!("DVL sample {i}");
    check_stamp(s.stamp_s, last_s, record)?;
    if !s.valid {
        return Ok(());
    }
    if !(s.velocity_mps.x.is_finite() && s.velocity_mps.y.is_finite()) {
        return Err(FrontendError::input(record(), "velocity_mps", "not finite"));
    }
    if let Some(why) = screening::implausible_dvl_speed(&s.velocity_mps) {
        return Err(FrontendError::input(record(), "velocity_mps", why));
    }
    if config.use_dvl_covariance
        && let Some(cov) = &s.covariance
        && !cov.fixed_view::<2, 2>(0, 0).iter().all(|v| v.is_finite())
    {
        return Err(FrontendError::input(record(), "covariance", "not finite"));
    }
    Ok(())
}

/// Checks attitude sample `i` like [`check_dvl`]: stamp order, a finite
/// plausible yaw and yaw rate.
pub(super) fn check_attitude(i: usize, a: &Attitude, last_s: f64) -> Result<(), FrontendError> {
    let record = || format!("attitude sample {i}");
    check_stamp(a.stamp_s, last_s, record)?;
    if !a.yaw_rad.is_finite() {
        return Err(FrontendError::input(record(), "yaw_rad", "not finite"));
    }
    if let Some(why) = screening::implausible_angle(a.yaw_rad) {
        return Err(FrontendError::input(record(), "yaw_rad", why));
    }
    if let Some(w) = a.yaw_rate_radps {
        if !w.is_finite() {
            return Err(FrontendError::input(
                record(),
                "yaw_rate_radps",
                "not finite",
            ));
        }
        if let Some(why) = screening::implausible_yaw_rate(w) {
            return Err(FrontendError::input(record(), "yaw_rate_radps", why));
        }
    }
    Ok(())
}

fn check_stamp(
    stamp_s: f64,
    last_s: f64,
    record: impl Fn() -> String,
) -> Result<(), FrontendError> {
    if !stamp_s.is_finite() {
        return Err(FrontendError::input(record(), "stamp_s", "not finite"));
    }
    if stamp_s < last_s {
        return Err(FrontendError::input(
            record(),
            "stamp_s",
            format!("{stamp_s} s is earlier than the previous record's {last_s} s"),
        ));
    }
    Ok(())
}

/// Standard deviation of the yaw rate before the first measurement of it
/// (attitude units without a yaw rate never measure it; heading updates
/// then estimate it), rad/s: more than a slow AUV turns.
const INITIAL_YAW_RATE_STD_RADPS: f64 = 0.1;

/// Clip of one DVL sample's innovation power in the noise adaptation, in
/// units of the current noise variance (the χ² 2-dof 0.999 quantile): an
/// outlier raises the estimate by at most this over
/// `dvl_noise_adaptation_samples`.
const ADAPTATION_CLIP_CHI2: f64 = 13.82;

/// The filter: state `(x, y, ψ, u, v, r)` and its covariance.
pub(super) struct Ekf {
    config: DeadReckoningConfig,
    pub(super) noise: ProcessNoise,
    /// `v_dvl = H s`: the DVL velocity in the instrument frame is the
    /// vehicle's body velocity plus the lever-arm term `r × ℓ`, rotated by
    /// `dvl_from_vehicle`.
    h_dvl: Matrix2x6<f64>,
    /// `vehicle_from_dvl` rotation.
    vehicle_from_dvl: Matrix2<f64>,
    /// `r × ℓ = r (-ℓ_y, ℓ_x)`: the lever arm's velocity per unit yaw rate
    /// (zero without lever-arm compensation).
    lever: Vector2<f64>,
    pub(super) stamp_s: f64,
    s: Vector6<f64>,
    p: Matrix6<f64>,
    /// Estimated DVL noise variance per axis, (m/s)² (NaN before the first
    /// sample), and the factor it gives the nominal noise (>= 1).
    dvl_noise_var: f64,
    dvl_noise_scale: f64,
}

impl Ekf {
    pub(super) fn new(config: &DeadReckoningConfig, mounting: &SensorMounting) -> Self {
        let vehicle_from_dvl = mounting.vehicle_from_dvl.rotation_matrix();
        let arm = mounting.vehicle_from_dvl.translation();
        let lever = if config.lever_arm_compensation {
            Vector2::new(-arm.y, arm.x)
        } else {
            Vector2::zeros()
        };
        let mut body = Matrix2x6::zeros();
        body.fixed_view_mut::<2, 2>(0, U)
            .copy_from(&Matrix2::identity());
        body.fixed_view_mut::<2, 1>(0, R).copy_from(&lever);
        Self {
            config: config.clone(),
            noise: config.process_noise(),
            h_dvl: vehicle_from_dvl.transpose() * body,
            vehicle_from_dvl,
            lever,
            stamp_s: f64::NAN,
            s: Vector6::zeros(),
            p: Matrix6::zeros(),
            dvl_noise_var: f64::NAN,
            dvl_noise_scale: 1.0,
        }
    }

    /// The yaw-rate noise of later attitude updates, rad/s.
    pub(super) fn set_yaw_rate_noise(&mut self, noise_radps: f64) {
        self.config.yaw_rate_noise_radps = noise_radps;
    }

    /// Measurement covariance of a DVL sample (instrument frame), (m/s)².
    fn dvl_noise(&self, sample: &DvlVelocity) -> Matrix2<f64> {
        match &sample.covariance {
            Some(c) if self.config.use_dvl_covariance => c.fixed_view::<2, 2>(0, 0).into_owned(),
            _ => Matrix2::identity() * self.config.dvl_velocity_noise_mps.powi(2),
        }
    }

    /// The state at the first time both a velocity and a heading exist:
    /// origin at the vehicle, heading measured, body velocity solved from
    /// the DVL sample (with the measured yaw rate, or 0 and a wide prior).
    pub(super) fn initialise(&mut self, stamp_s: f64, dvl: &DvlVelocity, attitude: &Attitude) {
        let c = &self.config;
        let (r, r_var) = match attitude.yaw_rate_radps {
            Some(w) => (w, c.yaw_rate_noise_radps.powi(2)),
            None => (0.0, INITIAL_YAW_RATE_STD_RADPS.powi(2)),
        };
        let z = Vector2::new(dvl.velocity_mps.x, dvl.velocity_mps.y);
        // v = R_m z - r ℓ, so Cov v = R_m C R_mᵀ + σ_r² ℓ ℓᵀ, Cov(v, r) = -σ_r² ℓ.
        let v = self.vehicle_from_dvl * z - r * self.lever;
        let cov_v = self.vehicle_from_dvl * self.dvl_noise(dvl) * self.vehicle_from_dvl.transpose()
            + self.lever * self.lever.transpose() * r_var;
        self.stamp_s = stamp_s;
        self.s = Vector6::new(
            0.0,
            0.0,
            wrap_angle(attitude.yaw_rad + c.heading_offset_rad),
            v.x,
            v.y,
            r,
        );
        self.p = Matrix6::zeros();
        self.p[(PSI, PSI)] = c.heading_noise_rad.powi(2);
        self.p.fixed_view_mut::<2, 2>(U, U).copy_from(&cov_v);
        let cross = -self.lever * r_var;
        self.p.fixed_view_mut::<2, 1>(U, R).copy_from(&cross);
        self.p
            .fixed_view_mut::<1, 2>(R, U)
            .copy_from(&cross.transpose());
        self.p[(R, R)] = r_var;
    }

    /// Predicts to `stamp_s`; returns the prediction (for the smoother).
    pub(super) fn predict(&mut self, stamp_s: f64) -> Prediction {
        let dt = stamp_s - self.stamp_s;
        let psi_mid = self.s[PSI] + 0.5 * self.s[R] * dt;
        let (mut next, f) = model::predict(&self.s, dt);
        next[PSI] = wrap_angle(next[PSI]);
        let q = model::process_covariance(&self.noise, psi_mid, dt);
        self.s = next;
        self.p = symmetric6(&(f * self.p * f.transpose() + q));
        self.stamp_s = stamp_s;
        Prediction {
            state: self.s,
            covariance: self.p,
            jacobian: f,
        }
    }

    /// Linear update with a two-dimensional measurement; returns `I - K H`.
    fn update2(
        &mut self,
        h: &Matrix2x6<f64>,
        innovation: &Vector2<f64>,
        noise: &Matrix2<f64>,
    ) -> Matrix6<f64> {
        let Some(s_inv) = (h * self.p * h.transpose() + noise).try_inverse() else {
            return Matrix6::identity();
        };
        let k = self.p * h.transpose() * s_inv;
        self.s += k * innovation;
        self.s[PSI] = wrap_angle(self.s[PSI]);
        let i_kh = Matrix6::identity() - k * h;
        // Joseph form: stays positive definite with rounding.
        self.p = symmetric6(&(i_kh * self.p * i_kh.transpose() + k * noise * k.transpose()));
        i_kh
    }

    /// Scalar update; returns `I - K H`.
    fn update1(&mut self, h: &RowVector6<f64>, innovation: f64, variance: f64) -> Matrix6<f64> {
        let s = (h * self.p * h.transpose())[0] + variance;
        if s.is_nan() || s <= 0.0 {
            return Matrix6::identity();
        }
        let k = self.p * h.transpose() / s;
        self.s += k * innovation;
        self.s[PSI] = wrap_angle(self.s[PSI]);
        let i_kh = Matrix6::identity() - k * h;
        self.p = symmetric6(&(i_kh * self.p * i_kh.transpose() + k * k.transpose() * variance));
        i_kh
    }

    /// The DVL update, unless the sample fails the innovation gate: its
    /// squared Mahalanobis distance `νᵀ (H P Hᵀ + R)⁻¹ ν` exceeds
    /// `dvl_gate_chi2` (a χ² quantile with 2 degrees of freedom). `R` is
    /// the sample's nominal noise times the adaptive factor
    /// ([`Self::adapt_dvl_noise`]). Returns `None` for a gated-out sample
    /// (the state is left as predicted).
    pub(super) fn update_dvl(&mut self, sample: &DvlVelocity, gate: bool) -> Option<Matrix6<f64>> {
        let z = Vector2::new(sample.velocity_mps.x, sample.velocity_mps.y);
        let h = self.h_dvl;
        let innovation = z - h * self.s;
        let nominal = self.dvl_noise(sample);
        let noise = nominal * self.dvl_noise_scale;
        let predicted = h * self.p * h.transpose();
        let d2 = (predicted + noise)
            .try_inverse()
            .map_or(f64::INFINITY, |s_inv| innovation.dot(&(s_inv * innovation)));
        self.adapt_dvl_noise(&innovation, &predicted, &nominal);
        if gate && self.config.dvl_gate_chi2 > 0.0 && d2 > self.config.dvl_gate_chi2 {
            return None;
        }
        Some(self.update2(&h, &innovation, &noise))
    }

    /// Innovation-based noise adaptation (covariance matching): the
    /// measurement noise per axis is estimated as an exponential moving
    /// average, over about `dvl_noise_adaptation_samples` samples, of
    /// `(νᵀν - tr(H P Hᵀ)) / 2` (the innovation power not explained by the
    /// state's uncertainty), each sample's term clipped to `[0,
    /// ADAPTATION_CLIP_CHI2 · σ²]` with `σ²` the current noise so that one
    /// outlier moves it little. The factor applied to the nominal noise is
    /// that estimate over the nominal variance, never below 1: the
    /// configured noise is a floor, a noisier stretch of the mission (the
    /// real St Pere DVL goes from 0.1 to 0.3-0.4 m/s standard deviation)
    /// gets a larger noise and so a larger, honest covariance.
    fn adapt_dvl_noise(
        &mut self,
        innovation: &Vector2<f64>,
        predicted: &Matrix2<f64>,
        nominal: &Matrix2<f64>,
    ) {
        let n = self.config.dvl_noise_adaptation_samples;
        if n == 0 {
            return;
        }
        let nominal_var = 0.5 * nominal.trace();
        if nominal_var.is_nan() || nominal_var <= 0.0 {
            return;
        }
        let current_var = nominal_var * self.dvl_noise_scale;
        let cap = ADAPTATION_CLIP_CHI2 * current_var;
        // `max`/`min`, not `clamp`: a NaN cap must not panic.
        let power = (0.5 * (innovation.norm_squared() - predicted.trace()))
            .max(0.0)
            .min(cap);
        let w = 1.0 / n as f64;
        self.dvl_noise_var = if self.dvl_noise_var.is_nan() {
            nominal_var
        } else {
            (1.0 - w) * self.dvl_noise_var + w * power
        };
        self.dvl_noise_scale = (self.dvl_noise_var / nominal_var).max(1.0);
    }

    /// Heading `yaw + heading_offset_rad` (wrapped innovation), then the
    /// yaw rate when the sample has one.
    pub(super) fn update_attitude(&mut self, attitude: &Attitude) -> Matrix6<f64> {
        let (offset_rad, heading_var, yaw_rate_var) = (
            self.config.heading_offset_rad,
            self.config.heading_noise_rad.powi(2),
            self.config.yaw_rate_noise_radps.powi(2),
        );
        let z = wrap_angle(attitude.yaw_rad + offset_rad);
        let mut h = RowVector6::zeros();
        h[PSI] = 1.0;
        let mut i_kh = self.update1(&h, wrap_angle(z - self.s[PSI]), heading_var);
        if let Some(w) = attitude.yaw_rate_radps {
            let mut h = RowVector6::zeros();
            h[R] = 1.0;
            i_kh = self.update1(&h, w - self.s[R], yaw_rate_var) * i_kh;
        }
        i_kh
    }

    pub(super) fn step(&self, transition: Matrix6<f64>) -> NavigationStep {
        NavigationStep {
            stamp_s: self.stamp_s,
            world_from_vehicle: Se2::new(self.s[X], self.s[Y], self.s[PSI]),
            velocity_mps: Vector2::new(self.s[U], self.s[V]),
            yaw_rate_radps: self.s[R],
            state_covariance: self.p,
            state_transition: transition,
        }
    }
}
