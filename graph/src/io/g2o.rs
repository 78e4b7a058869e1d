//! The g2o text format for 2D pose graphs.
//!
//! ```text
//! VERTEX_SE2 id x y theta
//! EDGE_SE2 from to dx dy dtheta I11 I12 I13 I22 I23 I33
//! EDGE_PRIOR_SE2 id x y theta I11 I12 I13 I22 I23 I33
//! FIX id [id ...]
//! ```
//! `EDGE_PRIOR_SE2` is g2o's own tag for a unary SE(2) prior
//! (`types_slam2d`); the reader also accepts `EDGE_SE2_PRIOR`, which
//! echofield wrote before. GTSAM's `readG2o` stops at the first record it
//! does not know (`FIX` or a prior), so [`write_g2o`] puts them last:
//! GTSAM then reads every vertex and every relative edge, and only the
//! priors and the fixed nodes are left for the caller to add
//! (`tools/check_gtsam.sh` does, and compares the χ²).
//! Information matrices are given by their upper triangle, row by row, in the
//! order `(x, y, θ)`. Edges read from a file are [`EdgeKind::Odometry`] when
//! they join consecutive ids and [`EdgeKind::Loop`] otherwise; the kind only
//! selects robust kernels in the backend.

use super::IoError;
use super::build::RawGraph;
use super::lines::{MAX_ABS_ANGLE_RAD, MAX_ABS_INFORMATION, MAX_ABS_POSITION_M};
use super::lines::{Record, records};
use crate::{Edge, EdgeKind, NodeId, PoseGraph, Se2};
use nalgebra::Matrix3;
use std::io::Write;
use std::path::Path;

const VERTEX_FIELDS: [&str; 4] = ["id", "x", "y", "theta"];
const EDGE_FIELDS: [&str; 11] = [
    "from", "to", "dx", "dy", "dtheta", "I11", "I12", "I13", "I22", "I23", "I33",
];
const PRIOR_FIELDS: [&str; 10] = [
    "id", "x", "y", "theta", "I11", "I12", "I13", "I22", "I23", "I33",
];

/// Reads a g2o file.
pub fn read_g2o(path: &Path) -> Result<PoseGraph, IoError> {
    parse_g2o(&super::read_text(path)?, path)
}

/// Parses g2o text; `path` only names the source in errors. Without any
/// `VERTEX_SE2` line, initial poses come from composing the edges (see
/// `spanning_tree_poses` in this module's source: odometry chain first).
pub fn parse_g2o(text: &str, path: &Path) -> Result<PoseGraph, IoError> {
    let mut raw = RawGraph::default();
    for record in records(text) {
        match record.tag() {
            "VERTEX_SE2" => read_vertex(&record, path, &mut raw)?,
            "EDGE_SE2" => read_edge(&record, path, &mut raw)?,
            "EDGE_PRIOR_SE2" | "EDGE_SE2_PRIOR" => read_prior(&record, path, &mut raw)?,
            "FIX" => read_fix(&record, path, &mut raw)?,
            other => {
                return Err(IoError::parse(
                    path,
                    record.line,
                    "tag",
                    format!(
                        "unknown g2o record `{other}` (supported: VERTEX_SE2, EDGE_SE2, EDGE_PRIOR_SE2, FIX)"
                    ),
                ));
            }
        }
    }
    raw.into_graph(path)
}

/// `VERTEX_SE2 id x y theta`.
fn read_vertex(record: &Record, path: &Path, raw: &mut RawGraph) -> Result<(), IoError> {
    record.expect_fields(path, &VERTEX_FIELDS)?;
    let id = record.id(path, 1, "id")?;
    raw.vertices.push((
        record.line,
        id,
        pose_fields(record, path, 2, &VERTEX_FIELDS)?,
    ));
    Ok(())
}

/// `EDGE_SE2 from to dx dy dtheta I11 I12 I13 I22 I23 I33`; odometry when
/// `to = from + 1`, else a loop.
fn read_edge(record: &Record, path: &Path, raw: &mut RawGraph) -> Result<(), IoError> {
    record.expect_fields(path, &EDGE_FIELDS)?;
    let from = record.id(path, 1, "from")?;
    let to = record.id(path, 2, "to")?;
    let measurement = pose_fields(record, path, 3, &EDGE_FIELDS)?;
    let information = upper_triangle(record, path, 6, &EDGE_FIELDS[5..])?;
    let kind = relative_kind(from, to);
    raw.edges.push((
        record.line,
        Edge::new(kind, from, to, measurement, information),
    ));
    Ok(())
}

/// `EDGE_PRIOR_SE2 id x y theta I11 ... I33` (or `EDGE_SE2_PRIOR`).
fn read_prior(record: &Record, path: &Path, raw: &mut RawGraph) -> Result<(), IoError> {
    record.expect_fields(path, &PRIOR_FIELDS)?;
    let id = record.id(path, 1, "id")?;
    let measurement = pose_fields(record, path, 2, &PRIOR_FIELDS)?;
    let information = upper_triangle(record, path, 5, &PRIOR_FIELDS[4..])?;
    raw.edges.push((
        record.line,
        Edge::new(EdgeKind::Prior, id, id, measurement, information),
    ));
    Ok(())
}

/// `FIX id...`: at least one vertex id.
fn read_fix(record: &Record, path: &Path, raw: &mut RawGraph) -> Result<(), IoError> {
    if record.tokens.len() < 2 {
        return Err(IoError::parse(
            path,
            record.line,
            "id",
            "FIX needs at least one vertex id",
        ));
    }
    for index in 1..record.tokens.len() {
        raw.fixed.push((record.line, record.id(path, index, "id")?));
    }
    record.expect_terminated(path, "id")
}

/// Writes the graph as g2o, in the order peers' readers need: every node
/// as `VERTEX_SE2`, the relative edges as `EDGE_SE2`, then the priors as
/// `EDGE_PRIOR_SE2` and the fixed nodes as `FIX` (see the module doc for
/// why these come last). Numbers are written with Rust's shortest
/// round-trip formatting, so reading the file back gives the same values
/// bit for bit.
pub fn write_g2o(graph: &PoseGraph, w: &mut dyn Write) -> std::io::Result<()> {
    for node in graph.nodes() {
        let p = &node.pose;
        writeln!(
            w,
            "VERTEX_SE2 {} {} {} {}",
            node.id,
            p.x(),
            p.y(),
            p.theta()
        )?;
    }
    let (priors, relative): (Vec<&Edge>, Vec<&Edge>) =
        graph.edges().partition(|e| e.kind == EdgeKind::Prior);
    for edge in relative {
        write!(w, "EDGE_SE2 {} {}", edge.from, edge.to)?;
        write_measurement(edge, w)?;
    }
    for edge in priors {
        write!(w, "EDGE_PRIOR_SE2 {}", edge.from)?;
        write_measurement(edge, w)?;
    }
    for id in graph.fixed() {
        writeln!(w, "FIX {id}")?;
    }
    Ok(())
}

/// The measurement and the information's upper triangle of `edge`, and
/// the line end.
fn write_measurement(edge: &Edge, w: &mut dyn Write) -> std::io::Result<()> {
    let z = &edge.measurement;
    let i = &edge.information;
    write!(w, " {} {} {}", z.x(), z.y(), z.theta())?;
    for (r, c) in [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)] {
        write!(w, " {}", i[(r, c)])?;
    }
    writeln!(w)
}

/// Edges between consecutive ids are odometry, others loop closures.
pub(crate) fn relative_kind(from: NodeId, to: NodeId) -> EdgeKind {
    if from.abs_diff(to) == 1 {
        EdgeKind::Odometry
    } else {
        EdgeKind::Loop
    }
}

/// Three consecutive pose fields starting at token `first`; `names` are
/// the field names of the whole record (after the tag), used in errors.
pub(crate) fn pose_fields(
    record: &Record,
    path: &Path,
    first: usize,
    names: &[&str],
) -> Result<Se2, IoError> {
    let names = &names[first - 1..first + 2];
    let position = |k: usize| {
        record.bounded(
            path,
            first + k,
            names[k],
            MAX_ABS_POSITION_M,
            "a position in metres",
        )
    };
    let (x, y) = (position(0)?, position(1)?);
    let theta = record.bounded(
        path,
        first + 2,
        names[2],
        MAX_ABS_ANGLE_RAD,
        "an angle in radians",
    )?;
    Ok(Se2::new(x, y, theta))
}

/// One entry of an information matrix (finite, within
/// [`MAX_ABS_INFORMATION`]).
pub(crate) fn information_entry(
    record: &Record,
    path: &Path,
    index: usize,
    name: &str,
) -> Result<f64, IoError> {
    record.bounded(
        path,
        index,
        name,
        MAX_ABS_INFORMATION,
        "an information-matrix entry",
    )
}

/// An information matrix from its upper triangle `I11 I12 I13 I22 I23 I33`.
fn upper_triangle(
    record: &Record,
    path: &Path,
    first: usize,
    names: &[&str],
) -> Result<Matrix3<f64>, IoError> {
    let mut v = [0.0; 6];
    for (k, value) in v.iter_mut().enumerate() {
        *value = information_entry(record, path, first + k, names[k])?;
    }
    Ok(Matrix3::new(
        v[0], v[1], v[2], v[1], v[3], v[4], v[2], v[4], v[5],
    ))
}
