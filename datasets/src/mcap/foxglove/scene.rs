//! Drawings for Foxglove's 3D panel: line segments as `foxglove.SceneUpdate`
//! and a raster (an acoustic mosaic) as `foxglove.Grid`.
//!
//! Field names and meanings follow Foxglove's message definitions
//! (<https://docs.foxglove.dev/docs/visualization/message-schemas/scene-update>,
//! `.../grid`); the JSON Schemas here are echofield's own, reduced to the
//! fields echofield writes (every field Foxglove's JSON reader expects is
//! present in each message, empty where unused).

use super::{TIME, finite_pose, frame_id, pose_schema, pose_value};
use crate::DatasetError;
use crate::mcap::validate::FieldError;
use crate::mcap::writer::MissionWriter;
use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use echofield_graph::Se2;
use serde_json::{Value, json};

pub const SCENE_UPDATE: &str = "foxglove.SceneUpdate";
pub const GRID: &str = "foxglove.Grid";

/// `foxglove.LinePrimitive.type` for independent segments (points 2k and
/// 2k+1 form segment k).
const LINE_LIST: u8 = 2;
/// `foxglove.NumericType.UINT8`.
const UINT8: u8 = 1;

/// One straight segment in the drawing's frame, metres, with its colour
/// (red, green, blue, alpha, each 0-1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineSegment {
    pub from_m: (f64, f64),
    pub to_m: (f64, f64),
    pub rgba: [f32; 4],
}

/// A raster for [`MissionWriter::write_grid`]: `cells` row-major with
/// `column_count` cells per row, row 0 starting at `origin` (the grid's
/// corner in the message's frame) and rows along the origin's +y; square
/// cells of `cell_size_m` metres.
#[derive(Debug, Clone, Copy)]
pub struct GridCells<'a> {
    pub origin: Se2,
    pub column_count: usize,
    pub cell_size_m: f64,
    pub cells: &'a [u8],
}

fn color_schema() -> Value {
    let unit = json!({ "type": "number", "minimum": 0, "maximum": 1 });
    json!({
        "type": "object",
        "properties": { "r": unit, "g": unit, "b": unit, "a": unit },
        "required": ["r", "g", "b", "a"]
    })
}

fn parse(text: &str) -> Value {
    serde_json::from_str(text).expect("the module's own schema fragments are valid JSON")
}

fn schema_text(title: &str, description: &str, properties: Value) -> String {
    let required: Vec<&String> = properties
        .as_object()
        .map(|p| p.keys().collect())
        .unwrap_or_default();
    let schema = json!({
        "$schema": "https://json-schema.org/draft/2020-12/schema",
        "title": title,
        "description": description,
        "type": "object",
        "properties": properties,
        "required": required,
    });
    serde_json::to_string_pretty(&schema).expect("JSON serialisation of a Value")
}

/// `foxglove.SceneUpdate` with entities that carry line primitives; the
/// other primitive arrays are present and empty.
pub fn scene_update_schema() -> String {
    let point = json!({
        "type": "object",
        "properties": { "x": { "type": "number" }, "y": { "type": "number" }, "z": { "type": "number" } },
        "required": ["x", "y", "z"]
    });
    let line = json!({
        "type": "object",
        "properties": {
            "type": { "type": "integer", "description": "0 LINE_STRIP, 1 LINE_LOOP, 2 LINE_LIST" },
            "pose": parse(&pose_schema()),
            "thickness": { "type": "number", "minimum": 0 },
            "scale_invariant": { "type": "boolean", "description": "thickness in pixels, not metres" },
            "points": { "type": "array", "items": point },
            "color": color_schema(),
            "colors": { "type": "array", "items": color_schema(), "description": "per-point colours" },
            "indices": { "type": "array", "items": { "type": "integer", "minimum": 0 } }
        },
        "required": ["type", "pose", "thickness", "scale_invariant", "points", "color", "colors", "indices"]
    });
    let unused = json!({ "type": "array", "description": "not written by echofield: empty" });
    let duration = json!({
        "type": "object",
        "properties": { "sec": { "type": "integer" }, "nsec": { "type": "integer" } },
        "required": ["sec", "nsec"]
    });
    let entity = json!({
        "type": "object",
        "properties": {
            "timestamp": parse(TIME),
            "frame_id": parse(&frame_id()),
            "id": { "type": "string" },
            "lifetime": duration,
            "frame_locked": { "type": "boolean" },
            "metadata": unused,
            "arrows": unused, "cubes": unused, "spheres": unused, "cylinders": unused,
            "lines": { "type": "array", "items": line },
            "triangles": unused, "texts": unused, "models": unused
        },
        "required": ["timestamp", "frame_id", "id", "lifetime", "frame_locked", "metadata",
            "arrows", "cubes", "spheres", "cylinders", "lines", "triangles", "texts", "models"]
    });
    schema_text(
        SCENE_UPDATE,
        "An update to the entities of a 3D scene",
        json!({
            "deletions": { "type": "array", "description": "not written by echofield: empty" },
            "entities": { "type": "array", "items": entity }
        }),
    )
}

/// `foxglove.Grid` with one-byte cells.
pub fn grid_schema() -> String {
    let field = json!({
        "type": "object",
        "properties": {
            "name": { "type": "string" },
            "offset": { "type": "integer", "minimum": 0 },
            "type": { "type": "integer", "minimum": 0, "maximum": 8, "description": "foxglove.NumericType" }
        },
        "required": ["name", "offset", "type"]
    });
    let count = |d: &str| json!({ "type": "integer", "minimum": 0, "description": d });
    schema_text(
        GRID,
        "A 2D grid of data in the x-y plane of its pose",
        json!({
            "timestamp": parse(TIME),
            "frame_id": parse(&frame_id()),
            "pose": parse(&pose_schema()),
            "column_count": count("Cells per row"),
            "cell_size": {
                "type": "object",
                "description": "Cell size along x and y, metres",
                "properties": { "x": { "type": "number" }, "y": { "type": "number" } },
                "required": ["x", "y"]
            },
            "row_stride": count("Bytes per row"),
            "cell_stride": count("Bytes per cell"),
            "fields": { "type": "array", "items": field },
            "data": { "type": "string", "contentEncoding": "base64", "description": "Cells, row-major, row 0 at the pose's origin, rows along +y" }
        }),
    )
}

fn color_value(rgba: [f32; 4]) -> Value {
    json!({ "r": rgba[0], "g": rgba[1], "b": rgba[2], "a": rgba[3] })
}

/// The segments' end points finite and colours within 0-1 (errors name
/// the segment), and the thickness finite and positive.
fn check_lines(segments: &[LineSegment], thickness_px: f64) -> Result<(), FieldError> {
    for (i, s) in segments.iter().enumerate() {
        let finite = [s.from_m.0, s.from_m.1, s.to_m.0, s.to_m.1]
            .iter()
            .all(|v| v.is_finite());
        if !finite {
            return Err(FieldError::new(
                format!("segments[{i}]"),
                "end point is not finite",
            ));
        }
        if !s.rgba.iter().all(|c| (0.0..=1.0).contains(c)) {
            return Err(FieldError::new(
                format!("segments[{i}].rgba"),
                "colour component outside 0-1",
            ));
        }
    }
    if thickness_px.is_finite() && thickness_px > 0.0 {
        Ok(())
    } else {
        Err(FieldError::new("thickness_px", "must be finite and > 0"))
    }
}

/// A `LINE_LIST` primitive of the segments (one colour per end point),
/// `thickness_px` screen pixels wide.
fn line_list(segments: &[LineSegment], thickness_px: f64) -> Value {
    let mut points = Vec::with_capacity(2 * segments.len());
    let mut colors = Vec::with_capacity(2 * segments.len());
    for s in segments {
        for (x, y) in [s.from_m, s.to_m] {
            points.push(json!({ "x": x, "y": y, "z": 0.0 }));
            colors.push(color_value(s.rgba));
        }
    }
    json!({
        "type": LINE_LIST,
        "pose": pose_value(&Se2::identity()),
        "thickness": thickness_px,
        "scale_invariant": true,
        "points": points,
        "color": color_value([1.0, 1.0, 1.0, 1.0]),
        "colors": colors,
        "indices": [],
    })
}

impl MissionWriter {
    /// Segments as one `foxglove.SceneUpdate` entity `entity_id` in frame
    /// `frame_id`, drawn `thickness_px` screen pixels wide. The entity lives
    /// until replaced (lifetime 0), so a message at the first stamp stays on
    /// screen over the whole playback.
    pub fn write_scene_lines(
        &mut self,
        topic: &str,
        stamp_s: f64,
        frame_id: &str,
        entity_id: &str,
        thickness_px: f64,
        segments: &[LineSegment],
    ) -> Result<(), DatasetError> {
        let check = check_lines(segments, thickness_px);
        self.write_foxglove(
            topic,
            SCENE_UPDATE,
            scene_update_schema,
            stamp_s,
            check,
            |t| {
                let line = line_list(segments, thickness_px);
                let entity = json!({
                    "timestamp": t,
                    "frame_id": frame_id,
                    "id": entity_id,
                    "lifetime": { "sec": 0, "nsec": 0 },
                    "frame_locked": false,
                    "metadata": [],
                    "arrows": [], "cubes": [], "spheres": [], "cylinders": [],
                    "lines": [line],
                    "triangles": [], "texts": [], "models": [],
                });
                json!({ "deletions": [], "entities": [entity] })
            },
        )
    }

    /// A raster of one-byte cells (field `intensity`, 0-255) as
    /// `foxglove.Grid` in `frame_id` (see [`GridCells`]).
    pub fn write_grid(
        &mut self,
        topic: &str,
        stamp_s: f64,
        frame_id: &str,
        grid: &GridCells<'_>,
    ) -> Result<(), DatasetError> {
        let GridCells {
            origin,
            column_count,
            cell_size_m,
            cells,
        } = *grid;
        let check = finite_pose("pose", &origin).and_then(|_| {
            if !(cell_size_m.is_finite() && cell_size_m > 0.0) {
                Err(FieldError::new("cell_size", "must be finite and > 0"))
            } else if column_count == 0 || !cells.len().is_multiple_of(column_count) {
                Err(FieldError::new(
                    "column_count",
                    format!(
                        "{column_count} does not divide the {} cells into rows",
                        cells.len()
                    ),
                ))
            } else {
                Ok(())
            }
        });
        self.write_foxglove(topic, GRID, grid_schema, stamp_s, check, |t| {
            json!({
                "timestamp": t,
                "frame_id": frame_id,
                "pose": pose_value(&origin),
                "column_count": column_count,
                "cell_size": { "x": cell_size_m, "y": cell_size_m },
                "row_stride": column_count,
                "cell_stride": 1,
                "fields": [{ "name": "intensity", "offset": 0, "type": UINT8 }],
                "data": BASE64.encode(cells),
            })
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schemas_parse_and_name_their_message() {
        for (text, title) in [(scene_update_schema(), SCENE_UPDATE), (grid_schema(), GRID)] {
            let v: Value = serde_json::from_str(&text).unwrap();
            assert_eq!(v["title"], title);
            let props = v["properties"].as_object().unwrap();
            assert_eq!(v["required"].as_array().unwrap().len(), props.len());
        }
    }
}
