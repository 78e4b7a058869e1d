//! rosbag2's sqlite3 storage (`.db3` files): a `topics` table (`id`,
//! `name`, `type`, `serialization_format`) and a `messages` table
//! (`topic_id`, `timestamp` in ns, `data`: the serialised message).
//!
//! Read with `rusqlite` (SQLite itself, bundled): the file is an SQLite
//! database, which nothing short of SQLite reads reliably.

use crate::DatasetError;
use rusqlite::{Connection, OpenFlags};
use std::path::Path;

/// One row of the `topics` table.
pub struct SqliteTopic {
    pub id: i64,
    pub name: String,
    pub type_name: String,
    pub serialization_format: String,
}

fn sql_error(path: &Path, what: &str, e: rusqlite::Error) -> DatasetError {
    DatasetError::Format {
        path: path.to_path_buf(),
        message: format!("rosbag2 sqlite3 storage: {what}: {e}"),
    }
}

/// A row of the storage.
pub enum SqliteRecord<'a> {
    Topic(SqliteTopic),
    /// A message: topic id, timestamp in ns, serialised data.
    Message(i64, u64, &'a [u8]),
}

/// Calls `on_record` for every topic, then for every message in time order
/// (ties in insertion order).
pub fn for_each_message(
    path: &Path,
    mut on_record: impl FnMut(SqliteRecord<'_>) -> Result<(), DatasetError>,
) -> Result<(), DatasetError> {
    let db = Connection::open_with_flags(path, OpenFlags::SQLITE_OPEN_READ_ONLY)
        .map_err(|e| sql_error(path, "cannot open", e))?;
    let mut topics = db
        .prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id")
        .map_err(|e| sql_error(path, "table `topics`", e))?;
    let rows = topics
        .query_map([], |row| {
            Ok(SqliteTopic {
                id: row.get(0)?,
                name: row.get(1)?,
                type_name: row.get(2)?,
                serialization_format: row.get(3)?,
            })
        })
        .map_err(|e| sql_error(path, "table `topics`", e))?;
    for topic in rows {
        on_record(SqliteRecord::Topic(
            topic.map_err(|e| sql_error(path, "table `topics`", e))?,
        ))?;
    }
    let mut messages = db
        .prepare("SELECT topic_id, timestamp, data FROM messages ORDER BY timestamp, id")
        .map_err(|e| sql_error(path, "table `messages`", e))?;
    let mut rows = messages
        .query([])
        .map_err(|e| sql_error(path, "table `messages`", e))?;
    let mut index = 0u64;
    while let Some(row) = rows
        .next()
        .map_err(|e| sql_error(path, &format!("message {index}"), e))?
    {
        let read = |e| sql_error(path, &format!("message {index}"), e);
        let topic_id: i64 = row.get(0).map_err(read)?;
        let timestamp: i64 = row.get(1).map_err(read)?;
        let data =
            row.get_ref(2).map_err(read)?.as_blob().map_err(|e| {
                sql_error(path, &format!("message {index}"), rusqlite::Error::from(e))
            })?;
        let Ok(timestamp_ns) = u64::try_from(timestamp) else {
            return Err(DatasetError::parse(
                path,
                format!("message {index}"),
                "timestamp",
                format!("{timestamp} ns is negative"),
            ));
        };
        on_record(SqliteRecord::Message(topic_id, timestamp_ns, data))?;
        index += 1;
    }
    Ok(())
}
