//! [`read_mission`]: one pass over the MCAP records, decoding the channels
//! that map to a sensor stream and skipping the others.

mod assemble;
mod container;

use super::cdr::CdrReader;
use super::rosbag2::{self, Storage};
use super::validate::{self, FieldError};
use super::{FORMAT_VERSION, METADATA_NAME, json};
use super::{TOPIC_ATTITUDE, TOPIC_BEAM, TOPIC_DVL, TOPIC_GROUND_TRUTH, TOPIC_POSITION_FIX};
use crate::DatasetError;
use crate::ros::messages::{self, Decoded, MessageType, Stream, Transform};
use crate::ros::wire::Ros1Reader;
use crate::ros::{bag, sqlite, tf};
use echofield_frontend::sensors::{Mission, SensorMounting};
use echofield_frontend::warnings::{Warning, WarningKind};
use mcap::records::Record;
use std::collections::HashMap;
use std::fs::File;
use std::path::{Path, PathBuf};

/// How many streams a mission has ([`Stream`], [`ROLES`]).
const STREAMS: usize = 5;

const STREAM_NAMES: [&str; STREAMS] = [
    "sonar beams",
    "DVL",
    "attitude",
    "ground truth",
    "position fixes",
];

/// The serialisation of a ROS message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Wire {
    /// CDR (ROS 2).
    Cdr,
    /// The ROS 1 wire format (bags).
    Ros1,
}

#[derive(Debug, Clone, Copy)]
enum Decoder {
    Json(Stream),
    Ros(MessageType, Wire),
}

impl Decoder {
    /// The stream a topic of this decoder feeds when chosen by type alone.
    fn stream(self) -> Option<Stream> {
        match self {
            Decoder::Json(s) => Some(s),
            Decoder::Ros(ty, _) => ty.stream(),
        }
    }

    /// Whether the topic can feed `stream` when chosen for it.
    fn can_feed(self, stream: Stream) -> bool {
        match self {
            Decoder::Json(s) => s == stream,
            Decoder::Ros(ty, _) => ty.can_feed(stream),
        }
    }
}

impl Decoder {
    /// One message: the records it holds and, for ROS messages, its
    /// `header.frame_id`; `log_time_ns` stamps messages without a header.
    /// Errors name the field that does not decode.
    fn decode(
        self,
        data: &[u8],
        log_time_ns: u64,
    ) -> Result<(Decoded, Option<String>), FieldError> {
        match self {
            Decoder::Json(Stream::Beam) => {
                json::decode_beam(data).map(|b| (Decoded::Beams(vec![b]), None))
            }
            Decoder::Json(Stream::Dvl) => json::decode_dvl(data).map(|d| (Decoded::Dvl(d), None)),
            Decoder::Json(Stream::Attitude) => {
                json::decode_attitude(data).map(|a| (Decoded::Attitude(a), None))
            }
            Decoder::Json(Stream::GroundTruth) => {
                json::decode_ground_truth(data).map(|g| (Decoded::GroundTruth(g), None))
            }
            Decoder::Json(Stream::PositionFix) => {
                json::decode_position_fix(data).map(|f| (Decoded::PositionFix(f), None))
            }
            Decoder::Ros(ty, Wire::Cdr) => CdrReader::new(data)
                .and_then(|mut r| messages::decode(ty, &mut r, log_time_ns))
                .map(|(d, frame)| (d, Some(frame))),
            Decoder::Ros(ty, Wire::Ros1) => {
                messages::decode(ty, &mut Ros1Reader::new(data), log_time_ns)
                    .map(|(d, frame)| (d, Some(frame)))
            }
        }
    }
}

/// Whether the messages of `topic` are decoded. Not decoded: transforms on
/// topics other than `/tf_static` and `/tf`, and topics of a stream whose
/// topic is chosen (unless chosen themselves, for any role).
fn needed(choice: &TopicChoice, decoder: Decoder, topic: &str) -> bool {
    match decoder.stream() {
        None => topic == TF_STATIC || topic == TF,
        Some(s) => {
            let choice = &choice.topics;
            choice[s as usize].as_ref().is_none_or(|t| *t == topic)
                || choice.iter().any(|t| t.as_deref() == Some(topic))
        }
    }
}

/// The topic that carries the static transforms.
const TF_STATIC: &str = "/tf_static";
/// The topic of the other transforms; its unchanging frame pairs count as
/// static ([`tf::ConstantTransforms`]).
const TF: &str = "/tf";

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
/// with MCAP or sqlite3 storage: its files in order) and from a ROS 1 bag
/// (a file starting `#ROSBAG V2.0`); returns what became of every
/// channel. A stream fed by several topics of a supported type needs a
/// choice: without one it is an error that names them. The message types
/// read and their conventions are listed in [`crate::ros::messages`];
/// the sonar mounting comes from `/tf_static` when the input has no
/// echofield metadata ([`ChannelUse`] of `/tf_static` says what was found).
pub fn read_mission_with(
    path: &Path,
    choice: &TopicChoice,
) -> Result<(Mission, Vec<ChannelUse>), DatasetError> {
    let mut state = State::new(path, choice);
    let (storage, files) = if path.is_dir() {
        rosbag2::storage_files(path)?
    } else if bag::is_bag(path) {
        state.start_file(path);
        bag::for_each_message(path, |record| match record {
            bag::BagRecord::Connection(id, topic, type_name) => {
                let decoder =
                    MessageType::from_type_name(type_name).map(|ty| Decoder::Ros(ty, Wire::Ros1));
                state.add_channel(id, topic, type_name, decoder);
                Ok(())
            }
            bag::BagRecord::Message(id, time_ns, data) => state.message(id, time_ns, data),
        })?;
        return state.finish();
    } else {
        (Storage::Mcap, vec![path.to_path_buf()])
    };
    for file_path in &files {
        state.start_file(file_path);
        match storage {
            Storage::Mcap => {
                let file = File::open(file_path).map_err(|e| DatasetError::io(file_path, e))?;
                let len = file
                    .metadata()
                    .map_err(|e| DatasetError::io(file_path, e))?
                    .len();
                container::for_each_record(file_path, file, len, |record| state.on_record(record))?;
            }
            Storage::Sqlite3 => sqlite::for_each_message(file_path, |record| match record {
                sqlite::SqliteRecord::Topic(topic) => {
                    let decoder = match MessageType::from_type_name(&topic.type_name) {
                        Some(ty) if topic.serialization_format == "cdr" => {
                            Some(Decoder::Ros(ty, Wire::Cdr))
                        }
                        _ => None,
                    };
                    // Topic ids are small row ids; the channel table is
                    // keyed by u32 (an id beyond it matches no message).
                    let id = u32::try_from(topic.id).unwrap_or(u32::MAX);
                    state.add_channel(id, &topic.name, &topic.type_name, decoder);
                    Ok(())
                }
                sqlite::SqliteRecord::Message(topic_id, time_ns, data) => {
                    state.message(u32::try_from(topic_id).unwrap_or(u32::MAX), time_ns, data)
                }
            })?,
        }
    }
    state.finish()
}

/// The roles a topic can be chosen for, as `--topic ROLE=/name` names them,
/// in [`Stream`] order.
pub const ROLES: [&str; STREAMS] = ["sonar", "dvl", "heading", "ground_truth", "position_fix"];

/// The topic chosen for each stream (`None`: by message type, when only
/// one topic carries it).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TopicChoice {
    /// Indexed like [`ROLES`].
    pub topics: [Option<String>; STREAMS],
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

/// Whether a topic chosen explicitly for one role is kept from the default
/// choice of the others.
fn chosen_elsewhere(choice: &TopicChoice, topic: &str, stream: usize) -> bool {
    choice
        .topics
        .iter()
        .enumerate()
        .any(|(s, t)| s != stream && t.as_deref() == Some(topic))
}

/// A topic seen in the input, with the records decoded from it when its
/// type feeds a stream (kept until [`State::finish`] chooses the topic of
/// each stream).
struct Topic {
    schema: String,
    decoder: Option<Decoder>,
    messages: u64,
    records: Vec<Decoded>,
    /// `header.frame_id` of its first decoded message.
    frame_id: Option<String>,
}

struct State<'c> {
    path: PathBuf,
    /// The file being read (a rosbag2 folder has several).
    file: PathBuf,
    choice: &'c TopicChoice,
    /// schema id -> (name, encoding), of the current file.
    schemas: HashMap<u16, (String, String)>,
    /// channel (MCAP), topic (sqlite3) or connection (ROS 1) id ->
    /// channel, of the current file.
    channels: HashMap<u32, Channel>,
    /// Every topic by name, in the order first seen.
    topics: Vec<(String, Topic)>,
    messages: u64,
    metadata: Option<(String, SensorMounting)>,
    /// The frame pairs of `/tf`, folded as they come.
    tf_pairs: tf::ConstantTransforms,
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
            tf_pairs: tf::ConstantTransforms::default(),
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
                self.message(u32::from(header.channel_id), header.log_time, &data)?;
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
        if self.channels.contains_key(&u32::from(channel.id)) {
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
        let schema_name = schema.map(|s| s.0.clone()).unwrap_or_default();
        self.add_channel(u32::from(channel.id), &channel.topic, &schema_name, decoder);
        Ok(())
    }

    /// Registers a channel (MCAP), topic (sqlite3) or connection (ROS 1)
    /// of the current file; the first of a topic decides its type.
    fn add_channel(&mut self, id: u32, topic: &str, type_name: &str, decoder: Option<Decoder>) {
        if !self.topics.iter().any(|(t, _)| t == topic) {
            self.topics.push((
                topic.to_string(),
                Topic {
                    schema: type_name.to_string(),
                    decoder,
                    messages: 0,
                    records: Vec::new(),
                    frame_id: None,
                },
            ));
        }
        self.channels.insert(
            id,
            Channel {
                topic: topic.to_string(),
                decoder,
            },
        );
    }

    /// One message of the current file, numbered in file order.
    fn message(
        &mut self,
        channel_id: u32,
        log_time_ns: u64,
        data: &[u8],
    ) -> Result<(), DatasetError> {
        let index = self.messages;
        self.messages += 1;
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
        if !needed(self.choice, decoder, &topic) {
            return Ok(());
        }
        let (decoded, frame_id) = decoder
            .decode(data, log_time_ns)
            .map_err(|e| e.at(&self.file, format!("message {index} (topic `{topic}`)")))?;
        if entry.frame_id.is_none() {
            entry.frame_id = frame_id;
        }
        match decoded {
            Decoded::Transforms(transforms) if topic == TF => {
                transforms.into_iter().for_each(|t| self.tf_pairs.add(t))
            }
            decoded => entry.records.push(decoded),
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

    /// The mission from the topics read: the chosen topic of each stream
    /// feeds it, its mounting comes from the echofield metadata or else
    /// from the static transforms, and each stream is sorted by stamp (a
    /// warning counts the records that went backwards). Also what became of
    /// every topic. Errors when no topic can feed a stream and there is no
    /// echofield metadata, or when the topic choice is invalid.
    fn finish(self) -> Result<(Mission, Vec<ChannelUse>), DatasetError> {
        let chosen = self.choose_topics()?;
        if self.metadata.is_none() && chosen.iter().all(Option::is_none) {
            return Err(DatasetError::Missing {
                what: format!(
                    "echofield or ROS mission topics (topics in the input: {}; read types: {})",
                    self.topic_list(),
                    supported_types(None)
                ),
                path: self.path,
            });
        }
        // The sonar's and the DVL's frames, for their mountings in the
        // static transforms.
        let frames = self.frames(&chosen);
        let constant_tf: Vec<Transform> = self.tf_pairs.constant().cloned().collect();
        let context = assemble::TopicContext {
            chosen: &chosen,
            choice: self.choice,
            constant_tf: &constant_tf,
            tf_pairs: self.tf_pairs.pairs(),
        };
        let mut gathered = assemble::Gathered::default();
        for (name, topic) in self.topics {
            gathered.add_topic(name, topic, &context);
        }
        let assemble::Gathered {
            mut mission,
            mut uses,
            static_transforms,
            tf_use,
            tf_dynamic_use,
        } = gathered;
        if let Some((name, mounting)) = self.metadata {
            mission.name = name;
            mission.mounting = mounting;
            if let Some(i) = tf_use {
                uses[i].reason = "the file's echofield metadata gives the mounting".into();
            }
        } else {
            mission.mounting = SensorMounting::assumed_identity();
            mission.name = self
                .path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default();
            if let Some(i) = tf_use.or(tf_dynamic_use) {
                let transforms = assemble::with_constant(static_transforms, constant_tf);
                let target = assemble::MountingTarget {
                    mission: &mut mission,
                    uses: &mut uses,
                    tf_use: i,
                };
                target.mount_from(&transforms, &frames);
            }
        }
        assemble::sort_streams(&mut mission);
        Ok((mission, uses))
    }

    /// The frames of the chosen sonar and DVL topics.
    fn frames(&self, chosen: &[Option<String>; STREAMS]) -> assemble::Frames {
        assemble::Frames {
            sonar: self.frame_of(chosen, Stream::Beam),
            dvl: self.frame_of(chosen, Stream::Dvl),
            dvl_topic: chosen[Stream::Dvl as usize].clone(),
        }
    }

    /// `header.frame_id` of the first decoded message of the topic chosen
    /// for `stream`, if any.
    fn frame_of(&self, chosen: &[Option<String>; STREAMS], stream: Stream) -> Option<String> {
        chosen[stream as usize].as_ref().and_then(|name| {
            self.topics
                .iter()
                .find(|(n, _)| n == name)
                .and_then(|(_, t)| t.frame_id.clone())
        })
    }

    /// The topic of each stream: the chosen one (which must exist and be of
    /// a type that can feed the stream), or the only topic of a type of the
    /// stream that is not chosen for another role.
    fn choose_topics(&self) -> Result<[Option<String>; STREAMS], DatasetError> {
        let mut chosen: [Option<String>; STREAMS] = Default::default();
        for (s, slot) in chosen.iter_mut().enumerate() {
            let stream = stream_of(s);
            let candidates: Vec<&str> = self
                .topics
                .iter()
                .filter(|(n, t)| {
                    t.decoder.and_then(Decoder::stream) == Some(stream)
                        && !chosen_elsewhere(self.choice, n, s)
                })
                .map(|(n, _)| n.as_str())
                .collect();
            let role = ROLES[s];
            *slot = match &self.choice.topics[s] {
                Some(wanted) => match self.topics.iter().find(|(n, _)| n == wanted) {
                    Some((_, t)) if t.decoder.is_some_and(|d| d.can_feed(stream)) => {
                        Some(wanted.clone())
                    }
                    found => {
                        let message = match found {
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
                },
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

/// The stream of index `s` (in `ROLES` order).
fn stream_of(s: usize) -> Stream {
    [
        Stream::Beam,
        Stream::Dvl,
        Stream::Attitude,
        Stream::GroundTruth,
        Stream::PositionFix,
    ][s.min(STREAMS - 1)]
}

/// The message types read for stream `s` (every stream with `None`).
fn supported_types(s: Option<usize>) -> String {
    let json = [
        json::BEAM_SCHEMA_NAME,
        json::DVL_SCHEMA_NAME,
        json::ATTITUDE_SCHEMA_NAME,
        json::GROUND_TRUTH_SCHEMA_NAME,
        json::POSITION_FIX_SCHEMA_NAME,
    ];
    let mut names: Vec<&str> = Vec::new();
    for (k, name) in json.iter().enumerate() {
        if s.is_none_or(|s| s == k) {
            names.push(name);
        }
    }
    for ty in MessageType::ALL {
        if s.is_none_or(|s| ty.can_feed(stream_of(s))) {
            names.push(ty.type_name());
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
        json::POSITION_FIX_SCHEMA_NAME => Some(Stream::PositionFix),
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
    if let Some(ty) = MessageType::from_type_name(name) {
        return match message_encoding {
            super::ros2::MESSAGE_ENCODING => Ok(Some(Decoder::Ros(ty, Wire::Cdr))),
            // ROS 1 messages in MCAP (`ros1msg` schemas).
            "ros1" => Ok(Some(Decoder::Ros(ty, Wire::Ros1))),
            _ => Err(format!(
                "channel `{topic}`: schema `{name}` with message encoding `{message_encoding}` and schema encoding `{schema_encoding}` is not supported (expected `cdr` or `ros1`)"
            )),
        };
    }
    if [
        TOPIC_BEAM,
        TOPIC_DVL,
        TOPIC_ATTITUDE,
        TOPIC_GROUND_TRUTH,
        TOPIC_POSITION_FIX,
    ]
    .contains(&topic)
    {
        return Err(format!(
            "channel `{topic}` is an echofield topic but has an unknown schema `{name}` (encoding `{schema_encoding}`, message encoding `{message_encoding}`)"
        ));
    }
    Ok(None)
}
