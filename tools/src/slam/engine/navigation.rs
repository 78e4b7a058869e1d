//! Where the engine's navigation comes from: the causal filter fed sample
//! by sample (online), or a navigation computed beforehand over the whole
//! mission (the batch run's smoothed dead reckoning).

use crate::slam::SlamError;
use echofield_frontend::dead_reckoning::gyro_check;
use echofield_frontend::dead_reckoning::{DeadReckoningConfig, ForwardFilter, Navigation};
use echofield_frontend::sensors::{Attitude, DvlVelocity, SensorMounting};

/// Span of attitude samples, s, over which the causal navigation runs the
/// yaw-rate check (`dead_reckoning.yaw_rate_check_window_s`) before raising
/// the yaw-rate noise of the samples after it: long enough for tens of
/// check windows, short enough to react within a few rotations.
const YAW_RATE_CHECK_SPAN_S: f64 = 60.0;

/// The navigation of a [`super::SlamEngine`].
pub(super) enum NavigationSource {
    /// The forward filter over the samples pushed so far.
    Causal(Box<CausalNavigation>),
    /// A navigation given whole (look-ahead: smoothed, or checked over the
    /// whole mission); pushed samples are ignored.
    Given(Navigation),
}

/// The forward filter and the causal yaw-rate check.
pub(super) struct CausalNavigation {
    filter: ForwardFilter,
    window_s: f64,
    /// Attitude samples since the last check.
    attitude: Vec<Attitude>,
}

impl NavigationSource {
    /// The causal filter. Its heading offset is the config's plus the
    /// mounting's. Errors: invalid config, non-finite mounting offset.
    pub(super) fn causal(
        config: &DeadReckoningConfig,
        mounting: &SensorMounting,
    ) -> Result<Self, SlamError> {
        let offset = mounting.heading_offset_rad;
        if !offset.is_finite() {
            return Err(SlamError::config(
                "mounting.heading_offset_deg",
                format!("{offset} rad is not finite"),
            ));
        }
        let config = DeadReckoningConfig {
            heading_offset_rad: config.heading_offset_rad + offset,
            ..config.clone()
        };
        let filter = ForwardFilter::new(&config, mounting, false)
            .map_err(|e| SlamError::frontend("dead reckoning", e))?;
        Ok(Self::Causal(Box::new(CausalNavigation {
            filter,
            window_s: config.yaw_rate_check_window_s,
            attitude: Vec::new(),
        })))
    }

    /// The navigation so far (`None` before the filter started).
    pub(super) fn current(&self) -> Option<&Navigation> {
        match self {
            Self::Causal(c) => c.filter.navigation(),
            Self::Given(n) => Some(n),
        }
    }

    /// Stamp up to which the navigation is final, s: the latest sample
    /// filtered, or `+inf` for a given navigation.
    pub(super) fn covered_until_s(&self) -> f64 {
        match self {
            Self::Causal(c) => c.filter.latest_s(),
            Self::Given(_) => f64::INFINITY,
        }
    }

    pub(super) fn push_dvl(&mut self, sample: &DvlVelocity) -> Result<(), SlamError> {
        if let Self::Causal(c) = self {
            c.filter
                .push_dvl(sample)
                .map_err(|e| SlamError::frontend("dead reckoning", e))?;
        }
        Ok(())
    }

    pub(super) fn push_attitude(&mut self, sample: &Attitude) -> Result<(), SlamError> {
        if let Self::Causal(c) = self {
            c.filter
                .push_attitude(sample)
                .map_err(|e| SlamError::frontend("dead reckoning", e))?;
            c.check_yaw_rates(sample);
        }
        Ok(())
    }

    /// Samples the causal filter skipped as late (0 for a given navigation).
    pub(super) fn late_samples(&self) -> usize {
        match self {
            Self::Causal(c) => c.filter.late_samples(),
            Self::Given(_) => 0,
        }
    }

    /// The whole navigation, with the yaw-rate noise it ended with. Errors
    /// when the causal filter never started.
    pub(super) fn finish(self) -> Result<Navigation, SlamError> {
        match self {
            Self::Given(n) => Ok(n),
            Self::Causal(c) => c
                .filter
                .finish(false)
                .map_err(|e| SlamError::frontend("dead reckoning", e)),
        }
    }
}

impl CausalNavigation {
    /// Collects `sample`; once the samples span [`YAW_RATE_CHECK_SPAN_S`],
    /// runs the yaw-rate check over them and raises the filter's yaw-rate
    /// noise (never lowers it) to what the check measured.
    fn check_yaw_rates(&mut self, sample: &Attitude) {
        if self.window_s <= 0.0 {
            return;
        }
        self.attitude.push(sample.clone());
        let span_s = sample.stamp_s - self.attitude[0].stamp_s;
        if span_s < YAW_RATE_CHECK_SPAN_S {
            return;
        }
        let samples = std::mem::take(&mut self.attitude);
        let Some(check) = gyro_check::check(&samples, self.window_s) else {
            return;
        };
        if check.yaw_rate_noise_radps > self.filter.yaw_rate_noise_radps() {
            tracing::info!(
                measured_radps = check.yaw_rate_noise_radps,
                at_s = sample.stamp_s,
                "the yaw rates disagree with the headings; raising the yaw-rate noise from here on"
            );
            self.filter
                .set_yaw_rate_noise(check.yaw_rate_noise_radps, Some(check));
        }
    }
}
