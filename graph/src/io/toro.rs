//! The TORO text format for 2D pose graphs.
//!
//! ```text
//! VERTEX2 id x y theta
//! EDGE2 from to dx dy dtheta Ixx Ixy Iyy Itt Ixt Iyt
//! ```
//! Note TORO's information order `xx xy yy tt xt yt`, unlike g2o's
//! `xx xy xt yy yt tt`.

use super::IoError;
use super::build::RawGraph;
use super::g2o::{information_entry, pose_fields, relative_kind};
use super::lines::records;
use crate::{Edge, EdgeKind, PoseGraph};
use nalgebra::Matrix3;
use std::io::Write;
use std::path::Path;

const VERTEX_FIELDS: [&str; 4] = ["id", "x", "y", "theta"];
const EDGE_FIELDS: [&str; 11] = [
    "from", "to", "dx", "dy", "dtheta", "Ixx", "Ixy", "Iyy", "Itt", "Ixt", "Iyt",
];

/// Reads a TORO file.
pub fn read_toro(path: &Path) -> Result<PoseGraph, IoError> {
    parse_toro(&super::read_text(path)?, path)
}

/// Parses TORO text; `path` only names the source in errors.
pub fn parse_toro(text: &str, path: &Path) -> Result<PoseGraph, IoError> {
    let mut raw = RawGraph::default();
    for record in records(text) {
        match record.tag() {
            "VERTEX2" => {
                record.expect_fields(path, &VERTEX_FIELDS)?;
                let id = record.id(path, 1, "id")?;
                raw.vertices.push((
                    record.line,
                    id,
                    pose_fields(&record, path, 2, &VERTEX_FIELDS)?,
                ));
            }
            "EDGE2" => {
                record.expect_fields(path, &EDGE_FIELDS)?;
                let from = record.id(path, 1, "from")?;
                let to = record.id(path, 2, "to")?;
                let measurement = pose_fields(&record, path, 3, &EDGE_FIELDS)?;
                let mut v = [0.0; 6];
                for (k, value) in v.iter_mut().enumerate() {
                    *value = information_entry(&record, path, 6 + k, EDGE_FIELDS[5 + k])?;
                }
                let [xx, xy, yy, tt, xt, yt] = v;
                let information = Matrix3::new(xx, xy, xt, xy, yy, yt, xt, yt, tt);
                raw.edges.push((
                    record.line,
                    Edge::new(relative_kind(from, to), from, to, measurement, information),
                ));
            }
            other => {
                return Err(IoError::parse(
                    path,
                    record.line,
                    "tag",
                    format!("unknown TORO record `{other}` (supported: VERTEX2, EDGE2)"),
                ));
            }
        }
    }
    raw.into_graph(path)
}

/// Writes the graph as TORO. Priors and fixed nodes have no TORO record and
/// are left out.
pub fn write_toro(graph: &PoseGraph, w: &mut dyn Write) -> std::io::Result<()> {
    for node in graph.nodes() {
        let p = &node.pose;
        writeln!(w, "VERTEX2 {} {} {} {}", node.id, p.x(), p.y(), p.theta())?;
    }
    for edge in graph.edges().filter(|e| e.kind != EdgeKind::Prior) {
        let z = &edge.measurement;
        let i = &edge.information;
        writeln!(
            w,
            "EDGE2 {} {} {} {} {} {} {} {} {} {} {}",
            edge.from,
            edge.to,
            z.x(),
            z.y(),
            z.theta(),
            i[(0, 0)],
            i[(0, 1)],
            i[(1, 1)],
            i[(2, 2)],
            i[(0, 2)],
            i[(1, 2)]
        )?;
    }
    Ok(())
}
