//! A minimal reader of ROS 1 bag files, format 2.0, uncompressed chunks.
//!
//! File: `#ROSBAG V2.0\n`, then records. Record: u32 header length, header
//! fields (each u32 length + `name=value`, value binary), u32 data length,
//! data; little-endian. Header field `op`: 0x03 bag header, 0x05 chunk
//! (fields `compression`, `size`; data = connection and message records),
//! 0x07 connection (`conn`, `topic`; data = connection header fields `type`,
//! `md5sum`, `message_definition`, ...), 0x02 message data (`conn`, `time` =
//! u32 sec + u32 nsec), 0x04 index data and 0x06 chunk info (not needed to
//! read everything in order).
//!
//! ROS 1 bags with standard messages are read with the `rosbag` crate
//! ([`crate::ros::bag`], compressed chunks too). This reader is kept for
//! the MiniKing logs because it reads a damaged bag up to the broken
//! record and names that record's byte offset (`stopped_early`), which the
//! crate's errors do not carry; moving the MiniKing reader onto the crate
//! (and so reading its compressed bags) is open. Compressed chunks (`bz2`,
//! `lz4`) are a clear [`DatasetError::Format`] here (`rosbag decompress`
//! converts such a bag, or `echofield convert ros` reads it if its
//! messages are standard ones).

use crate::error::DatasetError;
use std::collections::BTreeMap;
use std::path::Path;

const MAGIC: &[u8] = b"#ROSBAG V2.0\n";
const OP_MESSAGE: u8 = 0x02;
const OP_CHUNK: u8 = 0x05;
const OP_CONNECTION: u8 = 0x07;

/// A topic's connection: what its messages are.
#[derive(Clone, Debug, PartialEq)]
pub struct BagConnection {
    pub id: u32,
    pub topic: String,
    pub message_type: String,
    pub md5sum: String,
}

/// One message: connection, record time and serialized bytes.
pub(crate) struct BagMessage<'a> {
    pub conn: u32,
    pub time_s: f64,
    pub data: &'a [u8],
    /// Byte offset of the message record in the file.
    pub offset: usize,
}

pub(crate) struct Bag<'a> {
    pub connections: BTreeMap<u32, BagConnection>,
    pub messages: Vec<BagMessage<'a>>,
    /// Top-level records read.
    pub records: usize,
    pub stopped_early: Option<String>,
}

/// Header fields as `(name, value)` byte slices.
type Fields<'a> = Vec<(&'a [u8], &'a [u8])>;

struct Record<'a> {
    fields: Fields<'a>,
    data: &'a [u8],
    data_offset: usize,
}

impl<'a> Record<'a> {
    fn field(&self, name: &str) -> Option<&'a [u8]> {
        self.fields
            .iter()
            .find(|(k, _)| *k == name.as_bytes())
            .map(|(_, v)| *v)
    }

    fn u32_field(&self, name: &str) -> Result<u32, String> {
        match self.field(name) {
            Some(v) if v.len() == 4 => Ok(u32::from_le_bytes([v[0], v[1], v[2], v[3]])),
            Some(v) => Err(format!("field `{name}`: {} bytes, expected 4", v.len())),
            None => Err(format!("field `{name}`: missing")),
        }
    }

    fn text_field(&self, name: &str) -> Result<String, String> {
        let v = self
            .field(name)
            .ok_or_else(|| format!("field `{name}`: missing"))?;
        String::from_utf8(v.to_vec()).map_err(|_| format!("field `{name}`: not UTF-8"))
    }
}

fn le_u32(bytes: &[u8], at: usize, what: &str) -> Result<u32, String> {
    bytes
        .get(at..at + 4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .ok_or_else(|| {
            format!(
                "{what}: needs 4 bytes, only {} left (truncated)",
                bytes.len().saturating_sub(at)
            )
        })
}

/// `name=value` fields, each prefixed by its u32 length.
fn parse_fields<'a>(bytes: &'a [u8], what: &str) -> Result<Fields<'a>, String> {
    let mut fields = Vec::new();
    let mut k = 0;
    while k < bytes.len() {
        let len = le_u32(bytes, k, &format!("{what} field length"))? as usize;
        let field = bytes
            .get(k + 4..k + 4 + len)
            .ok_or_else(|| format!("{what} field of {len} bytes runs past its end"))?;
        let eq = field
            .iter()
            .position(|&b| b == b'=')
            .ok_or_else(|| format!("{what} field without `=`"))?;
        fields.push((&field[..eq], &field[eq + 1..]));
        k += 4 + len;
    }
    Ok(fields)
}

/// The record at `at` in `bytes`, the offset after it, and whether its data
/// is cut by the end of `bytes` (then `data` holds what there is).
fn record(bytes: &[u8], at: usize) -> Result<(Record<'_>, usize, bool), String> {
    let header_len = le_u32(bytes, at, "header length")? as usize;
    let header_start = at + 4;
    let header = bytes
        .get(header_start..header_start + header_len)
        .ok_or_else(|| format!("header of {header_len} bytes runs past the end (truncated)"))?;
    let fields = parse_fields(header, "header")?;
    let data_len_at = header_start + header_len;
    let data_len = le_u32(bytes, data_len_at, "data length")? as usize;
    let data_offset = data_len_at + 4;
    let end = data_offset + data_len;
    let data = bytes
        .get(data_offset..end.min(bytes.len()))
        .unwrap_or_default();
    Ok((
        Record {
            fields,
            data,
            data_offset,
        },
        end,
        end > bytes.len(),
    ))
}

pub(crate) fn read_bag<'a>(path: &Path, bytes: &'a [u8]) -> Result<Bag<'a>, DatasetError> {
    if !bytes.starts_with(MAGIC) {
        let shown = String::from_utf8_lossy(&bytes[..bytes.len().min(13)]).into_owned();
        return Err(DatasetError::Format {
            path: path.to_path_buf(),
            message: format!("not a ROS bag 2.0 (starts with {shown:?})"),
        });
    }
    let mut bag = Bag {
        connections: BTreeMap::new(),
        messages: Vec::new(),
        records: 0,
        stopped_early: None,
    };
    let mut at = MAGIC.len();
    while at < bytes.len() {
        // A record cut by the end of the file (a killed recording) is read as
        // far as it goes: the messages of a cut uncompressed chunk are kept.
        let outcome =
            record(bytes, at)
                .map_err(TopLevelError::Stop)
                .and_then(|(rec, next, cut)| {
                    let read = top_level(path, &rec, &mut bag);
                    match (read, cut) {
                        (Ok(()), false) => Ok(next),
                        (Err(TopLevelError::Fatal(e)), _) => Err(TopLevelError::Fatal(e)),
                        (_, true) => Err(TopLevelError::Stop(format!(
                            "data of {} bytes runs past the end of the file (truncated); read the \
                         records in its first {} bytes",
                            next - rec.data_offset,
                            rec.data.len()
                        ))),
                        (Err(stop), false) => Err(stop),
                    }
                });
        match outcome {
            Ok(next) => {
                bag.records += 1;
                at = next;
            }
            Err(TopLevelError::Fatal(err)) => return Err(err),
            Err(TopLevelError::Stop(message)) => {
                bag.stopped_early = Some(format!("record {} at byte {at}: {message}", bag.records));
                break;
            }
        }
    }
    Ok(bag)
}

enum TopLevelError {
    /// The file cannot be read on (e.g. compressed chunks).
    Fatal(DatasetError),
    /// The file is damaged from here on; keep what was read.
    Stop(String),
}

impl From<String> for TopLevelError {
    fn from(message: String) -> Self {
        TopLevelError::Stop(message)
    }
}

fn top_level<'a>(path: &Path, rec: &Record<'a>, bag: &mut Bag<'a>) -> Result<(), TopLevelError> {
    let op = rec.field("op").and_then(|v| v.first().copied());
    match op {
        Some(OP_CHUNK) => {
            let compression = rec.text_field("compression")?;
            if compression != "none" {
                return Err(TopLevelError::Fatal(DatasetError::Format {
                    path: path.to_path_buf(),
                    message: format!(
                        "chunk at byte {} is `{compression}`-compressed; only uncompressed bags are \
                         read (run `rosbag decompress` first)",
                        rec.data_offset
                    ),
                }));
            }
            let mut k = 0;
            while k < rec.data.len() {
                let offset = rec.data_offset + k;
                let (inner, next, cut) = record(rec.data, k)
                    .map_err(|e| format!("inside the chunk, record at byte {offset}: {e}"))?;
                if cut {
                    let message =
                        format!("inside the chunk, record at byte {offset} runs past the chunk");
                    return Err(TopLevelError::Stop(message));
                }
                inner_record(&inner, offset, bag)
                    .map_err(|e| format!("inside the chunk, record at byte {offset}: {e}"))?;
                k = next;
            }
            Ok(())
        }
        Some(OP_CONNECTION) => Ok(connection(rec, bag)?),
        Some(_) => Ok(()),
        None => Err(TopLevelError::Stop("field `op`: missing".into())),
    }
}

fn inner_record<'a>(rec: &Record<'a>, offset: usize, bag: &mut Bag<'a>) -> Result<(), String> {
    match rec.field("op").and_then(|v| v.first().copied()) {
        Some(OP_MESSAGE) => {
            let conn = rec.u32_field("conn")?;
            let time = rec
                .field("time")
                .filter(|t| t.len() == 8)
                .ok_or("field `time`: not 8 bytes")?;
            let sec = u32::from_le_bytes([time[0], time[1], time[2], time[3]]);
            let nsec = u32::from_le_bytes([time[4], time[5], time[6], time[7]]);
            bag.messages.push(BagMessage {
                conn,
                time_s: f64::from(sec) + 1e-9 * f64::from(nsec),
                data: rec.data,
                offset,
            });
            Ok(())
        }
        Some(OP_CONNECTION) => connection(rec, bag),
        Some(_) => Ok(()),
        None => Err("field `op`: missing".into()),
    }
}

fn connection(rec: &Record<'_>, bag: &mut Bag<'_>) -> Result<(), String> {
    let id = rec.u32_field("conn")?;
    let topic = rec.text_field("topic")?;
    let fields = parse_fields(rec.data, "connection")?;
    let text = |name: &str| {
        fields
            .iter()
            .find(|(k, _)| *k == name.as_bytes())
            .map(|(_, v)| String::from_utf8_lossy(v).into_owned())
    };
    let message_type = text("type").ok_or("connection field `type`: missing")?;
    let md5sum = text("md5sum").unwrap_or_default();
    bag.connections.insert(
        id,
        BagConnection {
            id,
            topic,
            message_type,
            md5sum,
        },
    );
    Ok(())
}
