//! The causal driver: a mission's records in time order in, the rotations
//! whose navigation is known out.
//!
//! A vehicle's sonar, DVL and attitude sensor deliver their records as
//! they happen; a recorded [`Mission`] is replayed the same way by
//! [`mission_records`]. [`ReadyRotations`] cuts the beams into rotations
//! ([`RotationStream`]) and holds each completed rotation until the
//! navigation covers it, so that every consumer (the SLAM engine, the
//! localisation on a prior map) places a rotation's beams with exactly the
//! navigation a vehicle would have had at that moment.
//!
//! # When a rotation is ready
//! A completed rotation is ready when the navigation's latest filtered
//! sample is at or after its last beam (`covered_s >= end_s`), or when any
//! record arrives more than the extrapolation horizon after its last beam
//! (the navigation will then never cover it: the consumer extrapolates or
//! skips it). Rotations become ready in order; a later one never overtakes
//! an earlier one. After [`ReadyRotations::finish`] every rotation is
//! ready.

use crate::dead_reckoning::{self, Record};
use crate::error::FrontendError;
use crate::rotation::{Rotation, RotationConfig, RotationStream};
use crate::sensors::{Attitude, DvlVelocity, Mission, SonarBeam};
use std::borrow::Borrow;
use std::collections::VecDeque;

/// One record of a mission, as a vehicle would deliver it. The beam is
/// borrowed from the mission ([`mission_records`]) or, with
/// [`records_with_beams`], whatever form the caller gave it in (e.g.
/// moved out of the mission).
#[derive(Clone, Copy, Debug)]
pub enum MissionRecord<'m, B = &'m SonarBeam> {
    Dvl(&'m DvlVelocity),
    Attitude(&'m Attitude),
    /// A sonar beam with its index in [`Mission::beams`].
    Beam(usize, B),
}

impl<B: Borrow<SonarBeam>> MissionRecord<'_, B> {
    /// The record's stamp, s.
    pub fn stamp_s(&self) -> f64 {
        match self {
            Self::Dvl(s) => s.stamp_s,
            Self::Attitude(a) => a.stamp_s,
            Self::Beam(_, b) => b.borrow().stamp_s,
        }
    }
}

/// Every record of `mission` in time order; at equal stamps DVL, then
/// attitude, then beams (navigation first, so that a beam is never
/// waiting for a sample stamped with it). Each stream keeps its own order
/// (out-of-order records are the consumer's to report).
pub fn mission_records(mission: &Mission) -> impl Iterator<Item = MissionRecord<'_>> {
    records_with_beams(mission, &mission.beams)
}

/// [`mission_records`] with the mission's beams given apart, in the
/// mission's order (`beams[i]` is `Mission::beams[i]`, e.g. moved out of
/// it before the replay): the same records in the same order, each beam
/// as given. `mission.beams` itself is not read.
pub fn records_with_beams<'m, B: Borrow<SonarBeam>>(
    mission: &'m Mission,
    beams: impl IntoIterator<Item = B>,
) -> impl Iterator<Item = MissionRecord<'m, B>> {
    let mut navigation = dead_reckoning::merged_records(mission).peekable();
    let mut beams = beams.into_iter().enumerate().peekable();
    std::iter::from_fn(move || {
        let Some((_, beam)) = beams.peek() else {
            return navigation.next().map(MissionRecord::from);
        };
        let beam_s = beam.borrow().stamp_s;
        match navigation.next_if(|r| r.stamp_s() <= beam_s) {
            Some(record) => Some(record.into()),
            None => beams.next().map(|(i, beam)| MissionRecord::Beam(i, beam)),
        }
    })
}

impl<'m, B> From<Record<'m>> for MissionRecord<'m, B> {
    fn from(record: Record<'m>) -> Self {
        match record {
            Record::Dvl(s) => Self::Dvl(s),
            Record::Attitude(a) => Self::Attitude(a),
        }
    }
}

/// Completed rotations waiting for the navigation (see the module doc).
pub struct ReadyRotations {
    stream: RotationStream,
    pending: VecDeque<Rotation>,
    /// Latest finite stamp of any record, s (`+inf` once finished).
    latest_s: f64,
    /// `dead_reckoning.max_extrapolation_s`, s.
    horizon_s: f64,
}

impl ReadyRotations {
    /// Rotations assembled with `config`, waiting at most `horizon_s`
    /// seconds of later records for the navigation. Errors: an invalid
    /// config.
    pub fn new(config: &RotationConfig, horizon_s: f64) -> Result<Self, FrontendError> {
        Ok(Self {
            stream: RotationStream::new(config)?,
            pending: VecDeque::new(),
            latest_s: f64::NEG_INFINITY,
            horizon_s,
        })
    }

    /// Takes the next beam; returns the rotation it completes (now
    /// waiting). Errors as [`RotationStream::push`], naming the beam.
    pub fn push_beam(&mut self, beam: &SonarBeam) -> Result<Option<&Rotation>, FrontendError> {
        let rotation = self.stream.push(beam)?;
        self.observe(beam.stamp_s);
        Ok(rotation.map(|r| {
            self.pending.push_back(r);
            &self.pending[self.pending.len() - 1]
        }))
    }

    /// A navigation record stamped `stamp_s` arrived (non-finite stamps
    /// are ignored: the navigation reports them).
    pub fn observe(&mut self, stamp_s: f64) {
        if stamp_s.is_finite() {
            self.latest_s = self.latest_s.max(stamp_s);
        }
    }

    /// The end of the data: the last unit if it is kept (now waiting);
    /// every rotation is ready from now on.
    pub fn finish(&mut self) -> Option<&Rotation> {
        self.latest_s = f64::INFINITY;
        let rotation = self.stream.finish()?;
        self.pending.push_back(rotation);
        self.pending.back()
    }

    /// Whether [`Self::finish`] was called.
    pub fn finished(&self) -> bool {
        self.latest_s == f64::INFINITY
    }

    /// Beams pushed so far.
    pub fn beams(&self) -> usize {
        self.stream.beams()
    }

    /// The ready rotations, oldest first, taken from the queue, when the
    /// navigation is final up to `covered_s` (s): all of them once at
    /// least `min_batch` are ready or the data has ended, else none.
    pub fn take_ready(&mut self, covered_s: f64, min_batch: usize) -> Vec<Rotation> {
        let (latest_s, horizon_s) = (self.latest_s, self.horizon_s);
        let ready = self
            .pending
            .iter()
            .take_while(|r| covered_s >= r.end_s || latest_s > r.end_s + horizon_s)
            .count();
        if ready == 0 || (ready < min_batch && !self.finished()) {
            return Vec::new();
        }
        self.pending.drain(..ready).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensors::{Attitude, DvlVelocity};

    fn beam(stamp_s: f64, angle_rad: f64) -> SonarBeam {
        SonarBeam {
            stamp_s,
            angle_rad,
            bin_size_m: 0.1,
            first_bin_range_m: 0.0,
            intensities: vec![0; 4],
        }
    }

    fn dvl(stamp_s: f64) -> DvlVelocity {
        DvlVelocity {
            stamp_s,
            velocity_mps: nalgebra::Vector3::zeros(),
            valid: true,
            covariance: None,
        }
    }

    fn attitude(stamp_s: f64) -> Attitude {
        Attitude {
            stamp_s,
            roll_rad: 0.0,
            pitch_rad: 0.0,
            yaw_rad: 0.0,
            yaw_rate_radps: None,
        }
    }

    #[test]
    fn records_come_in_time_order_with_navigation_first_at_equal_stamps() {
        let mission = Mission {
            beams: vec![beam(0.0, 0.0), beam(1.0, 0.1), beam(3.0, 0.2)],
            dvl: vec![dvl(1.0), dvl(2.5), dvl(4.0)],
            attitude: vec![attitude(0.5), attitude(1.0)],
            ..Mission::default()
        };
        let order: Vec<String> = mission_records(&mission)
            .map(|r| match r {
                MissionRecord::Dvl(s) => format!("d{}", s.stamp_s),
                MissionRecord::Attitude(a) => format!("a{}", a.stamp_s),
                MissionRecord::Beam(i, b) => format!("b{i}@{}", b.stamp_s),
            })
            .collect();
        assert_eq!(
            order,
            ["b0@0", "a0.5", "d1", "a1", "b1@1", "d2.5", "b2@3", "d4"]
        );
    }

    /// A head of 10 beams per turn, one beam per 0.1 s, from `t0_s`.
    fn turn(t0_s: f64, first: usize, n: usize) -> Vec<SonarBeam> {
        (first..first + n)
            .map(|i| beam(t0_s + 0.1 * i as f64, (i % 10) as f64 * 0.628))
            .collect()
    }

    #[test]
    fn a_rotation_waits_for_the_navigation_or_the_horizon() {
        let mut ready = ReadyRotations::new(&RotationConfig::default(), 1.0).unwrap();
        let mut completed = Vec::new();
        for b in turn(0.0, 0, 11) {
            if let Some(r) = ready.push_beam(&b).unwrap() {
                completed.push((r.index, r.end_s));
            }
        }
        // The 11th beam completes the first turn (beams 0-9, last at 0.9 s).
        assert_eq!(completed.len(), 1);
        let end_s = completed[0].1;
        assert!((end_s - 0.9).abs() < 1e-9, "{end_s}");
        // Navigation up to 0.8 s: not ready; a record past the horizon
        // makes it ready (never covered), as does navigation up to its end.
        assert!(ready.take_ready(0.8, 1).is_empty());
        ready.observe(end_s + 1.0);
        assert!(ready.take_ready(0.8, 1).is_empty(), "horizon not passed");
        ready.observe(end_s + 1.01);
        let taken = ready.take_ready(0.8, 1);
        assert_eq!(taken.len(), 1);
        assert_eq!(taken[0].index, 0);
        assert!(ready.take_ready(f64::INFINITY, 1).is_empty(), "taken once");
    }

    #[test]
    fn a_batch_waits_for_its_size_until_the_end() {
        let mut ready = ReadyRotations::new(&RotationConfig::default(), 100.0).unwrap();
        for b in turn(0.0, 0, 31) {
            ready.push_beam(&b).unwrap();
        }
        // Three turns completed and covered; a batch of four waits.
        assert!(ready.take_ready(10.0, 4).is_empty());
        assert!(!ready.finished());
        ready.finish();
        assert!(ready.finished());
        let taken = ready.take_ready(10.0, 4);
        let indices: Vec<usize> = taken.iter().map(|r| r.index).collect();
        assert_eq!(indices, [0, 1, 2]);
        assert_eq!(ready.beams(), 31);
    }
}
