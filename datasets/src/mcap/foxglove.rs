//! Extra channels with Foxglove's well-known JSON schemas, so that SLAM
//! outputs (optimised poses, scans, acoustic images, frames) show up in
//! Foxglove's 3D and image panels without any configuration.
//!
//! The schema texts are echofield's own JSON Schemas of the Foxglove message
//! definitions (<https://docs.foxglove.dev/docs/visualization/message-schemas>):
//! the same field names and types, without Foxglove's optional tracking fields.
//! Written here rather than taken from the `foxglove` crate (Foxglove's SDK)
//! because that brings its own MCAP writer, channels and live server for what
//! is, here, seven JSON messages on echofield's one MCAP writer.
//! echofield is planar: every pose gets z = 0 and a rotation about z only.
//! Timestamps are `{sec, nsec}` taken from the message's log time
//! (`stamp_s` rounded to the nanosecond).
//!
//! [`read_mission`](super::read_mission) skips these channels. Line drawings
//! and rasters for the 3D panel are in [`scene`].

pub mod scene;
pub use scene::{GRID, GridCells, LineSegment, SCENE_UPDATE};

use super::validate::{self, FieldError};
use super::writer::MissionWriter;
use super::{TOPIC_ATTITUDE, TOPIC_BEAM, TOPIC_DVL, TOPIC_GROUND_TRUTH, json};
use crate::DatasetError;
use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use echofield_graph::Se2;
use serde_json::{Value, json};

pub const POSE_IN_FRAME: &str = "foxglove.PoseInFrame";
pub const POSES_IN_FRAME: &str = "foxglove.PosesInFrame";
pub const POINT_CLOUD: &str = "foxglove.PointCloud";
pub const COMPRESSED_IMAGE: &str = "foxglove.CompressedImage";
pub const FRAME_TRANSFORM: &str = "foxglove.FrameTransform";

/// One point of a planar scan for [`MissionWriter::write_point_cloud`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScanPoint {
    /// Position in the cloud's frame, metres.
    pub x_m: f64,
    pub y_m: f64,
    /// Echo intensity or any per-point value Foxglove can colour by.
    pub intensity: f32,
}

const TIME: &str = r#"{
      "type": "object",
      "description": "Timestamp: seconds and nanoseconds since the Unix epoch",
      "properties": {
        "sec": { "type": "integer", "minimum": 0 },
        "nsec": { "type": "integer", "minimum": 0, "maximum": 999999999 }
      },
      "required": ["sec", "nsec"]
    }"#;

const VECTOR3: &str = r#"{
      "type": "object",
      "properties": { "x": { "type": "number" }, "y": { "type": "number" }, "z": { "type": "number" } },
      "required": ["x", "y", "z"]
    }"#;

const QUATERNION: &str = r#"{
      "type": "object",
      "properties": {
        "x": { "type": "number" }, "y": { "type": "number" }, "z": { "type": "number" }, "w": { "type": "number" }
      },
      "required": ["x", "y", "z", "w"]
    }"#;

fn pose_schema() -> String {
    format!(
        r#"{{
      "type": "object",
      "description": "Position (m) and orientation of a frame",
      "properties": {{ "position": {VECTOR3}, "orientation": {QUATERNION} }},
      "required": ["position", "orientation"]
    }}"#
    )
}

fn object_schema(title: &str, description: &str, properties: &[(&str, String)]) -> String {
    let props: Vec<String> = properties
        .iter()
        .map(|(name, schema)| format!("\"{name}\": {schema}"))
        .collect();
    let required: Vec<String> = properties.iter().map(|(n, _)| format!("\"{n}\"")).collect();
    format!(
        r#"{{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "{title}",
  "description": "{description}",
  "type": "object",
  "properties": {{
    {}
  }},
  "required": [{}]
}}
"#,
        props.join(",\n    "),
        required.join(", ")
    )
}

fn frame_id() -> String {
    r#"{ "type": "string", "description": "Frame of reference" }"#.to_string()
}

pub fn pose_in_frame_schema() -> String {
    object_schema(
        POSE_IN_FRAME,
        "A timestamped pose in a named frame",
        &[
            ("timestamp", TIME.into()),
            ("frame_id", frame_id()),
            ("pose", pose_schema()),
        ],
    )
}

pub fn poses_in_frame_schema() -> String {
    let poses = format!(r#"{{ "type": "array", "items": {} }}"#, pose_schema());
    object_schema(
        POSES_IN_FRAME,
        "An array of timestamped poses in a named frame",
        &[
            ("timestamp", TIME.into()),
            ("frame_id", frame_id()),
            ("poses", poses),
        ],
    )
}

pub fn point_cloud_schema() -> String {
    let fields = r#"{
      "type": "array",
      "items": {
        "type": "object",
        "properties": {
          "name": { "type": "string" },
          "offset": { "type": "integer", "minimum": 0, "description": "Byte offset within a point" },
          "type": { "type": "integer", "minimum": 0, "maximum": 8, "description": "foxglove.NumericType: 1 UINT8, 2 INT8, 3 UINT16, 4 INT16, 5 UINT32, 6 INT32, 7 FLOAT32, 8 FLOAT64" }
        },
        "required": ["name", "offset", "type"]
      }
    }"#;
    let data = r#"{ "type": "string", "contentEncoding": "base64", "description": "Packed little-endian points" }"#;
    let stride = r#"{ "type": "integer", "minimum": 0, "description": "Bytes per point" }"#;
    object_schema(
        POINT_CLOUD,
        "A collection of points with per-point fields",
        &[
            ("timestamp", TIME.into()),
            ("frame_id", frame_id()),
            ("pose", pose_schema()),
            ("point_stride", stride.into()),
            ("fields", fields.into()),
            ("data", data.into()),
        ],
    )
}

pub fn compressed_image_schema() -> String {
    let data = r#"{ "type": "string", "contentEncoding": "base64", "description": "Compressed image bytes" }"#;
    let format = r#"{ "type": "string", "description": "Image format: png, jpeg, webp or avif" }"#;
    object_schema(
        COMPRESSED_IMAGE,
        "A compressed image",
        &[
            ("timestamp", TIME.into()),
            ("frame_id", frame_id()),
            ("data", data.into()),
            ("format", format.into()),
        ],
    )
}

pub fn frame_transform_schema() -> String {
    let name = |d: &str| format!(r#"{{ "type": "string", "description": "{d}" }}"#);
    object_schema(
        FRAME_TRANSFORM,
        "The pose of a child frame in a parent frame (parent_from_child)",
        &[
            ("timestamp", TIME.into()),
            ("parent_frame_id", name("Parent frame")),
            ("child_frame_id", name("Child frame")),
            ("translation", VECTOR3.into()),
            ("rotation", QUATERNION.into()),
        ],
    )
}

fn timestamp(log_time_ns: u64) -> Value {
    json!({ "sec": log_time_ns / 1_000_000_000, "nsec": log_time_ns % 1_000_000_000 })
}

/// A planar pose as a Foxglove pose: z = 0, rotation by `theta` about z.
fn pose_value(pose: &Se2) -> Value {
    let half = 0.5 * pose.theta();
    json!({
        "position": { "x": pose.x(), "y": pose.y(), "z": 0.0 },
        "orientation": { "x": 0.0, "y": 0.0, "z": half.sin(), "w": half.cos() },
    })
}

fn finite_pose(field: &str, pose: &Se2) -> Result<(), FieldError> {
    if pose.is_finite() {
        Ok(())
    } else {
        Err(FieldError::new(field, "pose is not finite"))
    }
}

impl MissionWriter {
    fn write_foxglove(
        &mut self,
        topic: &str,
        schema_name: &str,
        schema: fn() -> String,
        stamp_s: f64,
        check: Result<(), FieldError>,
        message: impl FnOnce(Value) -> Value,
    ) -> Result<(), DatasetError> {
        let path = self.path().to_path_buf();
        let record = format!("{schema_name} on `{topic}` at {stamp_s} s");
        if [TOPIC_BEAM, TOPIC_DVL, TOPIC_ATTITUDE, TOPIC_GROUND_TRUTH].contains(&topic) {
            return Err(DatasetError::parse(
                &path,
                record,
                "topic",
                "reserved for echofield's sensor streams",
            ));
        }
        validate::stamp(stamp_s)
            .and(check)
            .map_err(|e| e.at(&path, &record))?;
        let log_time_ns = validate::log_time_ns(stamp_s);
        let value = message(timestamp(log_time_ns));
        let bytes = serde_json::to_vec(&value).expect("JSON serialisation of a Value");
        self.file.channel(
            topic,
            schema_name,
            json::SCHEMA_ENCODING,
            schema,
            json::MESSAGE_ENCODING,
        )?;
        self.file.write(topic, log_time_ns, &bytes)
    }

    /// One pose (`world_from_vehicle`, say) as `foxglove.PoseInFrame`.
    pub fn write_pose_in_frame(
        &mut self,
        topic: &str,
        stamp_s: f64,
        frame_id: &str,
        pose: &Se2,
    ) -> Result<(), DatasetError> {
        let check = finite_pose("pose", pose);
        self.write_foxglove(
            topic,
            POSE_IN_FRAME,
            pose_in_frame_schema,
            stamp_s,
            check,
            |t| json!({ "timestamp": t, "frame_id": frame_id, "pose": pose_value(pose) }),
        )
    }

    /// A whole trajectory (the optimised poses) as `foxglove.PosesInFrame`.
    pub fn write_poses_in_frame(
        &mut self,
        topic: &str,
        stamp_s: f64,
        frame_id: &str,
        poses: &[Se2],
    ) -> Result<(), DatasetError> {
        let check = poses
            .iter()
            .enumerate()
            .try_for_each(|(i, p)| finite_pose(&format!("poses[{i}]"), p));
        self.write_foxglove(
            topic,
            POSES_IN_FRAME,
            poses_in_frame_schema,
            stamp_s,
            check,
            |t| {
                let poses: Vec<Value> = poses.iter().map(pose_value).collect();
                json!({ "timestamp": t, "frame_id": frame_id, "poses": poses })
            },
        )
    }

    /// A planar scan as `foxglove.PointCloud`: points in the frame `origin`
    /// (the cloud's pose in `frame_id`), packed as little-endian `f32` x, y,
    /// z (= 0) and intensity, 16 bytes per point.
    pub fn write_point_cloud(
        &mut self,
        topic: &str,
        stamp_s: f64,
        frame_id: &str,
        origin: &Se2,
        points: &[ScanPoint],
    ) -> Result<(), DatasetError> {
        let check = finite_pose("pose", origin).and_then(|_| {
            points.iter().enumerate().try_for_each(|(i, p)| {
                if p.x_m.is_finite() && p.y_m.is_finite() && p.intensity.is_finite() {
                    Ok(())
                } else {
                    Err(FieldError::new(
                        format!("points[{i}]"),
                        "value is not finite",
                    ))
                }
            })
        });
        self.write_foxglove(
            topic,
            POINT_CLOUD,
            point_cloud_schema,
            stamp_s,
            check,
            |t| {
                let mut data = Vec::with_capacity(points.len() * 16);
                for p in points {
                    for v in [p.x_m as f32, p.y_m as f32, 0.0, p.intensity] {
                        data.extend_from_slice(&v.to_le_bytes());
                    }
                }
                const FLOAT32: u8 = 7;
                let fields: Vec<Value> = ["x", "y", "z", "intensity"]
                    .iter()
                    .enumerate()
                    .map(|(k, name)| json!({ "name": name, "offset": 4 * k, "type": FLOAT32 }))
                    .collect();
                json!({
                    "timestamp": t,
                    "frame_id": frame_id,
                    "pose": pose_value(origin),
                    "point_stride": 16,
                    "fields": fields,
                    "data": BASE64.encode(&data),
                })
            },
        )
    }

    /// An encoded image (an acoustic image or mosaic as PNG) as
    /// `foxglove.CompressedImage`; `format` is `png`, `jpeg`, `webp` or `avif`.
    pub fn write_compressed_image(
        &mut self,
        topic: &str,
        stamp_s: f64,
        frame_id: &str,
        format: &str,
        data: &[u8],
    ) -> Result<(), DatasetError> {
        let check = if ["png", "jpeg", "webp", "avif"].contains(&format) {
            Ok(())
        } else {
            Err(FieldError::new(
                "format",
                format!("`{format}` is not png, jpeg, webp or avif"),
            ))
        };
        self.write_foxglove(topic, COMPRESSED_IMAGE, compressed_image_schema, stamp_s, check, |t| {
            json!({ "timestamp": t, "frame_id": frame_id, "data": BASE64.encode(data), "format": format })
        })
    }

    /// The pose of `child_frame_id` in `parent_frame_id` (`parent_from_child`)
    /// as `foxglove.FrameTransform`, e.g. `world` → `vehicle` per node, or
    /// `vehicle` → `sonar` from the mounting.
    pub fn write_frame_transform(
        &mut self,
        topic: &str,
        stamp_s: f64,
        parent_frame_id: &str,
        child_frame_id: &str,
        parent_from_child: &Se2,
    ) -> Result<(), DatasetError> {
        let check = finite_pose("parent_from_child", parent_from_child);
        self.write_foxglove(
            topic,
            FRAME_TRANSFORM,
            frame_transform_schema,
            stamp_s,
            check,
            |t| {
                let pose = pose_value(parent_from_child);
                json!({
                    "timestamp": t,
                    "parent_frame_id": parent_frame_id,
                    "child_frame_id": child_frame_id,
                    "translation": pose["position"],
                    "rotation": pose["orientation"],
                })
            },
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schemas_parse_and_require_every_property() {
        for (text, title) in [
            (pose_in_frame_schema(), POSE_IN_FRAME),
            (poses_in_frame_schema(), POSES_IN_FRAME),
            (point_cloud_schema(), POINT_CLOUD),
            (compressed_image_schema(), COMPRESSED_IMAGE),
            (frame_transform_schema(), FRAME_TRANSFORM),
        ] {
            let v: Value = serde_json::from_str(&text).unwrap();
            assert_eq!(v["title"], title);
            let props = v["properties"].as_object().unwrap();
            assert_eq!(v["required"].as_array().unwrap().len(), props.len());
        }
    }

    #[test]
    fn quarter_turn_quaternion() {
        let v = pose_value(&Se2::new(1.0, 2.0, std::f64::consts::FRAC_PI_2));
        let h = std::f64::consts::FRAC_1_SQRT_2;
        assert!((v["orientation"]["z"].as_f64().unwrap() - h).abs() < 1e-15);
        assert!((v["orientation"]["w"].as_f64().unwrap() - h).abs() < 1e-15);
        assert_eq!(v["position"]["y"], 2.0);
    }

    #[test]
    fn timestamp_splits_nanoseconds() {
        assert_eq!(
            timestamp(12_345_000_000_007),
            json!({"sec": 12345, "nsec": 7})
        );
    }
}
