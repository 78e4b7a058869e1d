//! Reader of Blue Robotics Ping360 sensor logs written by Ping Viewer (`.bin`).
//!
//! The file is a Qt data stream of time-stamped raw serial chunks
//! (`qt_stream`); the chunks are joined and parsed as Ping protocol
//! messages ([`protocol`]); every `device_data` message (id 2300) becomes one
//! [`SonarBeam`]:
//! - `stamp_s`: the time stamp of the record holding the message's last byte,
//!   in seconds **since the log began** (the file carries no absolute clock;
//!   the date in the header is the viewer's build date).
//! - `angle_rad`: `2π·angle/400` wrapped to (−π, π], in the head's own
//!   direction of rotation (the head frame is the device's; its handedness
//!   seen from above depends on the mounting).
//! - `bin_size_m`: `0.5 · 1500 m/s · sample_period · 25 ns`; bins start at 0.
//! - `intensities`: the 8-bit samples, `number_of_samples` of them.
//!
//! Gain, pulse length and transmit frequency are not part of a beam; they
//! are listed in [`ReadStats::settings_changes`] (the committed logs start
//! each range setting at low gain and switch to high gain a few dozen beams
//! later). [`SonarRecording::repeated_angles`] lists the beams where the
//! head pinged twice at one angle (after a late reply in these logs); the
//! head's heading moved by 7-8 grad across the one in `inside_base`.
//! Sector sweeps of a Ping360 show a small direction-dependent angle lag,
//! ~0.46 grad per direction; `echofield_frontend::sweep_lag` estimates and
//! corrects it (the reader reports the angles as the head sent them).
//!
//! Logs begin with pings at the 2 m default before the user's range applies,
//! and users change the range during a log: beams are kept in file order
//! with their own bin size and count, and
//! [`SonarRecording::range_segments`] lists the changes (the frontend's
//! rotation assembly splits there).
//!
//! # Damaged files
//! - Not a Ping Viewer log (bad magic, short header): [`DatasetError::Format`].
//! - A broken record after the header (length past the end of the file,
//!   unreadable or decreasing time stamp): reading stops there, the beams
//!   before are kept, and [`ReadStats::stopped_early`] names record, byte and
//!   field.
//! - Bad checksum: counted, the parser resynchronises on the next `"BR"`.
//!   Incomplete final message: counted in `truncated_tail_bytes`.
//!   A `device_data` with inconsistent lengths or an angle ≥ 400: counted in
//!   `bad_beam_messages` and skipped.
//! - No beam at all: [`DatasetError::Missing`].
//!
//! # Example
//!
//! ```
//! let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
//!     .join("msis-real/ping360/Corrupted__20210619-213338492.bin");
//! let recording = echofield_datasets::ping360::read_ping360(&path)?;
//! assert_eq!(recording.stats.truncated_tail_bytes, 279); // its last message is cut
//! assert_eq!(recording.range_segments().len(), 5); // five range settings
//! # Ok::<(), echofield_datasets::DatasetError>(())
//! ```

pub mod protocol;
mod qt_stream;
pub mod timestamp;

use crate::error::DatasetError;
use crate::sonar_recording::{ReadStats, SettingsChange, SonarRecording};
use echofield_frontend::sensors::SonarBeam;
use echofield_graph::wrap_angle;
use protocol::{DEVICE_DATA_ID, GRADIANS_PER_TURN};
use std::f64::consts::TAU;
use std::path::Path;

/// Reads a Ping Viewer `.bin` log (see the module doc for the damaged-file
/// policy).
pub fn read_ping360(path: &Path) -> Result<SonarRecording, DatasetError> {
    let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, e))?;
    let container = qt_stream::read_container(path, &bytes)?;
    let framing = protocol::parse_messages(&container.stream);
    let mut stats = ReadStats {
        records: container.chunks.len(),
        messages: framing.messages.len(),
        bad_checksums: framing.bad_checksums,
        skipped_bytes: framing.skipped_bytes,
        truncated_tail_bytes: framing.truncated_tail_bytes,
        stopped_early: container.stopped_early,
        ..ReadStats::default()
    };
    let mut beams = Vec::new();
    for message in &framing.messages {
        if message.id != DEVICE_DATA_ID {
            *stats
                .other_messages
                .entry(format!("id {}", message.id))
                .or_default() += 1;
            continue;
        }
        let Ok(data) = protocol::decode_device_data(&container.stream[message.payload.clone()])
        else {
            stats.bad_beam_messages += 1;
            continue;
        };
        // The record that delivered the last byte (the checksum) of the message.
        let last_byte = message.payload.end + 1;
        let chunk = container
            .chunks
            .partition_point(|c| c.stream_offset <= last_byte)
            - 1;
        let stamp_s = container.chunks[chunk].elapsed_s;
        stats.record_settings(SettingsChange {
            first_beam: beams.len(),
            stamp_s,
            gain_setting: data.gain_setting,
            transmit_duration_us: f64::from(data.transmit_duration_us),
            transmit_frequency_khz: f64::from(data.transmit_frequency_khz),
        });
        beams.push(SonarBeam {
            stamp_s,
            angle_rad: wrap_angle(f64::from(data.angle_grad) * TAU / GRADIANS_PER_TURN),
            bin_size_m: data.bin_size_m(),
            first_bin_range_m: 0.0,
            intensities: data.data.to_vec(),
        });
    }
    if beams.is_empty() {
        return Err(no_beams(path, &stats));
    }
    Ok(SonarRecording {
        path: path.to_path_buf(),
        device: "Blue Robotics Ping360".into(),
        info: container.info,
        beams,
        stats,
    })
}

/// The error of a log without a readable beam, with what was read.
fn no_beams(path: &Path, stats: &ReadStats) -> DatasetError {
    DatasetError::Missing {
        path: path.to_path_buf(),
        what: format!(
            "Ping360 device_data messages (read {} records, {} good messages, {} bad checksums{})",
            stats.records,
            stats.messages,
            stats.bad_checksums,
            stats
                .stopped_early
                .as_ref()
                .map(|s| format!("; stopped at {s}"))
                .unwrap_or_default()
        ),
    }
}

impl ReadStats {
    /// Appends `settings` to `settings_changes` when the gain, transmit
    /// duration or frequency differs from the last change recorded (or
    /// none is).
    fn record_settings(&mut self, settings: SettingsChange) {
        let changed = self.settings_changes.last().is_none_or(|last| {
            (
                last.gain_setting,
                last.transmit_duration_us,
                last.transmit_frequency_khz,
            ) != (
                settings.gain_setting,
                settings.transmit_duration_us,
                settings.transmit_frequency_khz,
            )
        });
        if changed {
            self.settings_changes.push(settings);
        }
    }
}
