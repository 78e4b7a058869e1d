//! The Qt data stream container of Ping Viewer sensor logs (big-endian).
//!
//! Header: QString `"PingViewer sensor log file"`, int32 version, five
//! QStrings (viewer commit, build date, tag, OS name, OS version), int32
//! device family, int32 device type. Then records to the end of the file:
//! QString time stamp, QByteArray raw serial chunk. A QString is a u32 byte
//! length (0xFFFFFFFF = null) and UTF-16BE text; a QByteArray a u32 length
//! and the bytes.

use super::timestamp::parse_elapsed_s;
use crate::error::DatasetError;
use std::path::Path;

const MAGIC: &str = "PingViewer sensor log file";
/// Longest time stamp string accepted, bytes (12 characters are expected).
const MAX_STAMP_BYTES: u32 = 256;

/// One record: when the chunk arrived and where it starts in the joined stream.
pub(crate) struct Chunk {
    pub elapsed_s: f64,
    pub stream_offset: usize,
}

/// The whole container: header fields, chunks and the joined serial stream.
pub(crate) struct Container {
    pub info: Vec<(String, String)>,
    pub chunks: Vec<Chunk>,
    pub stream: Vec<u8>,
    /// Where and why reading stopped before the end of the file.
    pub stopped_early: Option<String>,
}

struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, field: &str) -> Result<&'a [u8], String> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.bytes.len());
        let end = end.ok_or_else(|| {
            format!(
                "field `{field}`: needs {n} bytes, only {} left (truncated file)",
                self.bytes.len() - self.pos
            )
        })?;
        let slice = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(slice)
    }

    fn u32(&mut self, field: &str) -> Result<u32, String> {
        let b = self.take(4, field)?;
        Ok(u32::from_be_bytes([b[0], b[1], b[2], b[3]]))
    }

    fn qstring(&mut self, field: &str, max_bytes: u32) -> Result<Option<String>, String> {
        let len = self.u32(field)?;
        if len == u32::MAX {
            return Ok(None);
        }
        if len % 2 != 0 || len > max_bytes {
            return Err(format!("field `{field}`: implausible string length {len}"));
        }
        let raw = self.take(len as usize, field)?;
        let units: Vec<u16> = raw
            .chunks_exact(2)
            .map(|p| u16::from_be_bytes([p[0], p[1]]))
            .collect();
        String::from_utf16(&units)
            .map(Some)
            .map_err(|_| format!("field `{field}`: invalid UTF-16"))
    }
}

pub(crate) fn read_container(path: &Path, bytes: &[u8]) -> Result<Container, DatasetError> {
    let mut cur = Cursor { bytes, pos: 0 };
    let format = |message: String| DatasetError::Format {
        path: path.to_path_buf(),
        message: format!("not a Ping Viewer sensor log: header {message}"),
    };
    let magic = cur.qstring("magic", 256).map_err(format)?;
    if magic.as_deref() != Some(MAGIC) {
        return Err(format(format!("starts with {magic:?}, expected {MAGIC:?}")));
    }
    let version = cur.u32("version").map_err(format)?;
    let mut info = vec![("format version".to_string(), version.to_string())];
    for name in [
        "viewer commit",
        "viewer build date",
        "viewer tag",
        "OS name",
        "OS version",
    ] {
        let value = cur.qstring(name, 4096).map_err(format)?;
        info.push((name.to_string(), value.unwrap_or_default()));
    }
    info.push((
        "device family".into(),
        cur.u32("device family").map_err(format)?.to_string(),
    ));
    info.push((
        "device type".into(),
        cur.u32("device type").map_err(format)?.to_string(),
    ));

    let mut container = Container {
        info,
        chunks: Vec::new(),
        stream: Vec::with_capacity(bytes.len()),
        stopped_early: None,
    };
    let mut previous_s = f64::NEG_INFINITY;
    while cur.pos < bytes.len() {
        let record_pos = cur.pos;
        match read_record(&mut cur, previous_s) {
            Ok((elapsed_s, data)) => {
                previous_s = elapsed_s;
                container.chunks.push(Chunk {
                    elapsed_s,
                    stream_offset: container.stream.len(),
                });
                container.stream.extend_from_slice(data);
            }
            Err(message) => {
                let index = container.chunks.len();
                container.stopped_early =
                    Some(format!("record {index} at byte {record_pos}: {message}"));
                break;
            }
        }
    }
    Ok(container)
}

fn read_record<'a>(cur: &mut Cursor<'a>, previous_s: f64) -> Result<(f64, &'a [u8]), String> {
    let stamp = cur
        .qstring("timestamp", MAX_STAMP_BYTES)?
        .ok_or("field `timestamp`: null string")?;
    let elapsed_s = parse_elapsed_s(&stamp).map_err(|e| format!("field `timestamp`: {e}"))?;
    if elapsed_s < previous_s {
        return Err(format!(
            "field `timestamp`: {stamp} ({elapsed_s} s) is earlier than the previous record ({previous_s} s)"
        ));
    }
    let len = cur.u32("data length")?;
    let data = if len == u32::MAX {
        &[][..]
    } else {
        cur.take(len as usize, "data")?
    };
    Ok((elapsed_s, data))
}
