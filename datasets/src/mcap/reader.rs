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
    read_mission_with(path, &TopicChoice::default()).map(|(mission, _)| mission)
}

/// [`read_mission`] with the topics of each stream chosen by `choice`
/// (`--topic ROLE=/name`), also from a rosbag2 folder (`metadata.yaml`
/// with MCAP storage: its files in order); returns what became of every
/// channel. A stream fed by several topics of a supported type needs a
/// choice: without one it is an error that names them.
pub fn read_mission_with(
    path: &Path,
    choice: &TopicChoice,
) -> Result<(Mission, Vec<ChannelUse>), DatasetError> {
    let files = if path.is_dir() {
        super::rosbag2::mcap_files(path)?
    } else {
        vec![path.to_path_buf()]
    };
    let mut state = State::new(path, choice);
    for file_path in &files {
        let file = File::open(file_path).map_err(|e| DatasetError::io(file_path, e))?;
        let len = file
            .metadata()
            .map_err(|e| DatasetError::io(file_path, e))?
            .len();
        state.start_file(file_path);
        container::for_each_record(file_path, file, len, |record| state.on_record(record))?;
    }
    state.finish()
}

/// The roles a topic can be chosen for, as `--topic ROLE=/name` names them,
/// in [`Stream`] order.
pub const ROLES: [&str; 4] = ["sonar", "dvl", "heading", "ground_truth"];

/// The topic chosen for each stream (`None`: by message type, when only
/// one topic carries it).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TopicChoice {
    /// Indexed like [`ROLES`].
    pub topics: [Option<String>; 4],
}

impl TopicChoice {
    /// Records one `ROLE=/name` assignment; errors name what is wrong.
    pub fn assign(&mut self, text: &str) -> Result<(), String> {
        let (index, topic) = Self::parse_assignment(text)?;
        self.topics[index] = Some(topic);
        Ok(())
    }

    /// One `ROLE=/name` assignment as the role's index in [`ROLES`] and
    /// the topic; errors name what is wrong.
    pub fn parse_assignment(text: &str) -> Result<(usize, String), String> {
        let (role, topic) = text
            .split_once('=')
            .ok_or_else(|| format!("`{text}` is not ROLE=/topic"))?;
        let index = ROLES
            .iter()
            .position(|r| *r == role.trim().replace('-', "_"))
            .ok_or_else(|| format!("unknown role `{role}` (roles: {})", ROLES.join(", ")))?;
        let topic = topic.trim();
        if topic.is_empty() {
            return Err(format!("`{text}`: the topic is empty"));
        }
        Ok((index, topic.to_string()))
    }
}

/// What the reader did with one channel (topic) of the input.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ChannelUse {
    pub topic: String,
    /// Its schema (message type) name; empty without a schema.
    pub schema: String,
    /// The role it fed ([`ROLES`]), or `None` when skipped.
    pub role: Option<&'static str>,
    /// Why it was used or skipped.
    pub reason: String,
    /// Messages of the channel in the input.
    pub messages: u64,
}

struct Channel {
    topic: String,
    decoder: Option<Decoder>,
}

/// A topic seen in the input, with the records decoded from it when its
/// type feeds a stream (kept until [`State::finish`] chooses the topic of
/// each stream).
struct Topic {
    schema: String,
    decoder: Option<Decoder>,
    messages: u64,
    records: Vec<Decoded>,
}

struct State<'c> {
    path: PathBuf,
    /// The file being read (a rosbag2 folder has several).
    file: PathBuf,
    choice: &'c TopicChoice,
    /// schema id -> (name, encoding), of the current file.
    schemas: HashMap<u16, (String, String)>,
    /// channel id -> channel, of the current file.
    channels: HashMap<u16, Channel>,
    /// Every topic by name, in the order first seen.
    topics: Vec<(String, Topic)>,
    messages: u64,
    metadata: Option<(String, SensorMounting)>,
}

impl<'c> State<'c> {
    fn new(path: &Path, choice: &'c TopicChoice) -> Self {
        Self {
            path: path.to_path_buf(),
            file: path.to_path_buf(),
            choice,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            topics: Vec::new(),
            messages: 0,
            metadata: None,
        }
    }

    /// Schema and channel ids are per file.
    fn start_file(&mut self, file: &Path) {
        self.file = file.to_path_buf();
        self.schemas.clear();
        self.channels.clear();
        self.messages = 0;
    }

    fn format_error(&self, message: String) -> DatasetError {
        DatasetError::Format {
            path: self.file.clone(),
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
        if !self.topics.iter().any(|(t, _)| *t == channel.topic) {
            self.topics.push((
                channel.topic.clone(),
                Topic {
                    schema: schema.map(|s| s.0.clone()).unwrap_or_default(),
                    decoder,
                    messages: 0,
                    records: Vec::new(),
                },
            ));
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
        let topic = channel.topic.clone();
        let decoder = channel.decoder;
        let Some((_, entry)) = self.topics.iter_mut().find(|(t, _)| *t == topic) else {
            return Ok(());
        };
        entry.messages += 1;
        let Some(decoder) = decoder else {
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
            e.at(&self.file, format!("message {index} (topic `{topic}`)"))
        })?;
        entry.records.push(decoded);
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

    fn finish(self) -> Result<(Mission, Vec<ChannelUse>), DatasetError> {
        let chosen = self.choose_topics()?;
        if self.metadata.is_none() && chosen.iter().all(Option::is_none) {
            return Err(DatasetError::Missing {
                what: format!(
                    "echofield or ROS 2 mission channels (topics in the input: {}; read types: {})",
                    self.topic_list(),
                    supported_types(None)
                ),
                path: self.path,
            });
        }
        let mut mission = Mission::default();
        let mut uses = Vec::with_capacity(self.topics.len());
        for (name, topic) in self.topics {
            let stream = topic.decoder.map(Decoder::stream);
            let used = stream.filter(|s| chosen[*s as usize].as_deref() == Some(name.as_str()));
            let reason = match (stream, used) {
                (Some(s), Some(_)) if self.choice.topics[s as usize].is_some() => {
                    format!("chosen with --topic {}", ROLES[s as usize])
                }
                (Some(_), Some(_)) => "the only topic of its type".to_string(),
                (Some(s), None) => format!(
                    "another topic feeds the {} (`{}`)",
                    STREAM_NAMES[s as usize],
                    chosen[s as usize].as_deref().unwrap_or("")
                ),
                (None, _) if topic.schema.is_empty() => "no schema".to_string(),
                (None, _) => format!("type `{}` is not one echofield reads", topic.schema),
            };
            if used.is_some() {
                for record in topic.records {
                    match record {
                        Decoded::Beam(b) => mission.beams.push(b),
                        Decoded::Dvl(d) => mission.dvl.push(d),
                        Decoded::Attitude(a) => mission.attitude.push(a),
                        Decoded::GroundTruth(g) => mission.ground_truth.push(g),
                    }
                }
            }
            uses.push(ChannelUse {
                topic: name,
                schema: topic.schema,
                role: used.map(|s| ROLES[s as usize]),
                reason,
                messages: topic.messages,
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
        Ok((mission, uses))
    }

    /// The topic of each stream: the chosen one (which must exist and be of
    /// a type of its stream), or the only topic of a type of the stream.
    fn choose_topics(&self) -> Result<[Option<String>; 4], DatasetError> {
        let mut chosen: [Option<String>; 4] = Default::default();
        for (s, slot) in chosen.iter_mut().enumerate() {
            let candidates: Vec<&str> = self
                .topics
                .iter()
                .filter(|(_, t)| t.decoder.map(|d| d.stream() as usize) == Some(s))
                .map(|(n, _)| n.as_str())
                .collect();
            let role = ROLES[s];
            *slot = match &self.choice.topics[s] {
                Some(wanted) if candidates.contains(&wanted.as_str()) => Some(wanted.clone()),
                Some(wanted) => {
                    let message = match self.topics.iter().find(|(n, _)| n == wanted) {
                        Some((_, t)) => format!(
                            "--topic {role}={wanted}: the topic carries `{}`, which is not a {} type echofield reads ({})",
                            t.schema,
                            STREAM_NAMES[s],
                            supported_types(Some(s))
                        ),
                        None => format!(
                            "--topic {role}={wanted}: no such topic (topics in the input: {})",
                            self.topic_list()
                        ),
                    };
                    return Err(DatasetError::Format {
                        path: self.path.clone(),
                        message,
                    });
                }
                None if candidates.len() > 1 => {
                    return Err(DatasetError::Format {
                        path: self.path.clone(),
                        message: format!(
                            "topics `{}` all carry {}: choose one with --topic {role}=/name",
                            candidates.join("`, `"),
                            STREAM_NAMES[s]
                        ),
                    });
                }
                None => candidates.first().map(|t| t.to_string()),
            };
        }
        Ok(chosen)
    }

    /// Every topic with its type, for messages.
    fn topic_list(&self) -> String {
        if self.topics.is_empty() {
            return "none".to_string();
        }
        let list: Vec<String> = self
            .topics
            .iter()
            .map(|(n, t)| {
                format!(
                    "{n} ({})",
                    if t.schema.is_empty() {
                        "no schema"
                    } else {
                        &t.schema
                    }
                )
            })
            .collect();
        list.join(", ")
    }
}

/// The message types read for stream `s` (every stream with `None`).
fn supported_types(s: Option<usize>) -> String {
    let json = [
        json::BEAM_SCHEMA_NAME,
        json::DVL_SCHEMA_NAME,
        json::ATTITUDE_SCHEMA_NAME,
        json::GROUND_TRUTH_SCHEMA_NAME,
    ];
    let mut names: Vec<&str> = Vec::new();
    for (k, name) in json.iter().enumerate() {
        if s.is_none_or(|s| s == k) {
            names.push(name);
        }
    }
    for kind in Ros2Kind::ALL {
        if s.is_none_or(|s| Decoder::Ros2(kind).stream() as usize == s) {
            names.push(kind.schema_name());
        }
    }
    names.join(", ")
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
