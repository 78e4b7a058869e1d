//! [`read_mission`]: one pass over the MCAP records, decoding the channels
//! that map to a sensor stream and skipping the others.

mod container;

use super::ros2::{self, Ros2Kind};
use super::validate::{self, FieldError};
use super::{FORMAT_VERSION, METADATA_NAME, json};
use super::{TOPIC_ATTITUDE, TOPIC_BEAM, TOPIC_DVL, TOPIC_GROUND_TRUTH};
use crate::DatasetError;
use echofield_frontend::sensors::{
    Attitude, DvlVelocity, GroundTruthPose, Mission, SensorMounting, SonarBeam,
};
use echofield_frontend::warnings::{Warning, WarningKind};
use mcap::records::Record;
use std::collections::HashMap;
use std::fs::File;
use std::path::{Path, PathBuf};

/// One decoded sensor record.
#[derive(Debug)]
pub(crate) enum Decoded {
    Beam(SonarBeam),
    Dvl(DvlVelocity),
    Attitude(Attitude),
    GroundTruth(GroundTruthPose),
}

/// The sensor streams of a mission, in `Mission` field order.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stream {
    Beam,
    Dvl,
    Attitude,
    GroundTruth,
}

const STREAM_NAMES: [&str; 4] = ["sonar beams", "DVL", "attitude", "ground truth"];

#[derive(Debug, Clone, Copy)]
enum Decoder {
    Json(Stream),
    Ros2(Ros2Kind),
}

impl Decoder {
    fn stream(self) -> Stream {
        match self {
            Decoder::Json(s) => s,
            Decoder::Ros2(Ros2Kind::Imu) => Stream::Attitude,
            Decoder::Ros2(Ros2Kind::TwistWithCovarianceStamped) => Stream::Dvl,
            Decoder::Ros2(Ros2Kind::Odometry | Ros2Kind::PoseStamped) => Stream::GroundTruth,
            Decoder::Ros2(Ros2Kind::SonarBeam) => Stream::Beam,
        }
    }
}

/// Reads a mission from an echofield or ROS 2 MCAP file (see the module
/// documentation of [`crate::mcap`] for the rules: sorting, duplicates,
/// skipped channels, errors).
///
/// Files without the `echofield.mission` metadata (ROS 2 recordings) get the
/// file stem as name and the identity mounting marked
/// [`MountingSource::Assumed`](echofield_frontend::sensors::MountingSource):
/// nothing in the file says where the sonar head sits, and the pipeline
/// warns about it.
pub fn read_mission(path: &Path) -> Result<Mission, DatasetError> {
    let file = File::open(path).map_err(|e| DatasetError::io(path, e))?;
    let len = file
        .metadata()
        .map_err(|e| DatasetError::io(path, e))?
        .len();
    let mut state = State::new(path);
    container::for_each_record(path, file, len, |record| state.on_record(record))?;
    state.finish()
}

struct Channel {
    topic: String,
    decoder: Option<Decoder>,
}

struct State {
    path: PathBuf,
    /// schema id -> (name, encoding)
    schemas: HashMap<u16, (String, String)>,
    channels: HashMap<u16, Channel>,
    /// The topic that feeds each stream.
    stream_topics: [Option<String>; 4],
    messages: u64,
    metadata: Option<(String, SensorMounting)>,
    mission: Mission,
}

impl State {
    fn new(path: &Path) -> Self {
        Self {
            path: path.to_path_buf(),
            schemas: HashMap::new(),
            channels: HashMap::new(),
            stream_topics: Default::default(),
            messages: 0,
            metadata: None,
            mission: Mission::default(),
        }
    }

    fn format_error(&self, message: String) -> DatasetError {
        DatasetError::Format {
            path: self.path.clone(),
            message,
        }
    }

    fn on_record(&mut self, record: Record<'_>) -> Result<(), DatasetError> {
        match record {
            Record::Schema { header, .. } => {
                self.schemas
                    .insert(header.id, (header.name, header.encoding));
            }
            Record::Channel(channel) => self.on_channel(channel)?,
            Record::Message { header, data } => {
                let index = self.messages;
                self.messages += 1;
                self.on_message(index, header.channel_id, header.log_time, &data)?;
            }
            Record::Metadata(metadata) if metadata.name == METADATA_NAME => {
                self.on_metadata(&metadata.metadata)?;
            }
            _ => {}
        }
        Ok(())
    }

    fn on_channel(&mut self, channel: mcap::records::Channel) -> Result<(), DatasetError> {
        // The summary section repeats channels; the first record decides.
        if self.channels.contains_key(&channel.id) {
            return Ok(());
        }
        let schema = if channel.schema_id == 0 {
            None
        } else {
            let found = self.schemas.get(&channel.schema_id);
            Some(found.ok_or_else(|| {
                self.format_error(format!(
                    "channel `{}` refers to schema id {} which has no Schema record before it",
                    channel.topic, channel.schema_id
                ))
            })?)
        };
        let decoder = classify(&channel.topic, &channel.message_encoding, schema)
            .map_err(|message| self.format_error(message))?;
        if let Some(decoder) = decoder {
            let slot = &mut self.stream_topics[decoder.stream() as usize];
            if let Some(other) = slot {
                return Err(DatasetError::Format {
                    path: self.path.clone(),
                    message: format!(
                        "topics `{other}` and `{}` both carry {}; keep one of them in the file",
                        channel.topic,
                        STREAM_NAMES[decoder.stream() as usize]
                    ),
                });
            }
            *slot = Some(channel.topic.clone());
        }
        self.channels.insert(
            channel.id,
            Channel {
                topic: channel.topic,
                decoder,
            },
        );
        Ok(())
    }

    fn on_message(
        &mut self,
        index: u64,
        channel_id: u16,
        log_time_ns: u64,
        data: &[u8],
    ) -> Result<(), DatasetError> {
        let Some(channel) = self.channels.get(&channel_id) else {
            return Err(self.format_error(format!(
                "message {index} refers to channel id {channel_id} which has no Channel record before it"
            )));
        };
        let Some(decoder) = channel.decoder else {
            return Ok(());
        };
        let decoded = match decoder {
            Decoder::Json(Stream::Beam) => json::decode_beam(data).map(Decoded::Beam),
            Decoder::Json(Stream::Dvl) => json::decode_dvl(data).map(Decoded::Dvl),
            Decoder::Json(Stream::Attitude) => json::decode_attitude(data).map(Decoded::Attitude),
            Decoder::Json(Stream::GroundTruth) => {
                json::decode_ground_truth(data).map(Decoded::GroundTruth)
            }
            Decoder::Ros2(kind) => ros2::decode(kind, data, log_time_ns),
        };
        let decoded = decoded.map_err(|e: FieldError| {
            e.at(
                &self.path,
                format!("message {index} (topic `{}`)", channel.topic),
            )
        })?;
        match decoded {
            Decoded::Beam(b) => self.mission.beams.push(b),
            Decoded::Dvl(d) => self.mission.dvl.push(d),
            Decoded::Attitude(a) => self.mission.attitude.push(a),
            Decoded::GroundTruth(g) => self.mission.ground_truth.push(g),
        }
        Ok(())
    }

    fn on_metadata(
        &mut self,
        values: &std::collections::BTreeMap<String, String>,
    ) -> Result<(), DatasetError> {
        let record = format!("metadata `{METADATA_NAME}`");
        let get = |key: &str| {
            values
                .get(key)
                .ok_or_else(|| DatasetError::parse(&self.path, &record, key, "missing"))
        };
        let version = get("format_version")?;
        if version != FORMAT_VERSION {
            return Err(DatasetError::parse(
                &self.path,
                &record,
                "format_version",
                format!("version `{version}` is not the supported `{FORMAT_VERSION}`"),
            ));
        }
        let name = get("name")?.clone();
        let mounting: SensorMounting = json::parse_owned(get("mounting")?).map_err(|e| {
            let field = format!("mounting.{}", e.field);
            DatasetError::parse(&self.path, &record, field, e.message)
        })?;
        validate::mounting(&mounting).map_err(|e| e.at(&self.path, &record))?;
        self.metadata = Some((name, mounting));
        Ok(())
    }

    fn finish(self) -> Result<Mission, DatasetError> {
        let mut mission = self.mission;
        if self.metadata.is_none() && self.stream_topics.iter().all(Option::is_none) {
            let topics: Vec<&str> = self.channels.values().map(|c| c.topic.as_str()).collect();
            return Err(DatasetError::Missing {
                path: self.path,
                what: format!(
                    "echofield or ROS 2 mission channels (topics in the file: {})",
                    if topics.is_empty() {
                        "none".to_string()
                    } else {
                        topics.join(", ")
                    }
                ),
            });
        }
        match self.metadata {
            Some((name, mounting)) => {
                mission.name = name;
                mission.mounting = mounting;
            }
            None => {
                mission.mounting = SensorMounting::assumed_identity();
                mission.name = self
                    .path
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default();
            }
        }
        // Stable sorts: equal stamps keep their file order. Records that
        // went backwards are counted first (a warning for the report).
        let streams = [
            resorted(STREAM_NAMES[0], mission.beams.iter().map(|b| b.stamp_s)),
            resorted(STREAM_NAMES[1], mission.dvl.iter().map(|d| d.stamp_s)),
            resorted(STREAM_NAMES[2], mission.attitude.iter().map(|a| a.stamp_s)),
            resorted(
                STREAM_NAMES[3],
                mission.ground_truth.iter().map(|g| g.stamp_s),
            ),
        ];
        mission.warnings.extend(streams.into_iter().flatten());
        mission
            .beams
            .sort_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s));
        mission.dvl.sort_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s));
        mission
            .attitude
            .sort_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s));
        mission
            .ground_truth
            .sort_by(|a, b| a.stamp_s.total_cmp(&b.stamp_s));
        Ok(mission)
    }
}

/// A warning when some of `stamps` (one stream's records in file order)
/// are earlier than a record before them: how many, and the first of them
/// (its index among the stream's records in the file, and by how much it
/// went back).
fn resorted(stream: &str, stamps: impl Iterator<Item = f64>) -> Option<Warning> {
    let mut latest = f64::NEG_INFINITY;
    let (mut count, mut first) = (0usize, None);
    for (i, stamp) in stamps.enumerate() {
        if stamp < latest {
            count += 1;
            first.get_or_insert((i, latest - stamp));
        }
        latest = latest.max(stamp);
    }
    let (i, back_s) = first?;
    Some(
        Warning::new(
            WarningKind::StampsResorted,
            count,
            format!(
                "{count} {stream} records have stamps earlier than a record before them in the \
                 file (the first, record {i} of the stream, by {back_s:.3} s) and were re-sorted \
                 by time: check the logger's clock"
            ),
        )
        .at(format!("{stream} record {i}")),
    )
}

/// Which decoder a channel needs, `None` to skip it, or an error for a
/// channel that claims to be mission data in a form echofield cannot decode.
fn classify(
    topic: &str,
    message_encoding: &str,
    schema: Option<&(String, String)>,
) -> Result<Option<Decoder>, String> {
    let (name, schema_encoding) = match schema {
        Some((n, e)) => (n.as_str(), e.as_str()),
        None => ("", ""),
    };
    let json_stream = match name {
        json::BEAM_SCHEMA_NAME => Some(Stream::Beam),
        json::DVL_SCHEMA_NAME => Some(Stream::Dvl),
        json::ATTITUDE_SCHEMA_NAME => Some(Stream::Attitude),
        json::GROUND_TRUTH_SCHEMA_NAME => Some(Stream::GroundTruth),
        _ => None,
    };
    if let Some(stream) = json_stream {
        if message_encoding != json::MESSAGE_ENCODING || schema_encoding != json::SCHEMA_ENCODING {
            return Err(format!(
                "channel `{topic}`: schema `{name}` with message encoding `{message_encoding}` and schema encoding `{schema_encoding}` is not supported (expected `json` / `jsonschema`)"
            ));
        }
        return Ok(Some(Decoder::Json(stream)));
    }
    if let Some(kind) = Ros2Kind::from_schema_name(name) {
        if message_encoding != ros2::MESSAGE_ENCODING || schema_encoding != ros2::SCHEMA_ENCODING {
            return Err(format!(
                "channel `{topic}`: schema `{name}` with message encoding `{message_encoding}` and schema encoding `{schema_encoding}` is not supported (expected `cdr` / `ros2msg`)"
            ));
        }
        return Ok(Some(Decoder::Ros2(kind)));
    }
    if [TOPIC_BEAM, TOPIC_DVL, TOPIC_ATTITUDE, TOPIC_GROUND_TRUTH].contains(&topic) {
        return Err(format!(
            "channel `{topic}` is an echofield topic but has an unknown schema `{name}` (encoding `{schema_encoding}`, message encoding `{message_encoding}`)"
        ));
    }
    Ok(None)
}
