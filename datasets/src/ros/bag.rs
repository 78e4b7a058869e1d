//! ROS 1 bag files (format 2.0), read with the `rosbag` crate (chunks
//! uncompressed, bz2 or lz4; connection records with their message type).

use crate::DatasetError;
use rosbag::{ChunkRecord, MessageRecord, RosBag};
use std::io::Read;
use std::path::Path;

/// The first bytes of a ROS 1 bag.
pub const MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// Whether `path` is a file that starts like a ROS 1 bag.
pub fn is_bag(path: &Path) -> bool {
    let mut head = [0u8; 13];
    std::fs::File::open(path)
        .and_then(|mut f| f.read_exact(&mut head))
        .is_ok()
        && head == MAGIC
}

fn bag_error(path: &Path, e: rosbag::Error) -> DatasetError {
    DatasetError::Format {
        path: path.to_path_buf(),
        message: format!("ROS 1 bag: {e}"),
    }
}

/// A record of a bag, in file order.
pub enum BagRecord<'a> {
    /// A connection (before its messages): id, topic, message type.
    Connection(u32, &'a str, &'a str),
    /// A message: connection id, receive time in ns, serialised data.
    Message(u32, u64, &'a [u8]),
}

/// Calls `on_record` for each connection and message, in file order
/// (chunk by chunk).
pub fn for_each_message(
    path: &Path,
    mut on_record: impl FnMut(BagRecord<'_>) -> Result<(), DatasetError>,
) -> Result<(), DatasetError> {
    let bag = RosBag::new(path).map_err(|e| DatasetError::io(path, e))?;
    for record in bag.chunk_records() {
        let ChunkRecord::Chunk(chunk) = record.map_err(|e| bag_error(path, e))? else {
            continue;
        };
        for message in chunk.messages() {
            match message.map_err(|e| bag_error(path, e))? {
                MessageRecord::Connection(c) => {
                    on_record(BagRecord::Connection(c.id, c.topic, c.tp))?
                }
                MessageRecord::MessageData(m) => {
                    on_record(BagRecord::Message(m.conn_id, m.time, m.data))?
                }
            }
        }
    }
    Ok(())
}
