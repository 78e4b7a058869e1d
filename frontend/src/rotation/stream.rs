//! Rotation assembly on a beam stream: the rules of [`super`] applied beam
//! by beam, each rotation returned as soon as the beam that ends it
//! arrives, with thresholds estimated from the recent past only.

use super::{Cutter, Rotation, RotationConfig, check_beam, classify, median, same_geometry};
use crate::error::FrontendError;
use crate::sensors::SonarBeam;
use echofield_graph::se2::wrap_angle;
use std::collections::VecDeque;

/// Beams over which the stream estimates the median angular step and beam
/// period: a couple of rotations of a typical head, so that the
/// thresholds follow the current settings and cost a bounded amount per
/// beam.
const WINDOW_BEAMS: usize = 512;

/// The causal counterpart of [`super::assemble_rotations`].
///
/// Differences from the batch function, all from using the past only: the
/// median angular step and beam period are those of the last
/// [`WINDOW_BEAMS`] beams (the beam period of the current geometry run,
/// else of the stream) instead of the whole stream's; on a head with steady
/// settings the two agree and the cuts are the same. Rotation indices and
/// beam ranges count every beam pushed.
pub struct RotationStream {
    config: RotationConfig,
    cutter: Cutter,
    prev: Option<SonarBeam>,
    pushed: usize,
    /// `|wrapped angle step|` of the last beams, rad.
    steps_rad: VecDeque<f64>,
    /// Stamp steps within the current geometry run, s.
    run_periods_s: VecDeque<f64>,
    /// Stamp steps of the stream, s.
    stream_periods_s: VecDeque<f64>,
    /// Stamps of the current unit's first beam and of the last beam, s.
    unit_start_s: f64,
    last_s: f64,
    step_rad: f64,
    rotations: usize,
}

impl RotationStream {
    /// Errors on an invalid config.
    pub fn new(config: &RotationConfig) -> Result<Self, FrontendError> {
        config.validate()?;
        Ok(Self {
            config: config.clone(),
            cutter: Cutter::default(),
            prev: None,
            pushed: 0,
            steps_rad: VecDeque::with_capacity(WINDOW_BEAMS),
            run_periods_s: VecDeque::with_capacity(WINDOW_BEAMS),
            stream_periods_s: VecDeque::with_capacity(WINDOW_BEAMS),
            unit_start_s: f64::NAN,
            last_s: f64::NAN,
            step_rad: 0.0,
            rotations: 0,
        })
    }

    /// Beams pushed so far.
    pub fn beams(&self) -> usize {
        self.pushed
    }

    /// Takes the next beam; returns the rotation it completes, if any (the
    /// rotation ends at the beam before). Errors name the beam (counting
    /// every beam pushed) and field, like [`super::assemble_rotations`].
    pub fn push(&mut self, beam: &SonarBeam) -> Result<Option<Rotation>, FrontendError> {
        let i = self.pushed;
        check_beam(i, beam, self.prev.as_ref())?;
        self.pushed += 1;
        let Some(prev) = self.prev.replace(beam.clone()) else {
            (self.unit_start_s, self.last_s) = (beam.stamp_s, beam.stamp_s);
            return Ok(None);
        };
        self.observe(&prev, beam);
        let max_step_rad = if self.step_rad > 0.0 {
            self.config.max_gap_beam_periods * self.step_rad
        } else {
            f64::INFINITY
        };
        let period_s = self
            .config
            .beam_period_s
            .or_else(|| median(self.run_periods_s.iter().copied()))
            .or_else(|| median(self.stream_periods_s.iter().copied()))
            .unwrap_or(f64::INFINITY);
        let max_gap_s = self.config.max_gap_beam_periods * period_s;
        let unit = self
            .cutter
            .push(i, &prev, beam, self.step_rad, max_gap_s, max_step_rad);
        let end_s = self.last_s;
        self.last_s = beam.stamp_s;
        let Some(unit) = unit else {
            return Ok(None);
        };
        let start_s = std::mem::replace(&mut self.unit_start_s, beam.stamp_s);
        Ok(self.numbered(classify(
            &unit,
            (start_s, end_s),
            self.step_rad,
            &self.config,
        )))
    }

    /// The unit the end of the data cuts, when it is kept (a full turn, or a
    /// partial one with `keep_partial`).
    pub fn finish(&mut self) -> Option<Rotation> {
        self.prev.as_ref()?;
        let unit = self.cutter.finish(self.pushed);
        let rotation = classify(
            &unit,
            (self.unit_start_s, self.last_s),
            self.step_rad,
            &self.config,
        );
        self.numbered(rotation)
    }

    fn numbered(&mut self, rotation: Option<Rotation>) -> Option<Rotation> {
        let mut rotation = rotation?;
        rotation.index = self.rotations;
        self.rotations += 1;
        Some(rotation)
    }

    /// Adds the step from `prev` to `beam` to the windows and updates the
    /// median angular step.
    fn observe(&mut self, prev: &SonarBeam, beam: &SonarBeam) {
        let push = |window: &mut VecDeque<f64>, value: f64| {
            if window.len() == WINDOW_BEAMS {
                window.pop_front();
            }
            window.push_back(value);
        };
        let dt_s = beam.stamp_s - prev.stamp_s;
        push(&mut self.stream_periods_s, dt_s);
        if same_geometry(prev, beam) {
            push(&mut self.run_periods_s, dt_s);
        } else {
            self.run_periods_s.clear();
        }
        push(
            &mut self.steps_rad,
            wrap_angle(beam.angle_rad - prev.angle_rad).abs(),
        );
        self.step_rad = median(self.steps_rad.iter().copied()).unwrap_or(0.0);
    }
}
