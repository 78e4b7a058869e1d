//! What [`super::calibrate`] found: every combination of the discrete
//! choices, each estimate with its uncertainty or the reason it cannot be
//! determined, and the mounting that results.

use super::uncertainty::Vote;
use crate::mounting::MountingConfig;
use crate::sensors::{AngleDirection, SensorMounting, SweepTiming};
use serde::Serialize;

/// Why the heading calibration is never estimated (module doc of
/// [`super`]).
pub const HEADING_OFFSET_REASON: &str = "cannot be determined from this mission: a constant \
     heading offset turns the whole map rigidly; it needs an absolute reference such as GPS";

/// One combination of the discrete choices at its best yaw (the lever arm
/// at the mission's value).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Combination {
    pub sonar_angle: AngleDirection,
    pub sweep: SweepTiming,
    /// The best yaw of the head, radians in (−π, π].
    pub yaw_rad: f64,
    /// The objective there, bits (lower is sharper).
    pub mean_entropy_bits: f64,
}

/// A discrete choice: the data's answer, the mission's, and the one kept.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct DiscreteEstimate<T> {
    /// The value of the best combination.
    pub estimate: T,
    /// The mission's value before the calibration.
    pub mission: T,
    /// `estimate` when the vote determines it, else `mission`.
    pub value: T,
    pub vote: Vote,
}

/// A continuous value: the estimate, its uncertainty, and the value kept.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ContinuousEstimate {
    /// What the data gave (the mission's value when nothing was
    /// estimated).
    pub estimate: f64,
    /// Block-jackknife standard deviation of `estimate`; `None` when it
    /// was not estimated.
    pub std: Option<f64>,
    /// The mission's value before the calibration.
    pub mission: f64,
    /// `estimate` when determined, else `mission`.
    pub value: f64,
    pub determined: bool,
    /// The cross-validated vote of the blocks for the estimate against the
    /// mission's value ([`super::head`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub vote: Option<Vote>,
    /// Why the mission's value was kept.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
}

impl ContinuousEstimate {
    /// An estimate, kept unless there is a `rejection` (the reason the
    /// mission's value stays).
    pub fn decided(
        estimate: f64,
        std: f64,
        mission: f64,
        vote: Vote,
        rejection: Option<String>,
    ) -> Self {
        let determined = rejection.is_none();
        Self {
            estimate,
            std: Some(std),
            mission,
            value: if determined { estimate } else { mission },
            determined,
            vote: Some(vote),
            reason: rejection,
        }
    }

    /// A value the data cannot tell, kept from the mission.
    pub fn kept(mission: f64, reason: &str) -> Self {
        Self {
            estimate: mission,
            std: None,
            mission,
            value: mission,
            determined: false,
            vote: None,
            reason: Some(reason.to_string()),
        }
    }
}

/// The size of the problem and of the search.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CalibrationSummary {
    pub rotations: usize,
    pub window_rotations: usize,
    pub windows: usize,
    pub blocks: usize,
    /// Returns placed (those the navigation covers).
    pub returns: usize,
    pub median_range_m: f64,
    pub cell_size_m: f64,
    /// Whether `cell_size_m` was derived from the data (else configured).
    pub cell_size_derived: bool,
    /// Whether the beams' intensities were binary (thresholded point sets,
    /// [`crate::intensity`]), their thin bands widened before the returns
    /// were extracted.
    pub binary_intensities: bool,
    /// Evaluations of the objective over all searches.
    pub evaluations: u64,
}

/// The result of [`super::calibrate`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Calibration {
    pub summary: CalibrationSummary,
    /// Every combination searched, best first.
    pub combinations: Vec<Combination>,
    pub sonar_angle: DiscreteEstimate<AngleDirection>,
    /// `None` for a mission whose beams carry their logged stamps.
    pub sweep: Option<DiscreteEstimate<SweepTiming>>,
    /// The head's yaw, radians in (−π, π].
    pub sonar_yaw_rad: ContinuousEstimate,
    pub sonar_x_m: ContinuousEstimate,
    pub sonar_y_m: ContinuousEstimate,
    /// Never estimated ([`HEADING_OFFSET_REASON`]).
    pub heading_offset_rad: ContinuousEstimate,
    /// The mission's mounting with every kept value.
    pub mounting: SensorMounting,
}

impl Calibration {
    /// The `[mounting]` overrides that give [`Calibration::mounting`]:
    /// every key of the sonar head set (the sweep only for a
    /// reconstruction), and the heading offset.
    pub fn mounting_config(&self) -> MountingConfig {
        MountingConfig {
            sonar_x_m: Some(self.sonar_x_m.value),
            sonar_y_m: Some(self.sonar_y_m.value),
            sonar_yaw_deg: Some(self.sonar_yaw_rad.value.to_degrees()),
            sonar_angle: Some(self.sonar_angle.value),
            sweep: self.sweep.map(|s| s.value),
            heading_offset_deg: Some(self.heading_offset_rad.value.to_degrees()),
            ..MountingConfig::default()
        }
    }
}
