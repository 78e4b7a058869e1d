//! A recording of raw MSIS beams from a real sonar log (Ping360 `.bin`,
//! MiniKing ROS bag), with what the reader met on the way.
//!
//! The beams are kept exactly as the head produced them, in file order; the
//! frontend's rotation assembly groups them into rotations and splits where
//! the range setting (bin size or bin count) changes.
//! [`SonarRecording::range_segments`] lists those changes.

use echofield_frontend::sensors::{Mission, SonarBeam};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Beams of one sonar log plus per-file information.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SonarRecording {
    /// The file read.
    pub path: PathBuf,
    /// Sonar model, e.g. "Blue Robotics Ping360".
    pub device: String,
    /// What the container says about itself (viewer version, topic, message
    /// type, ...), in file order.
    pub info: Vec<(String, String)>,
    /// Beams in file order; stamps never decrease.
    pub beams: Vec<SonarBeam>,
    pub stats: ReadStats,
}

/// Counts of what was read and what was skipped.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ReadStats {
    /// Container records read (Qt stream records, bag records).
    pub records: usize,
    /// Messages with a good frame (Ping protocol checksum, bag record).
    pub messages: usize,
    /// Good messages that are not beams, by message id or type name.
    pub other_messages: BTreeMap<String, usize>,
    /// Ping protocol messages whose checksum did not match (resynchronised).
    pub bad_checksums: usize,
    /// Beam messages with a good frame but an unusable payload (skipped).
    pub bad_beam_messages: usize,
    /// Stream bytes outside any good message (noise, resynchronisation).
    pub skipped_bytes: usize,
    /// Bytes of an incomplete message at the end of the stream.
    pub truncated_tail_bytes: usize,
    /// Why the reader stopped before the end of the file, naming the record,
    /// byte offset and field; the beams before that point are kept.
    pub stopped_early: Option<String>,
    /// The head's transmit and receive settings that a [`SonarBeam`] does
    /// not carry, at the first beam and at every beam where one of them
    /// changes. Empty when the format does not record them (MiniKing bags).
    pub settings_changes: Vec<SettingsChange>,
}

/// Settings of the head from beam `first_beam` on (until the next change).
/// Images built across a change of gain or pulse length mix intensities of
/// different scales.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SettingsChange {
    /// Index of the first beam with these settings in
    /// [`SonarRecording::beams`].
    pub first_beam: usize,
    /// Stamp of that beam, seconds.
    pub stamp_s: f64,
    /// Receiver gain setting as the device numbers it (Ping360: 0 low,
    /// 1 normal, 2 high).
    pub gain_setting: u8,
    /// Length of the transmitted pulse, microseconds.
    pub transmit_duration_us: f64,
    /// Transmit frequency, kHz.
    pub transmit_frequency_khz: f64,
}

/// A run of consecutive beams with one range setting.
#[derive(Clone, Debug, PartialEq)]
pub struct RangeSegment {
    /// Index of the first beam of the run in [`SonarRecording::beams`].
    pub first_beam: usize,
    pub beam_count: usize,
    pub bin_size_m: f64,
    pub bins: usize,
    /// Angle swept by the run, summing the wrapped steps between beams,
    /// radians (2π per full rotation; a sector scan sweeps back and forth).
    pub swept_rad: f64,
}

impl RangeSegment {
    /// Far range of the last bin, metres.
    pub fn range_m(&self) -> f64 {
        self.bin_size_m * self.bins as f64
    }
}

impl SonarRecording {
    /// Runs of beams with the same bin size (to 1 µm) and bin count.
    pub fn range_segments(&self) -> Vec<RangeSegment> {
        let mut segments: Vec<RangeSegment> = Vec::new();
        for (index, beam) in self.beams.iter().enumerate() {
            let bins = beam.intensities.len();
            match segments.last_mut() {
                Some(seg)
                    if seg.bins == bins && (seg.bin_size_m - beam.bin_size_m).abs() < 1e-6 =>
                {
                    let prev = &self.beams[index - 1];
                    seg.swept_rad +=
                        echofield_graph::wrap_angle(beam.angle_rad - prev.angle_rad).abs();
                    seg.beam_count += 1;
                }
                _ => segments.push(RangeSegment {
                    first_beam: index,
                    beam_count: 1,
                    bin_size_m: beam.bin_size_m,
                    bins,
                    swept_rad: 0.0,
                }),
            }
        }
        segments
    }

    /// Indices of the beams that report the same angle, bin size and bin
    /// count as the beam before them: the head pinged twice without
    /// stepping. In both committed Ping360 logs that have one, the beam
    /// before the repeat came several beam periods late. In
    /// `Sensor_Log_01__inside_base.bin` the two 10 m turns on either side of
    /// its repeat (beam 931, 45.86 s) image the same walls 7-8 grad apart
    /// in angle: the head's heading (or its angle reference) moved there,
    /// so rotations should not be compared across a repeat without checking
    /// (see `datasets/tests/ping360_logs.rs`).
    pub fn repeated_angles(&self) -> Vec<usize> {
        (1..self.beams.len())
            .filter(|&i| {
                let (a, b) = (&self.beams[i - 1], &self.beams[i]);
                a.angle_rad == b.angle_rad
                    && a.intensities.len() == b.intensities.len()
                    && (a.bin_size_m - b.bin_size_m).abs() < 1e-6
            })
            .collect()
    }

    /// A mission holding only these beams (no navigation), named after the
    /// file stem.
    pub fn to_mission(&self) -> Mission {
        let name = self
            .path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        Mission {
            name,
            beams: self.beams.clone(),
            ..Mission::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn beam(angle_rad: f64, bin_size_m: f64, bins: usize) -> SonarBeam {
        SonarBeam {
            stamp_s: 0.0,
            angle_rad,
            bin_size_m,
            first_bin_range_m: 0.0,
            intensities: vec![0; bins],
        }
    }

    /// A recording of `beams` from a file `x.bin`.
    fn recording(beams: Vec<SonarBeam>) -> SonarRecording {
        SonarRecording {
            path: PathBuf::from("x.bin"),
            device: String::new(),
            info: Vec::new(),
            beams,
            stats: ReadStats::default(),
        }
    }

    #[test]
    fn segments_split_on_bin_size_or_count_and_sum_the_sweep() {
        let mut beams: Vec<_> = (0..5)
            .map(|i| beam(f64::from(i) * 0.5 * PI, 0.1, 10))
            .collect();
        beams.push(beam(0.0, 0.2, 10));
        beams.push(beam(0.1, 0.2, 20));
        let rec = recording(beams);
        let segs = rec.range_segments();
        assert_eq!(segs.len(), 3);
        assert_eq!((segs[0].first_beam, segs[0].beam_count), (0, 5));
        // Four quarter turns, one of them across ±π.
        assert!((segs[0].swept_rad - 2.0 * PI).abs() < 1e-12);
        assert_eq!(
            (segs[1].first_beam, segs[2].first_beam, segs[2].bins),
            (5, 6, 20)
        );
        assert!((segs[2].range_m() - 4.0).abs() < 1e-12);
        assert_eq!(rec.to_mission().name, "x");
        // Beam 6 repeats no angle (its bin count differs from beam 5's).
        assert!(rec.repeated_angles().is_empty());
    }

    #[test]
    fn a_repeated_angle_with_the_same_geometry_is_listed() {
        let mut beams: Vec<_> = [0.1, 0.2, 0.2, 0.3, 0.3]
            .iter()
            .map(|&a| beam(a, 0.1, 10))
            .collect();
        beams[4].bin_size_m = 0.2;
        let rec = recording(beams);
        assert_eq!(rec.repeated_angles(), vec![2]);
    }
}
