//! Streaming, atomic MCAP writing.
//!
//! [`MissionWriter`] writes one message at a time, so a long mission (or the
//! SLAM pipeline's output) never has to be held in memory. The file goes to a
//! temporary file beside the destination and is renamed over it by
//! [`MissionWriter::finish`]; dropping the writer without `finish` leaves the
//! destination untouched and removes the temporary file.

mod canonical;

use super::validate::{self, FieldError};
use super::{FORMAT_VERSION, METADATA_NAME, TOPIC_ATTITUDE, TOPIC_BEAM, TOPIC_DVL};
use super::{TOPIC_GROUND_TRUTH, TOPIC_POSITION_FIX, json};
use crate::DatasetError;
use echofield_frontend::sensors::{
    Attitude, DvlVelocity, GroundTruthPose, PositionFix, SensorMounting, SonarBeam,
};
use mcap::records::{MessageHeader, Metadata};
use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// An MCAP file being written to a temporary file, renamed into place on
/// [`McapFile::finish`]. Shared by the echofield and ROS 2 writers.
pub(crate) struct McapFile {
    // Declared first so that on drop it finishes into the temporary file
    // before `temp` deletes it.
    mcap: mcap::Writer<BufWriter<File>>,
    temp: tempfile::TempPath,
    path: PathBuf,
    /// topic -> (channel id, schema name, messages written).
    channels: HashMap<String, (u16, String, u32)>,
}

fn mcap_error(path: &Path, err: mcap::McapError) -> DatasetError {
    match err {
        mcap::McapError::Io(source) => DatasetError::io(path, source),
        other => DatasetError::Format {
            path: path.to_path_buf(),
            message: format!("MCAP writer: {other}"),
        },
    }
}

impl McapFile {
    pub fn create(path: &Path) -> Result<Self, DatasetError> {
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        // `.echofield-{pid}-`: the owner's pid lets a later run tell the
        // temporary file of a killed run from one being written
        // (`echofield::output::stale`).
        let prefix = format!(".echofield-{}-", std::process::id());
        let temp = tempfile::Builder::new()
            .prefix(&prefix)
            .suffix(".mcap.tmp")
            .tempfile_in(dir)
            .map_err(|e| DatasetError::io(dir, e))?;
        let (file, temp) = temp.into_parts();
        let options = mcap::WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            // zstd's fastest level: most of a results file is base64 PNG,
            // which the default level 3 barely shrinks further. On the St
            // Pere replay's `mission.mcap` (`cargo bench -p echofield
            // --bench outputs`): 168 -> 137 ms, 10.17 -> 10.27 MB.
            .compression_level(1)
            // Single-threaded zstd: the bytes must not depend on the machine.
            .compression_threads(0)
            .library(format!("echofield-datasets {}", env!("CARGO_PKG_VERSION")));
        let mcap = options
            .create(BufWriter::with_capacity(1 << 20, file))
            .map_err(|e| mcap_error(path, e))?;
        Ok(Self {
            mcap,
            temp,
            path: path.to_path_buf(),
            channels: HashMap::new(),
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The channel of `topic`, created with this schema on first use. A topic
    /// already used with another schema is an error.
    pub fn channel(
        &mut self,
        topic: &str,
        schema_name: &str,
        schema_encoding: &str,
        schema: impl FnOnce() -> String,
        message_encoding: &str,
    ) -> Result<u16, DatasetError> {
        if let Some((id, name, _)) = self.channels.get(topic) {
            if name != schema_name {
                return Err(DatasetError::Format {
                    path: self.path.clone(),
                    message: format!(
                        "topic `{topic}` already carries `{name}`, cannot also write `{schema_name}`"
                    ),
                });
            }
            return Ok(*id);
        }
        let schema_id = self
            .mcap
            .add_schema(schema_name, schema_encoding, schema().as_bytes())
            .map_err(|e| mcap_error(&self.path, e))?;
        let id = self
            .mcap
            .add_channel(schema_id, topic, message_encoding, &BTreeMap::new())
            .map_err(|e| mcap_error(&self.path, e))?;
        self.channels
            .insert(topic.to_string(), (id, schema_name.to_string(), 0));
        Ok(id)
    }

    /// Writes one message on `topic` (whose channel must exist).
    pub fn write(
        &mut self,
        topic: &str,
        log_time_ns: u64,
        data: &[u8],
    ) -> Result<(), DatasetError> {
        let Some((id, _, sequence)) = self.channels.get_mut(topic) else {
            return Err(DatasetError::Format {
                path: self.path.clone(),
                message: format!("no channel for topic `{topic}`"),
            });
        };
        *sequence = sequence.wrapping_add(1);
        let header = MessageHeader {
            channel_id: *id,
            sequence: *sequence,
            log_time: log_time_ns,
            publish_time: log_time_ns,
        };
        self.mcap
            .write_to_known_channel(&header, data)
            .map_err(|e| mcap_error(&self.path, e))
    }

    pub fn metadata(
        &mut self,
        name: &str,
        values: BTreeMap<String, String>,
    ) -> Result<(), DatasetError> {
        let record = Metadata {
            name: name.to_string(),
            metadata: values,
        };
        self.mcap
            .write_metadata(&record)
            .map_err(|e| mcap_error(&self.path, e))
    }

    /// Completes the file, syncs it and renames it over the destination.
    pub fn finish(self) -> Result<(), DatasetError> {
        self.complete()?.persist()
    }

    /// Completes and syncs the temporary file without renaming it: the
    /// destination changes only with [`CompletedMcap::persist`].
    pub fn complete(mut self) -> Result<CompletedMcap, DatasetError> {
        let path = self.path.clone();
        self.mcap.finish().map_err(|e| mcap_error(&path, e))?;
        let mut file = self
            .mcap
            .into_inner()
            .into_inner()
            .map_err(|e| DatasetError::io(&path, e.into_error()))?;
        canonical::sort_summary(&mut file).map_err(|e| DatasetError::io(&path, e))?;
        file.sync_all().map_err(|e| DatasetError::io(&path, e))?;
        set_readable(&file);
        drop(file);
        Ok(CompletedMcap {
            temp: self.temp,
            path,
        })
    }
}

/// A complete MCAP file still at its temporary path
/// ([`MissionWriter::complete`]). [`CompletedMcap::persist`] renames it
/// over the destination; dropping it removes it and leaves the
/// destination untouched.
#[derive(Debug)]
pub struct CompletedMcap {
    temp: tempfile::TempPath,
    path: PathBuf,
}

impl CompletedMcap {
    /// The destination.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Renames the file over the destination.
    pub fn persist(self) -> Result<(), DatasetError> {
        let path = self.path;
        self.temp
            .persist(&path)
            .map_err(|e| DatasetError::io(&path, e.error))?;
        Ok(())
    }
}

/// Temporary files are created 0600; a mission file is an ordinary file.
#[cfg(unix)]
fn set_readable(file: &File) {
    use std::os::unix::fs::PermissionsExt;
    // Failing to widen permissions leaves a private but valid file.
    let _ = file.set_permissions(std::fs::Permissions::from_mode(0o644));
}

#[cfg(not(unix))]
fn set_readable(_file: &File) {}

/// Streams a mission into an MCAP file, one record at a time.
///
/// ```
/// use echofield_datasets::mcap::MissionWriter;
/// use echofield_frontend::sensors::{Attitude, SensorMounting};
///
/// let dir = tempfile::tempdir().unwrap();
/// let path = dir.path().join("nav.mcap");
/// let mut writer = MissionWriter::create(&path, "nav only", &SensorMounting::default()).unwrap();
/// for k in 0..10 {
///     let att = Attitude { stamp_s: k as f64 * 0.1, roll_rad: 0.0, pitch_rad: 0.0, yaw_rad: 0.3, yaw_rate_radps: None };
///     writer.write_attitude(&att).unwrap();
/// }
/// writer.finish().unwrap();
/// let mission = echofield_datasets::mcap::read_mission(&path).unwrap();
/// assert_eq!(mission.attitude.len(), 10);
/// ```
pub struct MissionWriter {
    pub(crate) file: McapFile,
    buf: Vec<u8>,
    counts: [usize; 5],
}

impl MissionWriter {
    /// Starts a mission file at `path` (written to a temporary file until
    /// [`finish`](Self::finish)) and records the name and mounting in the
    /// `echofield.mission` Metadata record.
    pub fn create(
        path: &Path,
        name: &str,
        mounting: &SensorMounting,
    ) -> Result<Self, DatasetError> {
        validate::mounting(mounting).map_err(|e| e.at(path, "mission"))?;
        let mut file = McapFile::create(path)?;
        let mounting_json =
            serde_json::to_string(mounting).expect("JSON serialisation of the mounting");
        let values = BTreeMap::from([
            ("format".to_string(), "echofield-mission".to_string()),
            ("format_version".to_string(), FORMAT_VERSION.to_string()),
            ("name".to_string(), name.to_string()),
            ("mounting".to_string(), mounting_json),
        ]);
        file.metadata(METADATA_NAME, values)?;
        Ok(Self {
            file,
            buf: Vec::with_capacity(1024),
            counts: [0; 5],
        })
    }

    /// The destination path (not the temporary file).
    pub fn path(&self) -> &Path {
        self.file.path()
    }

    fn write_record(
        &mut self,
        stream: usize,
        stamp_s: f64,
        check: Result<(), FieldError>,
        channel: (&str, &str, fn() -> String),
        encode: impl FnOnce(&mut Vec<u8>),
    ) -> Result<(), DatasetError> {
        const NAMES: [&str; 5] = ["beam", "dvl", "attitude", "ground_truth", "position_fix"];
        let index = self.counts[stream];
        check.map_err(|e| e.at(self.file.path(), format!("{} {index}", NAMES[stream])))?;
        let (topic, schema_name, schema) = channel;
        self.file.channel(
            topic,
            schema_name,
            json::SCHEMA_ENCODING,
            schema,
            json::MESSAGE_ENCODING,
        )?;
        encode(&mut self.buf);
        self.file
            .write(topic, validate::log_time_ns(stamp_s), &self.buf)?;
        self.counts[stream] += 1;
        Ok(())
    }

    /// Writes one beam on `/sonar/beam`.
    pub fn write_beam(&mut self, beam: &SonarBeam) -> Result<(), DatasetError> {
        let channel = (
            TOPIC_BEAM,
            json::BEAM_SCHEMA_NAME,
            json::beam_schema as fn() -> String,
        );
        self.write_record(0, beam.stamp_s, validate::beam(beam), channel, |out| {
            json::encode_beam(beam, out)
        })
    }

    /// Writes one DVL sample on `/dvl/velocity`.
    pub fn write_dvl(&mut self, dvl: &DvlVelocity) -> Result<(), DatasetError> {
        let channel = (
            TOPIC_DVL,
            json::DVL_SCHEMA_NAME,
            json::dvl_schema as fn() -> String,
        );
        self.write_record(1, dvl.stamp_s, validate::dvl(dvl), channel, |out| {
            json::encode_dvl(dvl, out)
        })
    }

    /// Writes one attitude sample on `/attitude`.
    pub fn write_attitude(&mut self, att: &Attitude) -> Result<(), DatasetError> {
        let channel = (
            TOPIC_ATTITUDE,
            json::ATTITUDE_SCHEMA_NAME,
            json::attitude_schema as fn() -> String,
        );
        self.write_record(2, att.stamp_s, validate::attitude(att), channel, |out| {
            json::encode_attitude(att, out)
        })
    }

    /// Writes one ground-truth pose on `/ground_truth/pose`.
    pub fn write_ground_truth(&mut self, gt: &GroundTruthPose) -> Result<(), DatasetError> {
        let channel = (
            TOPIC_GROUND_TRUTH,
            json::GROUND_TRUTH_SCHEMA_NAME,
            json::ground_truth_schema as fn() -> String,
        );
        self.write_record(3, gt.stamp_s, validate::ground_truth(gt), channel, |out| {
            json::encode_ground_truth(gt, out)
        })
    }

    /// Writes one position fix on `/position/fix`.
    pub fn write_position_fix(&mut self, fix: &PositionFix) -> Result<(), DatasetError> {
        let channel = (
            TOPIC_POSITION_FIX,
            json::POSITION_FIX_SCHEMA_NAME,
            json::position_fix_schema as fn() -> String,
        );
        self.write_record(
            4,
            fix.stamp_s,
            validate::position_fix(fix),
            channel,
            |out| json::encode_position_fix(fix, out),
        )
    }

    /// Completes the file and renames it over the destination.
    pub fn finish(self) -> Result<(), DatasetError> {
        self.file.finish()
    }

    /// Completes the file but leaves the destination as it is until
    /// [`CompletedMcap::persist`]: for a file written beside others that
    /// must replace its old version only once they have.
    pub fn complete(self) -> Result<CompletedMcap, DatasetError> {
        self.file.complete()
    }
}
