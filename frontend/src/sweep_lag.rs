//! Direction-dependent angle lag of a sector-scanning head: estimating it
//! from the beams and correcting the beam angles.
//!
//! A mechanically scanned head reports the angle it was commanded to. If the
//! transducer trails that angle by `lag` in the direction of its last move
//! (gear backlash, or a ping taken before the step has settled; the beams
//! cannot tell the two apart), a target at true angle `φ` is reported at
//! `φ + lag` on sweeps of increasing angle and at `φ − lag` on sweeps of
//! decreasing angle: consecutive sweeps of a sector scan disagree by
//! `2·lag`, while sweeps in the same direction (and continuous rotations)
//! agree with each other.
//!
//! On the real Ping360 logs of `datasets/msis-real/ping360` one sector's echoes
//! repeat from sweep to sweep and give a lag of about half a motor step; the
//! other sectors hold no such structure and give no estimate
//! ([`estimate_sweep_lag`] returns an error there). Measured: EXPERIMENTS.md §
//! Sweep lag.
//!
//! Correction ([`correct_sweep_lag`]): every beam's angle is moved back by
//! `lag_rad` against the direction of the last non-zero angle step that led
//! to it (a fly-back jump counts as a move too); beams before the first step
//! take the direction of that step.

use crate::error::FrontendError;
use crate::rotation::{Rotation, RotationConfig, RotationKind, assemble_rotations};
use crate::sensors::SonarBeam;
use echofield_graph::se2::wrap_angle;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Parameters of [`estimate_sweep_lag`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SweepLagConfig {
    /// Largest disagreement between two opposite sweeps searched, in
    /// angular steps of the head (each way). Default 4.
    pub max_shift_steps: usize,
    /// Bins nearer than this are left out of the comparison (ringing),
    /// metres. Default 0.
    pub min_range_m: f64,
    /// Bins farther than this are left out, metres; `None` (the default)
    /// uses the whole beam.
    pub max_range_m: Option<f64>,
    /// A pair of sweeps whose best normalised correlation is below this
    /// holds no repeatable structure and is not used. Default 0.3.
    pub min_correlation: f64,
    /// A pair is used only if its best correlation exceeds the lowest one
    /// over the shifts tried by at least this: a flat correlation curve
    /// (echoes that change from ping to ping, or the range profile every
    /// beam shares) fixes no shift. Default 0.15.
    pub min_peak_contrast: f64,
    /// A pair must share at least this many angles at every shift tried.
    /// Default 20.
    pub min_common_angles: usize,
}

impl Default for SweepLagConfig {
    fn default() -> Self {
        Self {
            max_shift_steps: 4,
            min_range_m: 0.0,
            max_range_m: None,
            min_correlation: 0.3,
            min_peak_contrast: 0.15,
            min_common_angles: 20,
        }
    }
}

impl SweepLagConfig {
    pub fn validate(&self) -> Result<(), FrontendError> {
        if self.max_shift_steps == 0 {
            return Err(FrontendError::config("max_shift_steps", "must be >= 1"));
        }
        if !(self.min_range_m.is_finite() && self.min_range_m >= 0.0) {
            return Err(FrontendError::config(
                "min_range_m",
                format!("must be finite and >= 0, got {}", self.min_range_m),
            ));
        }
        if let Some(max) = self.max_range_m
            && !(max.is_finite() && max > self.min_range_m)
        {
            return Err(FrontendError::config(
                "max_range_m",
                format!("must be finite and > min_range_m, got {max}"),
            ));
        }
        if !(self.min_correlation.is_finite() && (-1.0..=1.0).contains(&self.min_correlation)) {
            return Err(FrontendError::config(
                "min_correlation",
                format!("must be in [-1, 1], got {}", self.min_correlation),
            ));
        }
        if !(self.min_peak_contrast.is_finite() && (0.0..=2.0).contains(&self.min_peak_contrast)) {
            return Err(FrontendError::config(
                "min_peak_contrast",
                format!("must be in [0, 2], got {}", self.min_peak_contrast),
            ));
        }
        if self.min_common_angles < 3 {
            return Err(FrontendError::config("min_common_angles", "must be >= 3"));
        }
        Ok(())
    }
}

/// What [`estimate_sweep_lag`] found.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SweepLagEstimate {
    /// The lag, radians: positive when the transducer trails the reported
    /// angle (give it to [`correct_sweep_lag`]).
    pub lag_rad: f64,
    /// Standard deviation of the per-pair estimates, radians.
    pub spread_rad: f64,
    /// Pairs of consecutive opposite sweeps used.
    pub pairs: usize,
    /// Mean best correlation of those pairs.
    pub correlation: f64,
}

/// Moves each beam's angle back by `lag_rad` against the direction of its
/// last move (see the module doc); angles keep their wrapping. A
/// non-finite `lag_rad` is an error and changes nothing.
pub fn correct_sweep_lag(beams: &mut [SonarBeam], lag_rad: f64) -> Result<(), FrontendError> {
    if !lag_rad.is_finite() {
        return Err(FrontendError::config(
            "lag_rad",
            format!("must be finite, got {lag_rad}"),
        ));
    }
    let directions = move_directions(beams);
    for (beam, direction) in beams.iter_mut().zip(directions) {
        beam.angle_rad = wrap_angle(beam.angle_rad - direction * lag_rad);
    }
    Ok(())
}

/// Sign (+1, −1, or 0 if the angle never changes) of the last non-zero
/// step leading to each beam; leading beams take the first step's sign.
fn move_directions(beams: &[SonarBeam]) -> Vec<f64> {
    let step = |i: usize| wrap_angle(beams[i].angle_rad - beams[i - 1].angle_rad);
    let first = (1..beams.len())
        .map(step)
        .find(|s| *s != 0.0)
        .map_or(0.0, f64::signum);
    let mut direction = first;
    (0..beams.len())
        .map(|i| {
            if i > 0 && step(i) != 0.0 {
                direction = step(i).signum();
            }
            direction
        })
        .collect()
}

/// Estimates the lag from consecutive sector sweeps in opposite directions
/// (found by [`assemble_rotations`] with its default config): for each pair,
/// the angular shift that best correlates the two sweeps' intensity profiles
/// (each bin de-meaned over the angles, which removes the range profile
/// every beam shares), refined by a parabola through the best three shifts;
/// half of it is that pair's lag. Only adjacent sweeps in opposite
/// directions pair up (not two sweeps in one direction split by a fly-back
/// jump), and pairs whose correlation curve has no clear peak
/// (`min_correlation`, `min_peak_contrast`) are skipped; the estimate is
/// the mean over the others. Errors on a bad config, invalid beams, or when
/// no pair is left.
pub fn estimate_sweep_lag(
    beams: &[SonarBeam],
    config: &SweepLagConfig,
) -> Result<SweepLagEstimate, FrontendError> {
    config.validate()?;
    let sweeps: Vec<Rotation> = assemble_rotations(beams, &RotationConfig::default())?
        .into_iter()
        .filter(|r| r.kind == RotationKind::SectorSweep)
        .collect();
    let mut lags = Vec::new();
    let mut correlations = Vec::new();
    for pair in sweeps.windows(2) {
        let (a, b) = (&beams[pair[0].beams.clone()], &beams[pair[1].beams.clone()]);
        let direction_a = move_directions(a)[a.len() - 1];
        let direction_b = move_directions(b)[b.len() - 1];
        if pair[0].beams.end != pair[1].beams.start || direction_a == direction_b {
            continue;
        }
        let Some((shift_rad, correlation, contrast)) = best_shift(a, b, config) else {
            continue;
        };
        if correlation < config.min_correlation || contrast < config.min_peak_contrast {
            continue;
        }
        // B's angle for A's target is A's minus 2·lag when A increases.
        lags.push(0.5 * direction_b * shift_rad);
        correlations.push(correlation);
    }
    if lags.is_empty() {
        return Err(FrontendError::insufficient(
            "sweep lag estimate",
            format!(
                "no pair of consecutive opposite sweeps (of {} sector sweeps) correlates above {} with a peak {} above its lowest shift",
                sweeps.len(),
                config.min_correlation,
                config.min_peak_contrast
            ),
        ));
    }
    let n = lags.len() as f64;
    let lag_rad = lags.iter().sum::<f64>() / n;
    let spread_rad = (lags.iter().map(|l| (l - lag_rad).powi(2)).sum::<f64>() / n).sqrt();
    Ok(SweepLagEstimate {
        lag_rad,
        spread_rad,
        pairs: lags.len(),
        correlation: correlations.iter().sum::<f64>() / n,
    })
}

/// The shift `s` (radians) maximising the correlation of `a(k)` with
/// `b(k + s)`, that correlation, and its excess over the lowest correlation
/// of the shifts tried; `None` if the sweeps do not overlap enough or have
/// no usable bins.
fn best_shift(
    a: &[SonarBeam],
    b: &[SonarBeam],
    config: &SweepLagConfig,
) -> Option<(f64, f64, f64)> {
    let step_rad = median_step(a)?;
    let origin = a[0].angle_rad;
    // Profiles by step index from `a`'s first angle (sectors may cross ±π),
    // and the sweep's mean offset from that grid in steps (non-zero once the
    // angles are corrected), added back to the shift found.
    let grid = |beams: &[SonarBeam]| -> (BTreeMap<i64, Vec<f64>>, f64) {
        let mut phase = 0.0;
        let rows = beams
            .iter()
            .map(|beam| {
                let steps = wrap_angle(beam.angle_rad - origin) / step_rad;
                phase += steps - steps.round();
                let k = steps.round() as i64;
                (k, beam.intensities.iter().map(|&v| f64::from(v)).collect())
            })
            .collect();
        (rows, phase / beams.len() as f64)
    };
    let ((grid_a, phase_a), (grid_b, phase_b)) = (grid(a), grid(b));
    let bins = bin_window(&a[0], config)?;
    let max = config.max_shift_steps as i64;
    let mut curve = Vec::with_capacity(2 * max as usize + 1);
    for shift in -max..=max {
        let rows: Vec<(&[f64], &[f64])> = grid_a
            .iter()
            .filter_map(|(k, pa)| {
                Some((&pa[bins.clone()], &grid_b.get(&(k + shift))?[bins.clone()]))
            })
            .collect();
        if rows.len() < config.min_common_angles {
            return None;
        }
        curve.push(correlation(&rows)?);
    }
    let (best, value) =
        curve.iter().enumerate().fold(
            (0, f64::NEG_INFINITY),
            |acc, (i, &v)| if v > acc.1 { (i, v) } else { acc },
        );
    let offset = if best > 0 && best + 1 < curve.len() {
        let (l, c, r) = (curve[best - 1], curve[best], curve[best + 1]);
        let denominator = l - 2.0 * c + r;
        if denominator < 0.0 {
            0.5 * (l - r) / denominator
        } else {
            0.0
        }
    } else {
        0.0
    };
    let shift_steps = best as f64 - max as f64 + offset + phase_b - phase_a;
    let lowest = curve.iter().copied().fold(f64::INFINITY, f64::min);
    Some((shift_steps * step_rad, value, value - lowest))
}

/// Normalised correlation of paired profiles, each bin de-meaned over the
/// rows; `None` if either side is constant.
fn correlation(rows: &[(&[f64], &[f64])]) -> Option<f64> {
    let n = rows.len() as f64;
    let bins = rows[0].0.len();
    let (mut xy, mut xx, mut yy) = (0.0, 0.0, 0.0);
    for k in 0..bins {
        let mean_x = rows.iter().map(|r| r.0[k]).sum::<f64>() / n;
        let mean_y = rows.iter().map(|r| r.1[k]).sum::<f64>() / n;
        for (x, y) in rows {
            let (dx, dy) = (x[k] - mean_x, y[k] - mean_y);
            xy += dx * dy;
            xx += dx * dx;
            yy += dy * dy;
        }
    }
    (xx > 0.0 && yy > 0.0).then(|| xy / (xx * yy).sqrt())
}

/// Bins whose centre lies in `[min_range_m, max_range_m]`.
fn bin_window(beam: &SonarBeam, config: &SweepLagConfig) -> Option<std::ops::Range<usize>> {
    let n = beam.intensities.len();
    let first = (0..n).find(|&i| beam.bin_centre_range_m(i) >= config.min_range_m)?;
    let end = config.max_range_m.map_or(n, |max| {
        (first..n)
            .find(|&i| beam.bin_centre_range_m(i) > max)
            .unwrap_or(n)
    });
    (end > first).then_some(first..end)
}

/// Median absolute non-zero angular step of a sweep.
fn median_step(beams: &[SonarBeam]) -> Option<f64> {
    let mut steps: Vec<f64> = beams
        .windows(2)
        .map(|w| wrap_angle(w[1].angle_rad - w[0].angle_rad).abs())
        .filter(|s| *s > 0.0)
        .collect();
    if steps.is_empty() {
        return None;
    }
    let mid = steps.len() / 2;
    let (_, m, _) = steps.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*m)
}

#[cfg(test)]
mod tests;
