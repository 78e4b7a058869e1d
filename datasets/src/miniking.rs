//! Reader of Tritech MiniKing recordings in ROS 1 bags (`miniking_ros`).
//!
//! Every message of type `miniking_ros/AcousticBeam` (on any topic; the
//! driver publishes on `/miniking_node/sonar`) becomes one [`SonarBeam`]:
//! - `stamp_s`: the message's `header.stamp` (Unix seconds; the bag record
//!   time, ~85 ms later, when the stamp is zero).
//! - `angle_rad`: `angle` (degrees) converted and wrapped to (−π, π], in the
//!   head's own direction of rotation.
//! - `bin_size_m`: `range_max / bins`; bins start at 0.
//!
//! The bag container is read by [`bag`] (format 2.0, uncompressed chunks).
//!
//! # Damaged files
//! - Not a bag 2.0, compressed chunks, an AcousticBeam connection whose MD5
//!   differs from the known definition: [`DatasetError::Format`].
//! - A record running past the end of the file (a recording that was killed)
//!   or a broken record header: reading stops there, the beams before are
//!   kept, and [`ReadStats::stopped_early`] names record and byte.
//! - A beam message that does not decode (`bins` ≠ number of intensities,
//!   non-finite range or angle, short message) or whose stamp is earlier
//!   than the previous beam's: [`DatasetError::Parse`] naming message, byte
//!   offset and field.
//! - No AcousticBeam message: [`DatasetError::Missing`].
//!
//! # Example
//!
//! ```
//! let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
//!     .join("msis-real/miniking/full_sonar_scan_2015-05-26-11-38-04.bag");
//! let recording = echofield_datasets::miniking::read_miniking_bag(&path)?;
//! assert_eq!(recording.beams.len(), 875);
//! assert!((recording.beams[0].bin_size_m - 0.15).abs() < 1e-6); // 30 m / 200 bins
//! # Ok::<(), echofield_datasets::DatasetError>(())
//! ```

pub mod acoustic_beam;
pub mod bag;

use crate::error::DatasetError;
use crate::sonar_recording::{ReadStats, SonarRecording};
use acoustic_beam::{ACOUSTIC_BEAM_MD5, ACOUSTIC_BEAM_TYPE, decode_acoustic_beam};
use echofield_frontend::sensors::SonarBeam;
use echofield_graph::wrap_angle;
use std::path::Path;

/// Reads the AcousticBeam messages of a ROS 1 bag (see the module doc).
pub fn read_miniking_bag(path: &Path) -> Result<SonarRecording, DatasetError> {
    let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, e))?;
    let bag = bag::read_bag(path, &bytes)?;
    let info = connection_info(path, &bag)?;
    let mut stats = ReadStats {
        records: bag.records,
        messages: bag.messages.len(),
        stopped_early: bag.stopped_early,
        ..ReadStats::default()
    };
    let mut beams: Vec<SonarBeam> = Vec::new();
    for (index, message) in bag.messages.iter().enumerate() {
        let message_type = bag
            .connections
            .get(&message.conn)
            .map_or("unknown connection", |c| c.message_type.as_str());
        if message_type != ACOUSTIC_BEAM_TYPE {
            *stats
                .other_messages
                .entry(message_type.to_string())
                .or_default() += 1;
            continue;
        }
        let next = beam(path, index, message, beams.last())?;
        beams.push(next);
    }
    if beams.is_empty() {
        return Err(DatasetError::Missing {
            path: path.to_path_buf(),
            what: format!(
                "{ACOUSTIC_BEAM_TYPE} messages ({} messages read{})",
                stats.messages,
                stats
                    .stopped_early
                    .as_ref()
                    .map(|s| format!("; stopped at {s}"))
                    .unwrap_or_default()
            ),
        });
    }
    Ok(SonarRecording {
        path: path.to_path_buf(),
        device: "Tritech MiniKing".into(),
        info,
        beams,
        stats,
    })
}

/// `(connection N, topic [type])` of every connection; an error when an
/// AcousticBeam connection has another md5sum than the one decoded here.
fn connection_info(path: &Path, bag: &bag::Bag) -> Result<Vec<(String, String)>, DatasetError> {
    let mut info = Vec::new();
    for conn in bag.connections.values() {
        info.push((
            format!("connection {}", conn.id),
            format!("{} [{}]", conn.topic, conn.message_type),
        ));
        if conn.message_type == ACOUSTIC_BEAM_TYPE && conn.md5sum != ACOUSTIC_BEAM_MD5 {
            return Err(DatasetError::Format {
                path: path.to_path_buf(),
                message: format!(
                    "topic {}: {ACOUSTIC_BEAM_TYPE} with md5sum {}, this reader knows {ACOUSTIC_BEAM_MD5}",
                    conn.topic, conn.md5sum
                ),
            });
        }
    }
    Ok(info)
}

/// The beam of AcousticBeam message `index`, stamped with its header stamp
/// (the record time when that is 0). Errors name the message and field:
/// a message that does not decode, a stamp earlier than `prev`'s.
fn beam(
    path: &Path,
    index: usize,
    message: &bag::BagMessage,
    prev: Option<&SonarBeam>,
) -> Result<SonarBeam, DatasetError> {
    let record = format!("message {index} (byte {})", message.offset);
    let beam = decode_acoustic_beam(message.data)
        .map_err(|(field, msg)| DatasetError::parse(path, &record, field, msg))?;
    let stamp_s = if beam.stamp_s > 0.0 {
        beam.stamp_s
    } else {
        message.time_s
    };
    if let Some(prev) = prev
        && stamp_s < prev.stamp_s
    {
        return Err(DatasetError::parse(
            path,
            record,
            "header.stamp",
            format!(
                "{stamp_s} s is earlier than the previous beam's {} s",
                prev.stamp_s
            ),
        ));
    }
    Ok(SonarBeam {
        stamp_s,
        angle_rad: wrap_angle(f64::from(beam.angle_deg).to_radians()),
        bin_size_m: f64::from(beam.range_max_m) / f64::from(beam.bins),
        first_bin_range_m: 0.0,
        intensities: beam.intensities,
    })
}
