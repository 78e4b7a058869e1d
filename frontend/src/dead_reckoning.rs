//! Dead reckoning: an EKF over the planar vehicle pose and body velocities
//! that fuses DVL velocities, MRU heading and yaw rate, and the resulting
//! "transformations history" ([`Navigation`]) that every later stage
//! queries at beam times (paper section 3, Fig. 2).
//!
//! # Filter
//! The constant-velocity model of Ribas et al. (the seed paper's reference
//! \[10\]; equations in `dead_reckoning/model.rs`). State `(x, y, ψ, u, v, r)`:
//! `world_from_vehicle` in a local world frame whose origin is the vehicle
//! position when the filter starts and whose orientation is that of the
//! heading measurements, and the body velocities of the vehicle origin
//! (surge, sway, yaw rate). It never reads ground truth.
//!
//! - **Prediction** (to every record's stamp): the body velocities are
//!   constant and the pose moves along them at the mid-step heading.
//!   Process noise: white accelerations, surge and sway with density
//!   `velocity_random_walk_mps_per_sqrt_s²` (the velocity performs a random
//!   walk of that intensity), yaw with `yaw_rate_random_walk_radps_per_sqrt_s²`,
//!   plus an optional white heading noise `heading_random_walk_rad_per_sqrt_s²`.
//!   A real AUV's velocity changes slowly, so each DVL sample's noise (0.1-
//!   0.15 m/s) is averaged over many samples instead of being integrated
//!   sample by sample into the trajectory.
//! - **DVL update** (every valid sample): the horizontal velocity in the
//!   instrument frame, `v_dvl = R_dvlᵀ ((u, v) + r × ℓ)` with `R_dvl`, `ℓ`
//!   the rotation and lever arm of `vehicle_from_dvl` (the lever-arm term
//!   only with `lever_arm_compensation`), noise from the sample's
//!   covariance or `dvl_velocity_noise_mps`. Linear in the state.
//!   Innovation gating: a sample with `νᵀ S⁻¹ ν > dvl_gate_chi2` (`ν` the
//!   innovation, `S = H P Hᵀ + R` its predicted covariance, a χ² test with
//!   2 degrees of freedom) is an outlier (lost bottom lock, fish, the
//!   wall) and not used; after `dvl_gate_max_consecutive` rejections in a
//!   row the next sample is used regardless. Without the gate a single
//!   0.7 m/s outlier of the real St Pere DVL moves the pose by decimetres
//!   while the covariance claims it cannot.
//!   Noise adaptation (covariance matching): the DVL noise per axis is
//!   re-estimated from the recent innovations (`dvl_noise_adaptation_samples`)
//!   and used when larger than the configured `dvl_velocity_noise_mps`,
//!   so a stretch where the instrument is noisier (the end of the St Pere
//!   mission: 0.3-0.4 m/s instead of 0.1-0.15) gets wider covariances
//!   rather than confidently wrong odometry.
//! - **Attitude update** (every sample): the heading `yaw +
//!   heading_offset_rad` as a direct measurement of ψ with standard
//!   deviation `heading_noise_rad` (wrapped innovation), and the yaw rate,
//!   when the unit gives one, as a measurement of `r` with
//!   `yaw_rate_noise_radps`. Without yaw rates `r` is estimated from the
//!   headings. Joseph-form covariance updates.
//! - **Yaw-rate check** (`yaw_rate_check_window_s`, before filtering): the
//!   integrated yaw rates are compared with the heading changes; when they
//!   disagree more than the configured noises allow (a biased or
//!   mis-scaled gyro), the yaw-rate noise is raised to what explains the
//!   disagreement ([`gyro_check`]; [`Navigation::yaw_rate_noise_radps`]
//!   gives the noise used).
//! - **Smoothing** (`smoothing`, on by default): a Rauch-Tung-Striebel pass
//!   backwards over the filtered steps, so the pose at a beam time uses the
//!   records after it too (`dead_reckoning/smoother.rs`). Motion compensation is then
//!   limited by the velocity averaged over both sides of each beam, not
//!   over its past only. Turn it off for a causal (online) estimate.
//!
//! The model is planar: the DVL's vertical velocity and the attitude's roll
//! and pitch are not used (the horizontal DVL velocity is taken as the
//! velocity over ground in the horizontal plane).
//!
//! # Records
//! DVL samples flagged invalid are skipped whatever their content. The
//! filter starts at the first time at which both a valid DVL sample and an
//! attitude sample exist, with the body velocity solved from that DVL
//! sample; earlier records only initialise it. Non-finite stamps or used
//! values, and stamps that decrease within a stream, are errors naming the
//! record. A gap between valid DVL samples longer than `max_dvl_gap_s` is
//! logged with `tracing::warn!` and listed in [`Navigation::dvl_gaps`]; the
//! filter predicts through it with the estimated velocity, its covariance
//! growing with the process noise.
//!
//! # Example
//! ```
//! use echofield_frontend::dead_reckoning::{self, DeadReckoningConfig};
//! use echofield_frontend::dead_reckoning::synthetic::{SyntheticNavConfig, SyntheticPath, synthetic_mission};
//!
//! let path = SyntheticPath::Straight { speed_mps: 0.5, heading_rad: 0.3 };
//! let mission = synthetic_mission(&path, &SyntheticNavConfig::default(), 1);
//! let nav = dead_reckoning::run(&mission, &DeadReckoningConfig::default()).unwrap();
//! let pose = nav.pose_at(mission.dvl[20].stamp_s).unwrap();
//! assert!((pose.theta() - 0.3).abs() < 0.05);
//! ```

mod ekf;
mod forward;
pub mod gyro_check;
mod model;
mod navigation;
mod smoother;
pub mod synthetic;

pub use forward::ForwardFilter;
pub use navigation::{DvlGap, HeadingBias, Navigation, NavigationStep};

use crate::error::FrontendError;
use crate::screening;
use crate::sensors::Mission;
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};

/// Noise parameters and options of the dead-reckoning EKF.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DeadReckoningConfig {
    /// Standard deviation of one DVL sample's horizontal velocity, per axis,
    /// in m/s. Used for samples without a covariance (or all samples when
    /// `use_dvl_covariance` is false). Default 0.14 (the St Pere DVL).
    pub dvl_velocity_noise_mps: f64,
    /// Innovation gate of the DVL update: a valid sample whose innovation's
    /// squared Mahalanobis distance `νᵀ (H P Hᵀ + R)⁻¹ ν` exceeds this is
    /// not used (bottom-lock outliers: the real St Pere DVL has isolated
    /// 0.5-0.7 m/s errors). A χ² quantile with 2 degrees of freedom;
    /// default 20 (p = 4.5e-5: about 4.5 standard deviations, only gross
    /// errors). The tighter 13.82 (p = 0.001) also rejects the heavy tail of
    /// good samples when the vehicle manoeuvres against the constant-velocity
    /// model (measured: EXPERIMENTS.md § Dead reckoning). 0 turns the
    /// gate off.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): a test level (χ² with 2 degrees of freedom) against gross bottom-lock errors, not a property of a vehicle.
    #[serde(skip)]
    pub dvl_gate_chi2: f64,
    /// After this many consecutive gated-out samples the next one is used
    /// whatever its innovation, so that a real change of velocity the
    /// model did not expect cannot lock the filter out. Default 3.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): a safeguard of the gate against locking the filter out, not a property of a vehicle.
    #[serde(skip)]
    pub dvl_gate_max_consecutive: usize,
    /// Innovation-based adaptation of the DVL noise: the noise per axis is
    /// estimated from the innovations over about this many samples, and
    /// used when larger than the configured one (which stays a floor).
    /// 0 turns it off. Default 30 (about 20 s of the St Pere DVL).
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): the adaptation's memory; the noise a user sets is `dvl_velocity_noise_mps`, which stays the floor.
    #[serde(skip)]
    pub dvl_noise_adaptation_samples: usize,
    /// Use the covariance a DVL sample carries (its x-y block, in (m/s)²)
    /// instead of `dvl_velocity_noise_mps`. Default true.
    pub use_dvl_covariance: bool,
    /// Surge and sway acceleration noise of the constant-velocity model:
    /// the square root of the white acceleration's spectral density, per
    /// body axis, in m/s² per √Hz (= m/s per √s: over `t` seconds the true
    /// velocity wanders by about `value · √t`). Small values trust the
    /// velocity to stay constant and average more DVL samples; large ones
    /// follow each sample. Default 0.03 (about 0.1 m/s in 10 s): smaller values
    /// lag the real St Pere vehicle's manoeuvres, larger ones distort rotations
    /// more on simulated missions (measured: EXPERIMENTS.md § Dead reckoning).
    pub velocity_random_walk_mps_per_sqrt_s: f64,
    /// Standard deviation of one heading measurement, rad. Default 0.02.
    pub heading_noise_rad: f64,
    /// Standard deviation of one yaw-rate sample, rad/s. Default 0.01. A
    /// floor of the noise the yaw-rate check (`yaw_rate_check_window_s`)
    /// estimates from the data.
    pub yaw_rate_noise_radps: f64,
    /// Window of the yaw-rate check, s: before filtering, the integrated
    /// yaw rates are compared with the heading changes over consecutive
    /// windows this long, and the filter uses the yaw-rate noise that
    /// explains their disagreement (a lower confidence bound) when it
    /// exceeds `yaw_rate_noise_radps` (method in
    /// `dead_reckoning/gyro_check.rs`). A gyro with a bias or a scale error
    /// then no longer drags the heading away from the headings in turns
    /// (the real St Pere MTi is such a unit: README.md § Accuracy). 0 turns the
    /// check off. Default 1.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): the check estimates the gyro's noise from the data; the noise a user sets is `yaw_rate_noise_radps`, which stays the floor.
    #[serde(skip)]
    pub yaw_rate_check_window_s: f64,
    /// Yaw acceleration noise of the model: the square root of the white
    /// yaw acceleration's spectral density, rad/s² per √Hz (= rad/s per
    /// √s). Default 0.02.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): a model constant of the filter, bounded by the heading measurements at their rate.
    #[serde(skip)]
    pub yaw_rate_random_walk_radps_per_sqrt_s: f64,
    /// White noise on the heading besides the yaw-rate model (unmodelled
    /// yaw disturbances), rad per √s. Default 0.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): 0: the slowly wandering heading error is modelled by `heading_bias_sigma_rad` and `heading_bias_time_constant_s`.
    #[serde(skip)]
    pub heading_random_walk_rad_per_sqrt_s: f64,
    /// Standard deviation of the heading unit's slowly wandering error
    /// (magnetic disturbances near walls and hulls, soft-iron effects), rad:
    /// a Gauss-Markov process that the filter does not estimate, so that
    /// [`Navigation::relative`] adds the variance of its change over the
    /// interval to the relative heading. Default 2° (the dynamic heading
    /// accuracy an Xsens MTi specifies); 0 trusts the heading changes as
    /// much as the white `heading_noise_rad` allows.
    pub heading_bias_sigma_rad: f64,
    /// Correlation time of that error, s. Default 120 s (the time an AUV
    /// at 0.4 m/s takes to pass a 50 m pier or hull).
    pub heading_bias_time_constant_s: f64,
    /// Added to every MRU yaw before use: magnetic declination plus the
    /// mounting misalignment of the attitude unit, rad. Default 0.
    pub heading_offset_rad: f64,
    /// Model the DVL's lever arm (`vehicle_from_dvl` translation): the
    /// instrument measures `(u, v) + r × ℓ`. Default true.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): the lever arm is the mounting's
    /// (`[mounting]`); a DVL at the vehicle's origin has none to compensate.
    #[serde(skip)]
    pub lever_arm_compensation: bool,
    /// Smooth the filtered trajectory with a backward (Rauch-Tung-Striebel)
    /// pass, so every pose uses the records before and after it; false
    /// gives the causal filter. Default true.
    pub smoothing: bool,
    /// A gap between valid DVL samples longer than this (s) is logged and
    /// listed in `Navigation::dvl_gaps`. Default 5.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): it only decides which gaps are logged and listed.
    #[serde(skip)]
    pub max_dvl_gap_s: f64,
    /// How far (s) a pose may be extrapolated before the first or after the
    /// last filter step; beyond that, queries return
    /// `FrontendError::OutsideNavigation`. Default 2.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): a bound on queries before the first and after the last sample, not on the estimate.
    #[serde(skip)]
    pub max_extrapolation_s: f64,
}

impl Default for DeadReckoningConfig {
    fn default() -> Self {
        Self {
            dvl_velocity_noise_mps: 0.14,
            dvl_gate_chi2: 20.0,
            dvl_gate_max_consecutive: 3,
            dvl_noise_adaptation_samples: 30,
            use_dvl_covariance: true,
            velocity_random_walk_mps_per_sqrt_s: 0.03,
            heading_noise_rad: 0.02,
            yaw_rate_noise_radps: 0.01,
            yaw_rate_check_window_s: 1.0,
            yaw_rate_random_walk_radps_per_sqrt_s: 0.02,
            heading_random_walk_rad_per_sqrt_s: 0.0,
            heading_bias_sigma_rad: 2f64.to_radians(),
            heading_bias_time_constant_s: 120.0,
            heading_offset_rad: 0.0,
            lever_arm_compensation: true,
            smoothing: true,
            max_dvl_gap_s: 5.0,
            max_extrapolation_s: 2.0,
        }
    }
}

impl DeadReckoningConfig {
    /// Every value in range; the error names the first field out of it.
    pub fn validate(&self) -> Result<(), FrontendError> {
        self.check_signs()?;
        self.check_upper_bounds()
    }

    /// Noises, times and gates finite and positive or non-negative; the
    /// heading offset within ±2π.
    fn check_signs(&self) -> Result<(), FrontendError> {
        let positive = [
            ("dvl_velocity_noise_mps", self.dvl_velocity_noise_mps),
            ("heading_noise_rad", self.heading_noise_rad),
            (
                "heading_bias_time_constant_s",
                self.heading_bias_time_constant_s,
            ),
            ("max_dvl_gap_s", self.max_dvl_gap_s),
        ];
        for (field, value) in positive {
            crate::config_check::check_positive(field, value)?;
        }
        let non_negative = [
            (
                "velocity_random_walk_mps_per_sqrt_s",
                self.velocity_random_walk_mps_per_sqrt_s,
            ),
            ("yaw_rate_noise_radps", self.yaw_rate_noise_radps),
            ("yaw_rate_check_window_s", self.yaw_rate_check_window_s),
            (
                "yaw_rate_random_walk_radps_per_sqrt_s",
                self.yaw_rate_random_walk_radps_per_sqrt_s,
            ),
            (
                "heading_random_walk_rad_per_sqrt_s",
                self.heading_random_walk_rad_per_sqrt_s,
            ),
            ("heading_bias_sigma_rad", self.heading_bias_sigma_rad),
            ("max_extrapolation_s", self.max_extrapolation_s),
            ("dvl_gate_chi2", self.dvl_gate_chi2),
        ];
        for (field, value) in non_negative {
            if !(value.is_finite() && value >= 0.0) {
                return Err(FrontendError::config(
                    field,
                    format!("must be finite and >= 0, got {value}"),
                ));
            }
        }
        if !(self.heading_offset_rad.is_finite() && self.heading_offset_rad.abs() <= TAU) {
            return Err(FrontendError::config(
                "heading_offset_rad",
                format!(
                    "must be finite and within ±2π, got {}",
                    self.heading_offset_rad
                ),
            ));
        }
        Ok(())
    }

    /// No noise beyond what the quantity can be: beyond these bounds the
    /// covariances overflow the filter's arithmetic (the motion
    /// compensation then spreads the beams over absurd distances, and the
    /// odometry's information matrix can turn indefinite).
    fn check_upper_bounds(&self) -> Result<(), FrontendError> {
        let upper = [
            (
                "dvl_velocity_noise_mps",
                self.dvl_velocity_noise_mps,
                screening::MAX_DVL_SPEED_MPS,
            ),
            ("heading_noise_rad", self.heading_noise_rad, PI),
            ("heading_bias_sigma_rad", self.heading_bias_sigma_rad, PI),
            (
                "yaw_rate_noise_radps",
                self.yaw_rate_noise_radps,
                screening::MAX_YAW_RATE_RADPS,
            ),
        ];
        for (field, value, max) in upper {
            if value > max {
                return Err(FrontendError::config(
                    field,
                    format!("must be at most {max}, got {value}"),
                ));
            }
        }
        Ok(())
    }

    /// The model's process noise densities.
    pub(crate) fn process_noise(&self) -> model::ProcessNoise {
        model::ProcessNoise {
            acceleration: self.velocity_random_walk_mps_per_sqrt_s.powi(2),
            yaw_acceleration: self.yaw_rate_random_walk_radps_per_sqrt_s.powi(2),
            heading: self.heading_random_walk_rad_per_sqrt_s.powi(2),
        }
    }
}

/// Runs the EKF over the mission's DVL and attitude records and returns the
/// navigation history. Never reads `mission.ground_truth`. The heading
/// offset used is `config.heading_offset_rad` plus the mission's
/// `mounting.heading_offset_rad`.
///
/// Errors: invalid config; no valid DVL sample; no attitude sample; a
/// non-finite stamp, velocity, covariance, yaw or yaw rate; a stamp earlier
/// than the previous one in the same stream.
pub fn run(mission: &Mission, config: &DeadReckoningConfig) -> Result<Navigation, FrontendError> {
    config.validate()?;
    let offset = mission.mounting.heading_offset_rad;
    if !offset.is_finite() {
        return Err(FrontendError::input(
            "mounting",
            "heading_offset_rad",
            format!("{offset} is not finite"),
        ));
    }
    let mut config = DeadReckoningConfig {
        heading_offset_rad: config.heading_offset_rad + offset,
        ..config.clone()
    };
    ekf::check_records(mission, &config)?;
    let yaw_rate_check = (config.yaw_rate_check_window_s > 0.0)
        .then(|| gyro_check::check(&mission.attitude, config.yaw_rate_check_window_s))
        .flatten();
    if let Some(c) = &yaw_rate_check
        && c.yaw_rate_noise_radps > config.yaw_rate_noise_radps
    {
        tracing::info!(
            configured_radps = config.yaw_rate_noise_radps,
            measured_radps = c.yaw_rate_noise_radps,
            disagreement_deg = c.disagreement_rad.to_degrees(),
            "the yaw rates disagree with the headings more than their configured noise allows; using the measured noise"
        );
        config.yaw_rate_noise_radps = c.yaw_rate_noise_radps;
    }
    let mut filter = ForwardFilter::new(&config, &mission.mounting, config.smoothing)?;
    filter.set_yaw_rate_noise(config.yaw_rate_noise_radps, yaw_rate_check);
    for record in merged_records(mission) {
        match record {
            Record::Dvl(s) => filter.push_dvl(s)?,
            Record::Attitude(a) => filter.push_attitude(a)?,
        }
    }
    filter.finish(config.smoothing)
}

/// One navigation record of a mission.
pub enum Record<'a> {
    Dvl(&'a crate::sensors::DvlVelocity),
    Attitude(&'a crate::sensors::Attitude),
}

impl Record<'_> {
    /// The record's stamp, s.
    pub fn stamp_s(&self) -> f64 {
        match self {
            Record::Dvl(s) => s.stamp_s,
            Record::Attitude(a) => a.stamp_s,
        }
    }
}

/// The DVL samples (valid or not) and attitude samples of `mission` merged
/// in time order; at equal stamps DVL comes first (each stream is assumed
/// in order, as [`run`] checks).
pub fn merged_records(mission: &Mission) -> impl Iterator<Item = Record<'_>> {
    let (mut dvl, mut attitude) = (
        mission.dvl.iter().peekable(),
        mission.attitude.iter().peekable(),
    );
    std::iter::from_fn(move || match (dvl.peek(), attitude.peek()) {
        (Some(d), Some(a)) if d.stamp_s <= a.stamp_s => dvl.next().map(Record::Dvl),
        (Some(_), Some(_)) | (None, Some(_)) => attitude.next().map(Record::Attitude),
        (Some(_), None) => dvl.next().map(Record::Dvl),
        (None, None) => None,
    })
}

#[cfg(test)]
mod tests;
