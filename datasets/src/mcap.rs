//! Missions as MCAP files that standard tools (Foxglove, the `mcap` CLI, the
//! Python `mcap` package) can open.
//!
//! # echofield's own format
//!
//! One channel per sensor stream, JSON messages described by JSON Schemas
//! (message encoding `json`, schema encoding `jsonschema`), zstd-compressed
//! chunks, and the mission name and sensor mounting in a Metadata record named
//! [`METADATA_NAME`]. Every message is logged with `log_time = stamp_s · 10⁹`
//! (rounded to the nearest nanosecond); the exact stamp is the `stamp_s` field
//! of the message. Channels, schemas, fields, units and frames are documented
//! in `datasets/README.md`; the schema texts live in [`json`].
//!
//! | topic                | schema                     | sensor type        |
//! |----------------------|----------------------------|--------------------|
//! | `/sonar/beam`        | `echofield.SonarBeam`      | [`SonarBeam`]      |
//! | `/dvl/velocity`      | `echofield.DvlVelocity`    | [`DvlVelocity`]    |
//! | `/attitude`          | `echofield.Attitude`       | [`Attitude`]       |
//! | `/ground_truth/pose` | `echofield.GroundTruthPose`| [`GroundTruthPose`]|
//! | `/position/fix`      | `echofield.PositionFix`    | [`PositionFix`]    |
//!
//! # ROS recordings
//!
//! [`read_mission`] also reads MCAP files recorded by ROS 2 (`cdr` messages,
//! `ros2msg` schemas), and [`read_mission_with`] rosbag2 folders (MCAP or
//! sqlite3 storage) and ROS 1 bags, with the standard messages listed in
//! [`crate::ros::messages`] (sonar beams, DVL, heading, ground truth) and
//! the sonar mounting from `/tf_static` ([`crate::ros`]). Channels are
//! mapped to streams by type name, never by topic name, unless a topic is
//! chosen.
//!
//! # Reading rules
//!
//! - Each stream is stable-sorted by `stamp_s`: messages that arrive out of
//!   order are accepted and reordered, with a warning in `Mission::warnings`
//!   that counts them per stream and names the first; messages with exactly
//!   equal stamps are all kept, in file order.
//! - NaN or infinite values, negative stamps, non-positive bin sizes, empty
//!   beams, a corrupt or truncated container, and an unknown schema on an
//!   echofield topic are errors that name the file, the message (index in file
//!   order, from 0, with its topic) and the field. Bad input never panics.
//! - Channels the reader does not know (cameras, `/tf`, Foxglove outputs) are
//!   skipped. A stream is fed by the topic chosen for it
//!   ([`TopicChoice`], `--topic ROLE=/name`), or else by the only topic of
//!   a type it reads; several such topics without a choice are an error
//!   that names them. [`read_mission_with`] says what became of every
//!   channel ([`ChannelUse`]) and also reads rosbag2 folders with MCAP
//!   storage ([`rosbag2`]).
//!
//! # Example
//!
//! ```
//! use echofield_datasets::mcap::{read_mission, write_mission};
//! use echofield_frontend::sensors::{Mission, SonarBeam};
//!
//! let dir = tempfile::tempdir().unwrap();
//! let path = dir.path().join("mission.mcap");
//! let mission = Mission {
//!     name: "doc".into(),
//!     beams: vec![SonarBeam {
//!         stamp_s: 1.5,
//!         angle_rad: 0.25,
//!         bin_size_m: 0.1,
//!         first_bin_range_m: 0.0,
//!         intensities: vec![0, 10, 200],
//!     }],
//!     ..Mission::default()
//! };
//! write_mission(&path, &mission).unwrap();
//! assert_eq!(read_mission(&path).unwrap(), mission);
//! ```

pub(crate) mod cdr;
pub mod fixture;
pub mod foxglove;
pub mod json;
mod reader;
pub mod ros2;
pub mod rosbag2;
pub(crate) mod validate;
mod writer;

pub use reader::{ChannelUse, ROLES, TopicChoice, read_mission, read_mission_with};
pub use ros2::{Ros2GroundTruth, write_mission_ros2};
pub use writer::{CompletedMcap, MissionWriter};

use crate::DatasetError;
use echofield_frontend::sensors::Mission;
#[cfg(doc)]
use echofield_frontend::sensors::{Attitude, DvlVelocity, GroundTruthPose, PositionFix, SonarBeam};
use std::path::Path;

/// Topic of the sonar beams.
pub const TOPIC_BEAM: &str = "/sonar/beam";
/// Topic of the DVL velocities.
pub const TOPIC_DVL: &str = "/dvl/velocity";
/// Topic of the attitude samples.
pub const TOPIC_ATTITUDE: &str = "/attitude";
/// Topic of the ground-truth poses.
pub const TOPIC_GROUND_TRUTH: &str = "/ground_truth/pose";
/// Topic of the position fixes (optional; a prior for merging missions).
pub const TOPIC_POSITION_FIX: &str = "/position/fix";
/// Name of the Metadata record that holds the mission name and mounting.
pub const METADATA_NAME: &str = "echofield.mission";
/// Value of the `format_version` key of that record.
pub const FORMAT_VERSION: &str = "1";

/// Writes a whole mission to `path` atomically: the file is written to a
/// temporary file in the destination folder and renamed over `path` only when
/// complete, so `path` is never half-written.
///
/// Messages of all streams are interleaved by stamp (stable for equal stamps).
/// Fails without touching `path` if a record holds a NaN/infinite value, a
/// negative stamp, a non-positive bin size or an empty beam; the error names
/// the record (`beam 12`, `dvl 3`, ...) and the field.
pub fn write_mission(path: &Path, mission: &Mission) -> Result<(), DatasetError> {
    validate::mission(path, mission)?;
    let mut writer = MissionWriter::create(path, &mission.name, &mission.mounting)?;
    // Interleave the streams by stamp so the file is in log-time order.
    let mut order: Vec<(f64, u8, usize)> = Vec::with_capacity(
        mission.beams.len()
            + mission.dvl.len()
            + mission.attitude.len()
            + mission.ground_truth.len()
            + mission.position_fixes.len(),
    );
    order.extend(
        mission
            .beams
            .iter()
            .enumerate()
            .map(|(i, r)| (r.stamp_s, 0, i)),
    );
    order.extend(
        mission
            .dvl
            .iter()
            .enumerate()
            .map(|(i, r)| (r.stamp_s, 1, i)),
    );
    order.extend(
        mission
            .attitude
            .iter()
            .enumerate()
            .map(|(i, r)| (r.stamp_s, 2, i)),
    );
    order.extend(
        mission
            .ground_truth
            .iter()
            .enumerate()
            .map(|(i, r)| (r.stamp_s, 3, i)),
    );
    order.extend(
        mission
            .position_fixes
            .iter()
            .enumerate()
            .map(|(i, r)| (r.stamp_s, 4, i)),
    );
    order.sort_by(|a, b| a.0.total_cmp(&b.0));
    for (_, stream, i) in order {
        match stream {
            0 => writer.write_beam(&mission.beams[i])?,
            1 => writer.write_dvl(&mission.dvl[i])?,
            2 => writer.write_attitude(&mission.attitude[i])?,
            3 => writer.write_ground_truth(&mission.ground_truth[i])?,
            _ => writer.write_position_fix(&mission.position_fixes[i])?,
        }
    }
    writer.finish()
}
