//! The causal dead-reckoning filter: DVL and attitude samples pushed one at
//! a time in time order, the navigation history growing with each, and
//! queryable at any time up to the latest sample (plus the extrapolation the
//! config allows). [`super::run`] pushes a whole mission through it; an
//! online engine pushes samples as they arrive.

use super::DeadReckoningConfig;
use super::ekf::{Ekf, check_attitude, check_dvl};
use super::gyro_check::YawRateCheck;
use super::navigation::{DvlGap, HeadingBias, Navigation};
use super::smoother::{self, Prediction};
use crate::error::FrontendError;
use crate::sensors::{Attitude, DvlVelocity, SensorMounting};
use nalgebra::Matrix6;

/// The forward (causal) EKF of [`super`] as a stream consumer.
///
/// Contract: samples of each stream come in non-decreasing stamp order
/// (else the push is an error naming the record). A sample earlier than
/// the latest sample of the other stream cannot be filtered without
/// rewinding: it is skipped and counted ([`ForwardFilter::late_samples`]).
/// Nothing is estimated before the first time both a valid DVL sample and an
/// attitude sample exist; [`ForwardFilter::navigation`] is `None` until
/// then.
pub struct ForwardFilter {
    config: DeadReckoningConfig,
    ekf: Ekf,
    navigation: Option<Navigation>,
    /// Predictions kept for the smoother (only when `keep_predictions`).
    predictions: Option<Vec<Prediction>>,
    last_dvl: Option<DvlVelocity>,
    last_attitude: Option<Attitude>,
    /// Stamp of the last valid DVL sample used, s.
    last_dvl_used_s: f64,
    closed_gaps: Vec<DvlGap>,
    /// Consecutive samples the gate rejected: after
    /// `dvl_gate_max_consecutive` of them the next one is used whatever its
    /// innovation, so a real change of velocity is not locked out.
    gated_in_row: usize,
    gated: usize,
    dvl_count: usize,
    attitude_count: usize,
    last_dvl_stamp_s: f64,
    last_attitude_stamp_s: f64,
    late: usize,
    yaw_rate_check: Option<YawRateCheck>,
}

impl ForwardFilter {
    /// A filter with `config` (validated; its `heading_offset_rad` is used as
    /// given: add the mounting's offset before) for a vehicle with
    /// `mounting`'s DVL. `keep_predictions` keeps what
    /// [`ForwardFilter::finish`] needs to smooth.
    pub fn new(
        config: &DeadReckoningConfig,
        mounting: &SensorMounting,
        keep_predictions: bool,
    ) -> Result<Self, FrontendError> {
        config.validate()?;
        Ok(Self {
            config: config.clone(),
            ekf: Ekf::new(config, mounting),
            navigation: None,
            predictions: keep_predictions.then(Vec::new),
            last_dvl: None,
            last_attitude: None,
            last_dvl_used_s: f64::NAN,
            closed_gaps: Vec::new(),
            gated_in_row: 0,
            gated: 0,
            dvl_count: 0,
            attitude_count: 0,
            last_dvl_stamp_s: f64::NEG_INFINITY,
            last_attitude_stamp_s: f64::NEG_INFINITY,
            late: 0,
            yaw_rate_check: None,
        })
    }

    /// The history so far, `None` before the filter started.
    pub fn navigation(&self) -> Option<&Navigation> {
        self.navigation.as_ref()
    }

    /// Stamp of the latest sample filtered, s (`-inf` before any).
    pub fn latest_s(&self) -> f64 {
        if self.navigation.is_some() {
            self.ekf.stamp_s
        } else {
            f64::NEG_INFINITY
        }
    }

    /// Samples skipped because they were earlier than a sample of the other
    /// stream already filtered.
    pub fn late_samples(&self) -> usize {
        self.late
    }

    /// The yaw-rate noise used from now on, rad/s, and the yaw-rate check
    /// that set it (reported by the finished navigation).
    pub fn set_yaw_rate_noise(&mut self, noise_radps: f64, check: Option<YawRateCheck>) {
        self.config.yaw_rate_noise_radps = noise_radps;
        self.ekf.set_yaw_rate_noise(noise_radps);
        self.yaw_rate_check = check;
    }

    /// The yaw-rate noise in use, rad/s.
    pub fn yaw_rate_noise_radps(&self) -> f64 {
        self.config.yaw_rate_noise_radps
    }

    /// Filters one DVL sample. Errors: a non-finite or implausible value, a
    /// stamp earlier than the previous DVL sample's (naming `DVL sample i`,
    /// `i` counting every DVL sample pushed).
    pub fn push_dvl(&mut self, sample: &DvlVelocity) -> Result<(), FrontendError> {
        let i = self.dvl_count;
        check_dvl(i, sample, self.last_dvl_stamp_s, &self.config)?;
        self.dvl_count += 1;
        self.last_dvl_stamp_s = sample.stamp_s;
        if !sample.valid || self.is_late(sample.stamp_s, || format!("DVL sample {i}")) {
            return Ok(());
        }
        if self.navigation.is_none() {
            self.last_dvl = Some(sample.clone());
            self.try_start(sample.stamp_s);
            return Ok(());
        }
        let prediction = self.ekf.predict(sample.stamp_s);
        let f = prediction.jacobian;
        if sample.stamp_s - self.last_dvl_used_s > self.config.max_dvl_gap_s {
            record_gap(&mut self.closed_gaps, self.last_dvl_used_s, sample.stamp_s);
        }
        let gate = self.gated_in_row < self.config.dvl_gate_max_consecutive;
        let transition = match self.ekf.update_dvl(sample, gate) {
            Some(i_kh) => {
                self.last_dvl_used_s = sample.stamp_s;
                self.gated_in_row = 0;
                i_kh * f
            }
            None => {
                self.gated_in_row += 1;
                self.gated += 1;
                f
            }
        };
        self.record(prediction, transition);
        Ok(())
    }

    /// Filters one attitude sample; errors like [`ForwardFilter::push_dvl`]
    /// (`attitude sample i`).
    pub fn push_attitude(&mut self, sample: &Attitude) -> Result<(), FrontendError> {
        let i = self.attitude_count;
        check_attitude(i, sample, self.last_attitude_stamp_s)?;
        self.attitude_count += 1;
        self.last_attitude_stamp_s = sample.stamp_s;
        if self.is_late(sample.stamp_s, || format!("attitude sample {i}")) {
            return Ok(());
        }
        if self.navigation.is_none() {
            self.last_attitude = Some(sample.clone());
            self.try_start(sample.stamp_s);
            return Ok(());
        }
        let prediction = self.ekf.predict(sample.stamp_s);
        let f = prediction.jacobian;
        let transition = self.ekf.update_attitude(sample) * f;
        self.record(prediction, transition);
        Ok(())
    }

    /// A sample earlier than the filter's time: counted, logged once.
    fn is_late(&mut self, stamp_s: f64, record: impl Fn() -> String) -> bool {
        if self.navigation.is_none() || stamp_s >= self.ekf.stamp_s {
            return false;
        }
        if self.late == 0 {
            tracing::warn!(
                record = record(),
                stamp_s,
                filter_s = self.ekf.stamp_s,
                "a navigation sample is earlier than one already filtered; skipped (later ones are counted)"
            );
        }
        self.late += 1;
        true
    }

    /// Starts at the first time both a velocity and a heading exist.
    fn try_start(&mut self, stamp_s: f64) {
        let (Some(dvl), Some(attitude)) = (&self.last_dvl, &self.last_attitude) else {
            return;
        };
        self.ekf.initialise(stamp_s, dvl, attitude);
        self.last_dvl_used_s = dvl.stamp_s;
        let mut navigation = Navigation::from_steps(
            vec![self.ekf.step(Matrix6::identity())],
            Vec::new(),
            self.config.max_extrapolation_s,
            self.ekf.noise,
            false,
        );
        navigation.set_heading_bias(HeadingBias {
            sigma_rad: self.config.heading_bias_sigma_rad,
            time_constant_s: self.config.heading_bias_time_constant_s,
        });
        self.navigation = Some(navigation);
    }

    fn record(&mut self, prediction: Prediction, transition: Matrix6<f64>) {
        if let Some(predictions) = &mut self.predictions {
            predictions.push(prediction);
        }
        let gaps = self.gaps();
        if let Some(navigation) = &mut self.navigation {
            navigation.push_step(self.ekf.step(transition));
            navigation.set_dvl_gated(self.gated);
            navigation.set_dvl_gaps(gaps);
        }
    }

    /// The closed gaps and, when the latest sample is more than
    /// `max_dvl_gap_s` after the last DVL sample used, the open one.
    fn gaps(&self) -> Vec<DvlGap> {
        let mut gaps = self.closed_gaps.clone();
        if self.ekf.stamp_s - self.last_dvl_used_s > self.config.max_dvl_gap_s {
            gaps.push(DvlGap {
                start_s: self.last_dvl_used_s,
                end_s: self.ekf.stamp_s,
            });
        }
        gaps
    }

    /// The history, smoothed when `smoothing` and the predictions were
    /// kept. Errors when the filter never started (no valid DVL sample or
    /// no attitude sample).
    pub fn finish(mut self, smoothing: bool) -> Result<Navigation, FrontendError> {
        if self.ekf.stamp_s - self.last_dvl_used_s > self.config.max_dvl_gap_s {
            warn_gap(self.last_dvl_used_s, self.ekf.stamp_s);
        }
        let Some(mut navigation) = self.navigation.take() else {
            return Err(FrontendError::insufficient(
                "dead reckoning",
                "no time with both a valid DVL sample and an attitude sample",
            ));
        };
        if self.gated > 0 {
            tracing::debug!(
                gated = self.gated,
                "DVL samples rejected by the innovation gate"
            );
        }
        if smoothing
            && let Some(predictions) = &self.predictions
            && navigation.steps().len() > 1
        {
            let gaps = navigation.dvl_gaps().to_vec();
            let mut steps = navigation.into_steps();
            smoother::smooth(&mut steps, predictions);
            let mut smoothed = Navigation::from_steps(
                steps,
                gaps,
                self.config.max_extrapolation_s,
                self.ekf.noise,
                true,
            );
            smoothed.set_dvl_gated(self.gated);
            smoothed.set_heading_bias(HeadingBias {
                sigma_rad: self.config.heading_bias_sigma_rad,
                time_constant_s: self.config.heading_bias_time_constant_s,
            });
            navigation = smoothed;
        }
        navigation.set_yaw_rate_noise(self.config.yaw_rate_noise_radps, self.yaw_rate_check);
        navigation.shrink_to_fit();
        Ok(navigation)
    }
}

fn record_gap(gaps: &mut Vec<DvlGap>, start_s: f64, end_s: f64) {
    warn_gap(start_s, end_s);
    gaps.push(DvlGap { start_s, end_s });
}

fn warn_gap(start_s: f64, end_s: f64) {
    tracing::warn!(
        start_s,
        end_s,
        "no valid DVL sample for {:.1} s; predicting with the estimated velocity",
        end_s - start_s
    );
}
