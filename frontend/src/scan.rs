//! The range scan `S_k` of one rotation (paper section 3, "scan building"):
//! the ranges extracted from each beam (see [`crate::segmentation`]) placed at
//! their bin endpoints (eq. 3) in the vehicle frame at the rotation's
//! reference time, motion-compensated with the beam frames of eq. (4) (see
//! [`crate::motion::reference_from_beams`]).
//!
//! ```
//! use echofield_frontend::dead_reckoning::Navigation;
//! use echofield_frontend::motion::reference_from_beams;
//! use echofield_frontend::scan::build_scan;
//! use echofield_frontend::segmentation::SegmentationConfig;
//! use echofield_frontend::{SensorMounting, SonarBeam};
//!
//! // A still sonar seeing a ring of echoes 8 m away.
//! let beams: Vec<SonarBeam> = (0..200)
//!     .map(|k| {
//!         let mut intensities = vec![5u8; 200];
//!         intensities[79] = 200;
//!         SonarBeam { stamp_s: k as f64 * 0.07, angle_rad: k as f64 * 0.0314,
//!                     bin_size_m: 0.1, first_bin_range_m: 0.0, intensities }
//!     })
//!     .collect();
//! let nav = Navigation::stationary(0.0, 14.0);
//! let frames = reference_from_beams(&beams, &nav, &SensorMounting::default(), 7.0).unwrap();
//! let scan = build_scan(&beams, &frames, 7.0, &SegmentationConfig::default()).unwrap();
//! assert_eq!(scan.points.len(), 200);
//! // 8 m, plus 4 mm of beam-width correction (a ring seen at normal incidence).
//! let range = scan.points[0].coords.norm();
//! assert!((range - 8.0 - f64::from(scan.range_corrections_m[0])).abs() < 1e-9);
//! assert!((range - 8.004).abs() < 1e-3);
//! ```

use crate::error::FrontendError;
use crate::off_axis::{Echo, keep_returns};
use crate::segmentation::{RangeReturn, SegmentationConfig, extract_ranges_into};
use crate::sensors::SonarBeam;
use echofield_graph::Se2;
use nalgebra::{Point2, Vector2};

/// The scan `S_k`: points in metres in the vehicle frame at the reference
/// time, with the intensity and source beam of each.
#[derive(Clone, Debug, PartialEq)]
pub struct Scan {
    /// Time of the frame the points are expressed in, s.
    pub reference_stamp_s: f64,
    /// The paper's `p_i` (eq. 5), metres, vehicle frame at `reference_stamp_s`.
    pub points: Vec<Point2<f64>>,
    /// Smoothed intensity of each point's return, 0-255 scale.
    pub intensities: Vec<f32>,
    /// Index of each point's beam in the beam slice given to [`build_scan`].
    pub beam_indices: Vec<u32>,
    /// How far each point was moved outward along its beam by the
    /// beam-width correction ([`beam_width`]), metres; empty when none was
    /// applied.
    pub range_corrections_m: Vec<f32>,
}

impl Scan {
    pub fn len(&self) -> usize {
        self.points.len()
    }

    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// An empty scan at `reference_stamp_s`.
    pub fn empty(reference_stamp_s: f64) -> Self {
        Self {
            reference_stamp_s,
            points: Vec::new(),
            intensities: Vec::new(),
            beam_indices: Vec::new(),
            range_corrections_m: Vec::new(),
        }
    }

    /// The beam frames to build this rotation's image with, so that it
    /// agrees with the scan: each frame of `reference_from_beams` moved
    /// along its beam by the correction of its beam's return (the first
    /// one, with several returns per beam). Beams without a return keep
    /// their frame.
    pub fn image_frames(&self, reference_from_beams: &[Se2]) -> Vec<Se2> {
        let mut frames = reference_from_beams.to_vec();
        let mut last = None;
        for (&b, &dr) in self.beam_indices.iter().zip(&self.range_corrections_m) {
            if last != Some(b)
                && let Some(frame) = frames.get_mut(b as usize)
            {
                *frame = frame.compose(&Se2::new(f64::from(dr), 0.0, 0.0));
            }
            last = Some(b);
        }
        frames
    }
}

/// Builds `S_k` from the beams of one rotation and their frames
/// `reference_from_beams` (from [`crate::motion::reference_from_beams`] at
/// `reference_stamp_s`): each return `r` of beam `j` becomes the point
/// `reference_from_beams[j] · (r.range_m + Δr, 0)`, `Δr` the beam-width
/// correction of `config.beam_width` ([`beam_width`]; 0 when it is off),
/// kept in [`Scan::range_corrections_m`]. Returns that a neighbouring beam
/// hears much louder are dropped first (`config.off_axis`, see
/// [`crate::off_axis`]).
///
/// Errors: invalid config; slices of different lengths; a beam with a
/// non-finite or non-positive bin size or a non-finite first-bin range, or
/// a non-finite frame (named by index); and
/// [`FrontendError::TooFewRanges`] when fewer than
/// `config.min_scan_points` points result (an empty or silent rotation):
/// callers treat that as "this rotation has no scan" rather than a failure
/// of the run.
pub fn build_scan(
    beams: &[SonarBeam],
    reference_from_beams: &[Se2],
    reference_stamp_s: f64,
    config: &SegmentationConfig,
) -> Result<Scan, FrontendError> {
    config.validate()?;
    if beams.len() != reference_from_beams.len() {
        return Err(FrontendError::input(
            "scan",
            "reference_from_beams",
            format!(
                "{} frames for {} beams",
                reference_from_beams.len(),
                beams.len()
            ),
        ));
    }
    let mut scan = Scan {
        points: Vec::with_capacity(beams.len() * config.max_peaks.min(4)),
        ..Scan::empty(reference_stamp_s)
    };
    let echoes = echoes(beams, reference_from_beams, config)?;
    let angles: Vec<f64> = beams.iter().map(|b| b.angle_rad).collect();
    let keep = keep_returns(&echoes, &angles, &config.off_axis);
    for (echo, _) in echoes.iter().zip(&keep).filter(|(_, k)| **k) {
        // Eq. (3) in the frame of eq. (4).
        let (x, y) = reference_from_beams[echo.beam].transform_xy(echo.range_m, 0.0);
        scan.points.push(Point2::new(x, y));
        scan.intensities.push(echo.intensity as f32);
        scan.beam_indices.push(echo.beam as u32);
    }
    if config.beam_width.enabled {
        correct_beam_width(&mut scan, reference_from_beams, &config.beam_width);
    }
    if scan.points.len() < config.min_scan_points {
        return Err(FrontendError::TooFewRanges {
            reference_stamp_s,
            found: scan.points.len(),
            required: config.min_scan_points,
        });
    }
    Ok(scan)
}

/// The returns of every beam (each checked first), in beam order.
fn echoes(
    beams: &[SonarBeam],
    reference_from_beams: &[Se2],
    config: &SegmentationConfig,
) -> Result<Vec<Echo>, FrontendError> {
    let (mut smoothed, mut returns): (Vec<f32>, Vec<RangeReturn>) = (Vec::new(), Vec::new());
    let mut echoes = Vec::new();
    for (j, (beam, frame)) in beams.iter().zip(reference_from_beams).enumerate() {
        check_beam(j, beam, frame)?;
        returns.clear();
        extract_ranges_into(beam, config, &mut smoothed, &mut returns);
        echoes.extend(returns.iter().map(|r| Echo {
            beam: j,
            range_m: r.range_m,
            intensity: f64::from(r.intensity),
        }));
    }
    Ok(echoes)
}

/// Moves each point of `scan` along its beam by the beam-width correction
/// (metres, recorded in `range_corrections_m`).
fn correct_beam_width(
    scan: &mut Scan,
    reference_from_beams: &[Se2],
    config: &beam_width::BeamWidthCorrection,
) {
    scan.range_corrections_m = beam_width::corrections(
        &scan.points,
        &scan.beam_indices,
        reference_from_beams,
        config,
    );
    for ((p, &b), &dr) in scan
        .points
        .iter_mut()
        .zip(&scan.beam_indices)
        .zip(&scan.range_corrections_m)
    {
        *p += reference_from_beams[b as usize].rotation() * Vector2::new(f64::from(dr), 0.0);
    }
}

fn check_beam(j: usize, beam: &SonarBeam, frame: &Se2) -> Result<(), FrontendError> {
    if !(beam.bin_size_m.is_finite() && beam.bin_size_m > 0.0) {
        return Err(FrontendError::input(
            format!("beam {j}"),
            "bin_size_m",
            format!("must be finite and > 0, got {}", beam.bin_size_m),
        ));
    }
    if !beam.first_bin_range_m.is_finite() {
        return Err(FrontendError::input(
            format!("beam {j}"),
            "first_bin_range_m",
            "not finite",
        ));
    }
    if !frame.is_finite() {
        return Err(FrontendError::input(
            format!("beam {j}"),
            "reference_from_beam",
            "not finite",
        ));
    }
    Ok(())
}

pub mod beam_width;
pub mod overlap;
#[cfg(test)]
mod tests;
