//! Pose-graph and trajectory files.
//!
//! - [`g2o`]: `VERTEX_SE2`, `EDGE_SE2`, `EDGE_PRIOR_SE2` (also the older
//!   `EDGE_SE2_PRIOR`), `FIX`.
//! - [`toro`]: `VERTEX2`, `EDGE2` (information ordered `xx xy yy tt xt yt`).
//! - [`trajectory`]: TUM, CSV and KITTI-style trajectory rows.
//!
//! Readers never panic on bad input: every problem is an [`IoError`] naming the
//! file, the line (1-based) and the field. Text must be UTF-8 (an invalid
//! byte is reported with its line, column and byte offset); a leading
//! byte-order mark is skipped. Values must be finite and within
//! [`MAX_ABS_POSITION_M`], [`MAX_ABS_ANGLE_RAD`] and
//! [`MAX_ABS_INFORMATION`]. A file whose last line has no line end is
//! refused when that line is a record: its last value may have been cut.

pub mod g2o;
pub mod toro;
pub mod trajectory;

mod build;
mod error;
mod lines;

pub use error::IoError;
pub use g2o::write_g2o;
pub use lines::{MAX_ABS_ANGLE_RAD, MAX_ABS_INFORMATION, MAX_ABS_POSITION_M};
pub use trajectory::{
    TrajectoryPose, graph_trajectory, read_tum, write_csv, write_kitti, write_tum,
};

use crate::PoseGraph;
use std::path::Path;

/// A pose-graph file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GraphFormat {
    G2o,
    Toro,
}

/// Reads a g2o or TORO file, detecting the format from its first record.
///
/// Files without vertex records (manhattan, CSAIL, city10000) get their
/// initial poses by composing edges along a breadth-first spanning tree from
/// the smallest node id, preferring the odometry chain `i -> i+1` (see
/// [`g2o::parse_g2o`]).
pub fn read_pose_graph(path: &Path) -> Result<PoseGraph, IoError> {
    parse_pose_graph(&read_text(path)?, path)
}

/// Reads a whole UTF-8 text file, naming it in the error: an invalid
/// UTF-8 sequence is an [`IoError::Parse`] naming its line, column and
/// byte offset. A leading byte-order mark is kept in the returned text;
/// every parser of this module skips it.
pub fn read_text(path: &Path) -> Result<String, IoError> {
    let bytes = std::fs::read(path).map_err(|source| IoError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    lines::decode_utf8(bytes, path)
}

/// Parses pose-graph text; `path` is only used in error messages.
pub fn parse_pose_graph(text: &str, path: &Path) -> Result<PoseGraph, IoError> {
    match detect_format(text) {
        Some(GraphFormat::G2o) => g2o::parse_g2o(text, path),
        Some(GraphFormat::Toro) => toro::parse_toro(text, path),
        None => match lines::records(text).next() {
            None => Err(IoError::Empty {
                path: path.to_path_buf(),
            }),
            Some(record) => Err(IoError::parse(
                path,
                record.line,
                "tag",
                format!(
                    "unknown record `{}`: expected g2o (VERTEX_SE2, EDGE_SE2, FIX) or TORO (VERTEX2, EDGE2)",
                    record.tag()
                ),
            )),
        },
    }
}

/// The format of the first record with a known tag.
pub fn detect_format(text: &str) -> Option<GraphFormat> {
    let first = lines::records(text).next()?;
    match first.tag() {
        "VERTEX_SE2" | "EDGE_SE2" | "EDGE_PRIOR_SE2" | "EDGE_SE2_PRIOR" | "FIX" => {
            Some(GraphFormat::G2o)
        }
        "VERTEX2" | "EDGE2" => Some(GraphFormat::Toro),
        _ => None,
    }
}
