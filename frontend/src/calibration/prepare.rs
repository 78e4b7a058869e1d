//! From a mission to the objectives of the calibration: the beams of every
//! sweep assumption, their returns, the windows and the cell size.

use super::config::{CalibrationConfig, MIN_BLOCKS, derive_cell_size_m};
use super::objective::{Objective, window_stride};
use crate::dead_reckoning::Navigation;
use crate::error::FrontendError;
use crate::image::ImageConfig;
use crate::intensity::{self, IntensityKind};
use crate::mounting::restamp_sweep;
use crate::rotation::{Rotation, RotationConfig, assemble_rotations};
use crate::segmentation::SegmentationConfig;
use crate::sensors::{Mission, SonarBeam, SweepTiming};
use crate::sharpness::{BeamReturn, beam_returns};
use echofield_graph::wrap_angle;

/// The objectives of every sweep assumption, over the same windows.
#[derive(Debug)]
pub struct Prepared {
    /// One per sweep assumption: the mission's own first.
    pub objectives: Vec<(SweepTiming, Objective)>,
    pub rotations: usize,
    pub median_range_m: f64,
    pub cell_size_m: f64,
    pub cell_size_derived: bool,
    pub binary_intensities: bool,
}

/// Builds the objectives (module doc).
///
/// Errors: no beams; no beam with an echo; too few rotations for
/// [`MIN_BLOCKS`] windows; no return the segmentation and the navigation
/// keep; beams marked as a reconstruction that cannot be re-stamped.
pub fn prepare(
    mission: &Mission,
    navigation: &Navigation,
    rotation: &RotationConfig,
    segmentation: &SegmentationConfig,
    config: &CalibrationConfig,
) -> Result<Prepared, FrontendError> {
    let (beams, segmentation, binary_intensities) = scan_beams(mission, segmentation)?;
    let segmentation = &segmentation;
    let rotations = covered_rotations(&beams, navigation, rotation, config)?;
    let sweeps = match mission.mounting.sweep {
        SweepTiming::Logged => vec![SweepTiming::Logged],
        own @ SweepTiming::AngleIncreasing => vec![own, SweepTiming::AngleDecreasing],
        own @ SweepTiming::AngleDecreasing => vec![own, SweepTiming::AngleIncreasing],
    };
    let mut returns = Vec::with_capacity(sweeps.len());
    for &sweep in &sweeps {
        if sweep == mission.mounting.sweep {
            returns.push(beam_returns(&beams, segmentation));
        } else {
            let mut restamped = beams.clone();
            restamp_sweep(&mut restamped)?;
            returns.push(beam_returns(&restamped, segmentation));
        }
    }
    let ranges = returns[0].iter().map(|r| r.range_m).collect();
    let median_range_m = median(ranges).ok_or_else(|| {
        FrontendError::insufficient(
            "returns",
            format!(
                "the segmentation finds no return in {} beams (see [segmentation])",
                beams.len()
            ),
        )
    })?;
    let (cell_size_m, cell_size_derived) = match config.cell_size_m {
        Some(cell) => (cell, false),
        None => (derived_cell(&beams, median_range_m)?, true),
    };
    let objectives: Vec<(SweepTiming, Objective)> = sweeps
        .into_iter()
        .zip(&returns)
        .map(|(sweep, r)| {
            let w = config.window_rotations;
            (
                sweep,
                Objective::new(r, navigation, &rotations, w, cell_size_m),
            )
        })
        .collect();
    check_coverage(&objectives[0].1, &returns[0])?;
    Ok(Prepared {
        objectives,
        rotations: rotations.len(),
        median_range_m,
        cell_size_m,
        cell_size_derived,
        binary_intensities,
    })
}

/// The rotations of `beams` that the navigation covers (the others place
/// no return, and windows over them would be empty); an error when they
/// are too few for [`MIN_BLOCKS`] windows.
fn covered_rotations(
    beams: &[SonarBeam],
    navigation: &Navigation,
    rotation: &RotationConfig,
    config: &CalibrationConfig,
) -> Result<Vec<Rotation>, FrontendError> {
    let all = assemble_rotations(beams, rotation)?;
    let covered: Vec<Rotation> = all
        .iter()
        .filter(|r| r.start_s >= navigation.start_s() && r.end_s <= navigation.end_s())
        .cloned()
        .collect();
    let window = config.window_rotations;
    let needed = window + (MIN_BLOCKS - 1) * window_stride(window);
    if covered.len() < needed {
        return Err(FrontendError::insufficient(
            "windows",
            format!(
                "{} rotations ({} of them within the navigation's time span) give fewer than \
                 {MIN_BLOCKS} windows of {window} rotations; at least {needed} are needed (a \
                 longer mission, or a smaller calibration.window_rotations)",
                all.len(),
                covered.len(),
            ),
        ));
    }
    Ok(covered)
}

/// The mission's beams and the segmentation as the pipeline builds its
/// scans from them ([`intensity::prepare`] with the default image: binary
/// beams get their bands widened and the intensity-comparing stages
/// switched off), and whether the beams were binary.
fn scan_beams(
    mission: &Mission,
    segmentation: &SegmentationConfig,
) -> Result<(Vec<SonarBeam>, SegmentationConfig, bool), FrontendError> {
    if mission.beams.is_empty() {
        return Err(FrontendError::insufficient(
            "beams",
            "the mission has no sonar beams",
        ));
    }
    let mut beams = mission.beams.clone();
    let mut segmentation = segmentation.clone();
    let prepared = intensity::prepare(&mut beams, &mut segmentation, &mut ImageConfig::default());
    match prepared.kind {
        IntensityKind::Empty => Err(FrontendError::insufficient(
            "echoes",
            format!("none of the {} beams holds an echo", beams.len()),
        )),
        IntensityKind::Binary { .. } => Ok((beams, segmentation, true)),
        IntensityKind::Graded => Ok((beams, segmentation, false)),
    }
}

/// [`derive_cell_size_m`] with the median angular step between consecutive
/// beams and the median bin size.
fn derived_cell(beams: &[SonarBeam], median_range_m: f64) -> Result<f64, FrontendError> {
    let steps = beams
        .windows(2)
        .map(|w| wrap_angle(w[1].angle_rad - w[0].angle_rad).abs())
        .filter(|s| *s > 0.0)
        .collect();
    let step = median(steps).unwrap_or(f64::NAN);
    let bin = median(beams.iter().map(|b| b.bin_size_m).collect()).unwrap_or(f64::NAN);
    let cell = derive_cell_size_m(median_range_m, step, bin).ok_or_else(|| {
        FrontendError::insufficient(
            "cell size",
            format!(
                "cannot derive a cell size (median range {median_range_m} m, beam step {step} \
                 rad, bin {bin} m); set calibration.cell_size_m"
            ),
        )
    })?;
    tracing::info!(
        cell_size_m = cell,
        median_range_m,
        beam_step_deg = step.to_degrees(),
        "calibration cell size derived from the returns"
    );
    Ok(cell)
}

/// An error when the navigation covers none of the returns.
fn check_coverage(objective: &Objective, returns: &[BeamReturn]) -> Result<(), FrontendError> {
    if objective.returns() == 0 {
        return Err(FrontendError::insufficient(
            "navigation",
            format!(
                "none of the {} returns lies within the navigation's time span",
                returns.len()
            ),
        ));
    }
    Ok(())
}

/// The median (upper of the two middle values); `None` when empty or when
/// a value is NaN.
fn median(mut values: Vec<f64>) -> Option<f64> {
    if values.is_empty() || values.iter().any(|v| v.is_nan()) {
        return None;
    }
    let mid = values.len() / 2;
    let (_, m, _) = values.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*m)
}
