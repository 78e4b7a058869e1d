//! Rotation assembly: grouping the beam stream into 360° sonar rotations.
//!
//! The paper builds one range scan `S_k` and one acoustic image `I_k` per
//! 360° MSIS rotation (section 3). A mechanically scanned head reports one
//! transducer angle per beam; this module unwraps those angles and cuts the
//! stream into units the rest of the frontend processes one at a time.
//!
//! Behaviour for each case (each has a test below):
//! - **Continuous rotation, wrap-around.** Steps between consecutive beams are
//!   wrapped to (-π, π] and accumulated; a rotation is complete when the
//!   accumulated angle of the next beam would reach 2π (minus half a median
//!   step), so a head with 200 steps per turn gives rotations of 200 beams, and
//!   the next rotation starts at the first beam that repeats an angle. A unit
//!   cut for any reason below whose beams already cover 2π (span plus one
//!   median step) is full too, e.g. the last 200 beams of the data.
//! - **Direction reversals and sector scans.** A step whose sign opposes the
//!   unit's direction (zero steps are ignored), or an angular jump larger than
//!   `max_gap_beam_periods` median steps (a sector head's fly-back), ends the
//!   current unit. A unit that both starts and ends at such a reversal is one
//!   sweep of a sector ([`RotationKind::SectorSweep`]) and is kept like a full
//!   rotation. A unit that ends at a reversal but did not start at one (the
//!   first sweep after the start of the data, or a continuous rotation whose
//!   direction changes) is partial.
//! - **Time gaps.** A stamp difference larger than `max_gap_beam_periods` beam
//!   periods ends the unit; the next unit starts after the gap. The unit cut
//!   by the gap is partial. The beam period is `beam_period_s` if set, else
//!   the median stamp difference within the run of beams with the beam's
//!   bin size and count (a head pings more slowly at a longer range: a
//!   Ping360 every 38 ms at 1 m and every 96 ms at 40 m in one log), or of
//!   the whole stream for a run too short to have one.
//! - **Changes of bin size, bin count or first-bin range** end the unit there;
//!   the unit cut by the change is partial.
//! - **Partial units** (cut by a gap, a change, a non-sweep reversal, or the
//!   end of the data) are dropped, unless `keep_partial` is set and they cover
//!   at least `min_partial_coverage_rad`; then they are returned with
//!   [`RotationKind::Partial`].
//!
//! Stamps must be non-decreasing and finite, angles finite; otherwise an
//! error names the beam.

use crate::error::FrontendError;
use crate::sensors::SonarBeam;
use echofield_graph::se2::wrap_angle;
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};
use std::ops::Range;

/// Parameters of rotation assembly.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RotationConfig {
    /// A stamp difference between consecutive beams longer than this many
    /// beam periods is a gap and ends the current unit; an angular step
    /// larger than this many median angular steps is a jump (a sector
    /// fly-back) and ends it too. Dimensionless, > 1. Default 3.
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): relative to the beam period derived from the stamps, it needs no tuning per sonar.
    #[serde(skip)]
    pub max_gap_beam_periods: f64,
    /// The beam period in seconds. `None` (the default) derives it as the
    /// median of the positive stamp differences.
    pub beam_period_s: Option<f64>,
    /// Keep partial units (see the module doc) instead of dropping them.
    /// Default false.
    pub keep_partial: bool,
    /// With `keep_partial`, the smallest angular coverage (radians) a partial
    /// unit must have to be kept. Default π (half a turn).
    ///
    /// Not a config key (`#[serde(skip)]`: config files keep the default;
    /// library callers may set it): half a turn: with `keep_partial`, less than that cannot be matched reliably.
    #[serde(skip)]
    pub min_partial_coverage_rad: f64,
    /// A rotation becomes a node only when the dead reckoning moved it
    /// this far from the last node, in metres of translation plus the
    /// heading change times half the beams' reach (keyframe selection:
    /// `crate::nodes::spacing`); the others are dropped. 0 makes every
    /// rotation a node; whatever the spacing, at most
    /// `nodes::spacing::MAX_THINNED_IN_A_ROW` rotations in a row are
    /// dropped. Default 2 m (why: EXPERIMENTS.md § Long missions, "The
    /// node spacing as `run`'s default").
    pub node_spacing_m: f64,
}

impl Default for RotationConfig {
    fn default() -> Self {
        Self {
            max_gap_beam_periods: 3.0,
            beam_period_s: None,
            keep_partial: false,
            min_partial_coverage_rad: PI,
            node_spacing_m: 2.0,
        }
    }
}

impl RotationConfig {
    pub fn validate(&self) -> Result<(), FrontendError> {
        if !(self.max_gap_beam_periods.is_finite() && self.max_gap_beam_periods > 1.0) {
            return Err(FrontendError::config(
                "max_gap_beam_periods",
                format!("must be finite and > 1, got {}", self.max_gap_beam_periods),
            ));
        }
        if let Some(period) = self.beam_period_s
            && !(period.is_finite() && period > 0.0)
        {
            return Err(FrontendError::config(
                "beam_period_s",
                format!("must be finite and > 0, got {period}"),
            ));
        }
        if !(self.min_partial_coverage_rad.is_finite()
            && self.min_partial_coverage_rad > 0.0
            && self.min_partial_coverage_rad <= TAU)
        {
            return Err(FrontendError::config(
                "min_partial_coverage_rad",
                format!("must be in (0, 2π], got {}", self.min_partial_coverage_rad),
            ));
        }
        if !(self.node_spacing_m.is_finite() && (0.0..=1000.0).contains(&self.node_spacing_m)) {
            return Err(FrontendError::config(
                "node_spacing_m",
                format!("must be in [0, 1000] m, got {}", self.node_spacing_m),
            ));
        }
        Ok(())
    }
}

/// What kind of unit a [`Rotation`] is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum RotationKind {
    /// A full 360° turn.
    Full,
    /// One sweep of a sector scan, from one reversal to the next.
    SectorSweep,
    /// Less than a full turn (only returned with `keep_partial`).
    Partial,
}

/// One rotation: a contiguous run of beams processed as one scan and image.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Rotation {
    /// Position in the returned list (0, 1, 2, ...).
    pub index: usize,
    /// Indices into the beam slice given to [`assemble_rotations`].
    pub beams: Range<usize>,
    /// Stamp of the first beam, seconds.
    pub start_s: f64,
    /// Stamp of the last beam, seconds.
    pub end_s: f64,
    /// The central time `(start_s + end_s) / 2`: the paper's central pose
    /// (section 4) is the vehicle pose at this time.
    pub reference_stamp_s: f64,
    /// Angle swept, radians: the unwrapped span from the first to the last
    /// beam plus one median step (each beam stands for one step of angle).
    pub coverage_rad: f64,
    pub kind: RotationKind,
}

/// Why a unit ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Boundary {
    Start,
    Full,
    Reversal,
    Gap,
    GeometryChange,
    End,
}

/// Groups `beams` (time-ordered) into rotations; see the module doc for
/// the rules. Errors on invalid config, an empty slice, a non-finite stamp
/// or angle, decreasing stamps, a non-positive bin size, or when no unit
/// survives.
pub fn assemble_rotations(
    beams: &[SonarBeam],
    config: &RotationConfig,
) -> Result<Vec<Rotation>, FrontendError> {
    config.validate()?;
    if beams.is_empty() {
        return Err(FrontendError::insufficient(
            "rotation assembly",
            "no sonar beams",
        ));
    }
    check_beams(beams)?;
    let limits = Limits::new(beams, config);
    let mut rotations = Vec::new();
    for unit in cut_units(beams, &limits) {
        let stamps_s = (
            beams[unit.beams.start].stamp_s,
            beams[unit.beams.end.max(unit.beams.start + 1) - 1].stamp_s,
        );
        if let Some(mut rotation) = classify(&unit, stamps_s, limits.step_rad, config) {
            rotation.index = rotations.len();
            rotations.push(rotation);
        }
    }
    if rotations.is_empty() {
        return Err(FrontendError::insufficient(
            "rotation assembly",
            format!(
                "no complete rotation or sector sweep in {} beams (set keep_partial to keep partial ones)",
                beams.len()
            ),
        ));
    }
    Ok(rotations)
}

/// The rotation a unit gives under the median angular step `step_rad`, or
/// `None` when it is dropped (index 0: the caller numbers them).
/// `(start_s, end_s)` are the stamps of its first and last beams.
fn classify(
    unit: &Unit,
    (start_s, end_s): (f64, f64),
    step_rad: f64,
    config: &RotationConfig,
) -> Option<Rotation> {
    let coverage_rad = (unit.span_rad + step_rad).min(TAU);
    let full = unit.ended_by == Boundary::Full || unit.span_rad + step_rad >= TAU - 0.5 * step_rad;
    let kind = match (unit.started_by, unit.ended_by) {
        _ if full => RotationKind::Full,
        (Boundary::Reversal, Boundary::Reversal) => RotationKind::SectorSweep,
        _ => RotationKind::Partial,
    };
    let keep = kind != RotationKind::Partial
        || (config.keep_partial && coverage_rad >= config.min_partial_coverage_rad);
    if !keep || unit.beams.len() < 2 {
        return None;
    }
    Some(Rotation {
        index: 0,
        beams: unit.beams.clone(),
        start_s,
        end_s,
        reference_stamp_s: 0.5 * (start_s + end_s),
        coverage_rad,
        kind,
    })
}

/// The thresholds derived from the stream: median angular step, largest
/// allowed time step per run of one geometry, largest angle step.
struct Limits {
    step_rad: f64,
    /// `(first beam of the run, largest stamp step within it)`, in order.
    max_gap_s: Vec<(usize, f64)>,
    max_step_rad: f64,
}

impl Limits {
    fn new(beams: &[SonarBeam], config: &RotationConfig) -> Self {
        let stream_period_s = median(beams.windows(2).map(|w| w[1].stamp_s - w[0].stamp_s));
        let mut max_gap_s = Vec::new();
        let mut start = 0;
        for end in 1..=beams.len() {
            if end < beams.len() && same_geometry(&beams[end - 1], &beams[end]) {
                continue;
            }
            let run_period_s = median(
                beams[start..end]
                    .windows(2)
                    .map(|w| w[1].stamp_s - w[0].stamp_s),
            );
            let period_s = config
                .beam_period_s
                .or(run_period_s)
                .or(stream_period_s)
                .unwrap_or(f64::INFINITY);
            max_gap_s.push((start, config.max_gap_beam_periods * period_s));
            start = end;
        }
        let step_rad = median(
            beams
                .windows(2)
                .map(|w| wrap_angle(w[1].angle_rad - w[0].angle_rad).abs()),
        )
        .unwrap_or(0.0);
        Self {
            step_rad,
            max_gap_s,
            max_step_rad: if step_rad > 0.0 {
                config.max_gap_beam_periods * step_rad
            } else {
                f64::INFINITY
            },
        }
    }
}

impl Limits {
    /// The largest stamp step before beam `i` that is not a gap (that of
    /// beam `i`'s run).
    fn max_gap_before_s(&self, i: usize) -> f64 {
        let run = self.max_gap_s.partition_point(|&(first, _)| first <= i) - 1;
        self.max_gap_s[run].1
    }
}

/// A run of beams between two boundaries.
struct Unit {
    beams: Range<usize>,
    started_by: Boundary,
    ended_by: Boundary,
    /// Unwrapped angle from the first to the last beam, absolute, radians.
    span_rad: f64,
}

/// Cuts the stream at every boundary (see the module doc).
fn cut_units(beams: &[SonarBeam], limits: &Limits) -> Vec<Unit> {
    let mut cutter = Cutter::default();
    let mut units: Vec<Unit> = (1..beams.len())
        .filter_map(|i| {
            let max_gap_s = limits.max_gap_before_s(i);
            cutter.push(
                i,
                &beams[i - 1],
                &beams[i],
                limits.step_rad,
                max_gap_s,
                limits.max_step_rad,
            )
        })
        .collect();
    units.push(cutter.finish(beams.len()));
    units
}

/// The state of the cut between beams: where the current unit started and
/// how far it has turned.
#[derive(Default)]
struct Cutter {
    start: usize,
    started_by: Option<Boundary>,
    cumulative_rad: f64,
    direction: f64,
}

impl Cutter {
    /// Beam `i` follows `prev`; returns the unit it ends, if any, with the
    /// limits in force at beam `i`.
    fn push(
        &mut self,
        i: usize,
        prev: &SonarBeam,
        beam: &SonarBeam,
        step_rad: f64,
        max_gap_s: f64,
        max_step_rad: f64,
    ) -> Option<Unit> {
        let step = wrap_angle(beam.angle_rad - prev.angle_rad);
        let reversal = step.abs() > max_step_rad
            || (step != 0.0 && self.direction != 0.0 && step.signum() != self.direction);
        let ended_by = if beam.stamp_s - prev.stamp_s > max_gap_s {
            Boundary::Gap
        } else if !same_geometry(prev, beam) {
            Boundary::GeometryChange
        } else if reversal {
            Boundary::Reversal
        } else {
            self.cumulative_rad += step;
            if self.direction == 0.0 && step != 0.0 {
                self.direction = step.signum();
            }
            if self.cumulative_rad.abs() < TAU - 0.5 * step_rad {
                return None;
            }
            Boundary::Full
        };
        // A full turn ends before beam i, which repeats the first angle.
        let last_step = if ended_by == Boundary::Full {
            step
        } else {
            0.0
        };
        let unit = Unit {
            beams: self.start..i,
            started_by: self.started_by.unwrap_or(Boundary::Start),
            ended_by,
            span_rad: (self.cumulative_rad - last_step).abs(),
        };
        (self.start, self.started_by, self.cumulative_rad) = (i, Some(ended_by), 0.0);
        if ended_by != Boundary::Full {
            self.direction = 0.0;
        }
        Some(unit)
    }

    /// The unit the end of the data cuts (`len` beams in all).
    fn finish(&self, len: usize) -> Unit {
        Unit {
            beams: self.start..len,
            started_by: self.started_by.unwrap_or(Boundary::Start),
            ended_by: Boundary::End,
            span_rad: self.cumulative_rad.abs(),
        }
    }
}

fn check_beams(beams: &[SonarBeam]) -> Result<(), FrontendError> {
    for (i, beam) in beams.iter().enumerate() {
        check_beam(i, beam, i.checked_sub(1).map(|p| &beams[p]))?;
    }
    Ok(())
}

/// Checks beam `i` of the stream (its predecessor `prev`): finite stamp,
/// angle and first-bin range, a plausible angle, a positive bin size, a
/// stamp not earlier than the previous beam's.
fn check_beam(i: usize, beam: &SonarBeam, prev: Option<&SonarBeam>) -> Result<(), FrontendError> {
    let record = || format!("beam {i}");
    if !beam.stamp_s.is_finite() {
        return Err(FrontendError::input(record(), "stamp_s", "not finite"));
    }
    if !beam.angle_rad.is_finite() {
        return Err(FrontendError::input(record(), "angle_rad", "not finite"));
    }
    if let Some(why) = crate::screening::implausible_angle(beam.angle_rad) {
        return Err(FrontendError::input(record(), "angle_rad", why));
    }
    if !(beam.bin_size_m.is_finite() && beam.bin_size_m > 0.0) {
        return Err(FrontendError::input(
            record(),
            "bin_size_m",
            format!("must be finite and > 0, got {}", beam.bin_size_m),
        ));
    }
    if !beam.first_bin_range_m.is_finite() {
        return Err(FrontendError::input(
            record(),
            "first_bin_range_m",
            "not finite",
        ));
    }
    if let Some(prev) = prev
        && beam.stamp_s < prev.stamp_s
    {
        return Err(FrontendError::input(
            record(),
            "stamp_s",
            format!(
                "{} s is earlier than the previous beam's {} s",
                beam.stamp_s, prev.stamp_s
            ),
        ));
    }
    Ok(())
}

fn same_geometry(a: &SonarBeam, b: &SonarBeam) -> bool {
    a.intensities.len() == b.intensities.len()
        && (a.bin_size_m - b.bin_size_m).abs() <= 1e-9 * a.bin_size_m
        && (a.first_bin_range_m - b.first_bin_range_m).abs() <= 1e-9
}

/// Median of the positive values, `None` if there are none.
fn median(values: impl Iterator<Item = f64>) -> Option<f64> {
    let mut v: Vec<f64> = values.filter(|x| *x > 0.0).collect();
    if v.is_empty() {
        return None;
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f64::total_cmp);
    Some(*m)
}

mod stream;
pub use stream::RotationStream;

#[cfg(test)]
mod tests;
