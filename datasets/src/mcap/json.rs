//! echofield's JSON messages: the JSON Schema text of each channel and the
//! conversion between the messages and the sensor types of
//! `echofield_frontend::sensors`.
//!
//! Every schema is JSON Schema draft 2020-12 with `additionalProperties:
//! false`; the reader is as strict (unknown fields are errors). Numbers are
//! written by `serde_json` in their shortest exact form and read back with
//! correct rounding, so every `f64` round-trips bit for bit. Beam intensities
//! are one byte per bin, base64 (RFC 4648 standard alphabet, padded), marked
//! `"contentEncoding": "base64"` so Foxglove shows them as bytes.

use super::validate::{self, FieldError};
use base64::Engine as _;
use base64::engine::general_purpose::STANDARD as BASE64;
use echofield_frontend::sensors::{Attitude, DvlVelocity, GroundTruthPose, PositionFix, SonarBeam};
use echofield_graph::Se2;
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize, de::DeserializeOwned};
use std::borrow::Cow;

/// Message encoding of every echofield channel.
pub const MESSAGE_ENCODING: &str = "json";
/// Schema encoding of every echofield channel.
pub const SCHEMA_ENCODING: &str = "jsonschema";

pub const BEAM_SCHEMA_NAME: &str = "echofield.SonarBeam";
pub const DVL_SCHEMA_NAME: &str = "echofield.DvlVelocity";
pub const ATTITUDE_SCHEMA_NAME: &str = "echofield.Attitude";
pub const GROUND_TRUTH_SCHEMA_NAME: &str = "echofield.GroundTruthPose";
pub const POSITION_FIX_SCHEMA_NAME: &str = "echofield.PositionFix";

const STAMP: &str = r#""stamp_s": {
      "type": "number",
      "minimum": 0,
      "description": "Time of the measurement, seconds (Unix time for real logs). The MCAP log_time is this stamp in nanoseconds, rounded."
    }"#;

/// JSON Schema of `/sonar/beam`.
pub fn beam_schema() -> String {
    format!(
        r#"{{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "{BEAM_SCHEMA_NAME}",
  "description": "One beam of a mechanically scanned imaging sonar (MSIS): echo intensities along one transducer angle, in the sonar head frame.",
  "type": "object",
  "properties": {{
    {STAMP},
    "angle_rad": {{
      "type": "number",
      "description": "Transducer angle in the sonar head frame, radians, counter-clockwise from the head's x axis (seen from above); not necessarily wrapped."
    }},
    "bin_size_m": {{
      "type": "number",
      "exclusiveMinimum": 0,
      "description": "Range length of one bin, metres."
    }},
    "first_bin_range_m": {{
      "type": "number",
      "minimum": 0,
      "description": "Range of the start of bin 0, metres; bin i covers [first_bin_range_m + i*bin_size_m, first_bin_range_m + (i+1)*bin_size_m)."
    }},
    "intensities": {{
      "type": "string",
      "contentEncoding": "base64",
      "description": "Echo intensities 0-255, one byte per bin, nearest bin first, base64 (RFC 4648, padded). At least one bin."
    }}
  }},
  "required": ["stamp_s", "angle_rad", "bin_size_m", "first_bin_range_m", "intensities"],
  "additionalProperties": false
}}
"#
    )
}

/// JSON Schema of `/dvl/velocity`.
pub fn dvl_schema() -> String {
    format!(
        r#"{{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "{DVL_SCHEMA_NAME}",
  "description": "Velocity of the DVL over the bottom, in the DVL instrument frame (x forward, y left, z up when mounted without rotation).",
  "type": "object",
  "properties": {{
    {STAMP},
    "velocity_mps": {{
      "type": "object",
      "description": "Velocity over ground in the DVL frame, m/s.",
      "properties": {{
        "x": {{ "type": "number", "description": "m/s" }},
        "y": {{ "type": "number", "description": "m/s" }},
        "z": {{ "type": "number", "description": "m/s" }}
      }},
      "required": ["x", "y", "z"],
      "additionalProperties": false
    }},
    "valid": {{
      "type": "boolean",
      "description": "False when the instrument flagged the sample (no bottom lock, bad status); such samples carry no information."
    }},
    "covariance_m2ps2": {{
      "type": "array",
      "items": {{ "type": "number" }},
      "minItems": 9,
      "maxItems": 9,
      "description": "Optional 3x3 velocity covariance, row-major, (m/s)^2, DVL frame."
    }}
  }},
  "required": ["stamp_s", "velocity_mps", "valid"],
  "additionalProperties": false
}}
"#
    )
}

/// JSON Schema of `/attitude`.
pub fn attitude_schema() -> String {
    format!(
        r#"{{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "{ATTITUDE_SCHEMA_NAME}",
  "description": "Attitude of the vehicle frame (x forward, y left, z up) in the world frame (x east, y north, z up), from the MRU/AHRS/compass.",
  "type": "object",
  "properties": {{
    {STAMP},
    "roll_rad": {{ "type": "number", "description": "Roll about the vehicle x axis, radians, right-handed." }},
    "pitch_rad": {{ "type": "number", "description": "Pitch about the vehicle y axis, radians, right-handed (y left, so positive pitches the nose down)." }},
    "yaw_rad": {{ "type": "number", "description": "Heading of the vehicle x axis from the world x axis (east), radians, counter-clockwise positive." }},
    "yaw_rate_radps": {{ "type": "number", "description": "Optional yaw rate, rad/s, counter-clockwise positive." }}
  }},
  "required": ["stamp_s", "roll_rad", "pitch_rad", "yaw_rad"],
  "additionalProperties": false
}}
"#
    )
}

/// JSON Schema of `/ground_truth/pose`.
pub fn ground_truth_schema() -> String {
    format!(
        r#"{{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "{GROUND_TRUTH_SCHEMA_NAME}",
  "description": "Ground-truth pose world_from_vehicle (DGPS, simulator) in the local metric world frame (x east, y north).",
  "type": "object",
  "properties": {{
    {STAMP},
    "x_m": {{ "type": "number", "description": "Vehicle x in the world frame, metres." }},
    "y_m": {{ "type": "number", "description": "Vehicle y in the world frame, metres." }},
    "yaw_rad": {{ "type": "number", "description": "Heading of the vehicle x axis, radians in (-pi, pi], counter-clockwise from the world x axis." }}
  }},
  "required": ["stamp_s", "x_m", "y_m", "yaw_rad"],
  "additionalProperties": false
}}
"#
    )
}

/// JSON Schema of `/position/fix`.
pub fn position_fix_schema() -> String {
    format!(
        r#"{{
  "$schema": "https://json-schema.org/draft/2020-12/schema",
  "title": "{POSITION_FIX_SCHEMA_NAME}",
  "description": "A position fix of the vehicle (GPS at the surface, USBL) in a projected plane (x east, y north, metres) common to every mission of the site (UTM, or a local tangent plane about an agreed origin); not necessarily the mission's world frame. A prior for merging missions, never ground truth.",
  "type": "object",
  "properties": {{
    {STAMP},
    "x_m": {{ "type": "number", "description": "Easting in the common plane, metres (|x| at most 2e7)." }},
    "y_m": {{ "type": "number", "description": "Northing in the common plane, metres (|y| at most 2e7)." }},
    "std_m": {{ "type": "number", "exclusiveMinimum": 0, "maximum": 10000, "description": "Standard deviation of each axis of the fix, metres." }}
  }},
  "required": ["stamp_s", "x_m", "y_m", "std_m"],
  "additionalProperties": false
}}
"#
    )
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct BeamMsg<'a> {
    stamp_s: f64,
    angle_rad: f64,
    bin_size_m: f64,
    first_bin_range_m: f64,
    #[serde(borrow)]
    intensities: Cow<'a, str>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Xyz {
    x: f64,
    y: f64,
    z: f64,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct DvlMsg {
    stamp_s: f64,
    velocity_mps: Xyz,
    valid: bool,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    covariance_m2ps2: Option<[f64; 9]>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct AttitudeMsg {
    stamp_s: f64,
    roll_rad: f64,
    pitch_rad: f64,
    yaw_rad: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    yaw_rate_radps: Option<f64>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct GroundTruthMsg {
    stamp_s: f64,
    x_m: f64,
    y_m: f64,
    yaw_rad: f64,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PositionFixMsg {
    stamp_s: f64,
    x_m: f64,
    y_m: f64,
    std_m: f64,
}

fn to_json<T: Serialize>(msg: &T, out: &mut Vec<u8>) {
    out.clear();
    // Serialising these plain structs of finite numbers cannot fail.
    serde_json::to_writer(&mut *out, msg).expect("JSON serialisation of a plain struct");
}

/// Encodes a beam (already validated) into `out`.
pub(crate) fn encode_beam(beam: &SonarBeam, out: &mut Vec<u8>) {
    let msg = BeamMsg {
        stamp_s: beam.stamp_s,
        angle_rad: beam.angle_rad,
        bin_size_m: beam.bin_size_m,
        first_bin_range_m: beam.first_bin_range_m,
        intensities: Cow::Owned(BASE64.encode(&beam.intensities)),
    };
    to_json(&msg, out);
}

pub(crate) fn encode_dvl(dvl: &DvlVelocity, out: &mut Vec<u8>) {
    let v = &dvl.velocity_mps;
    let msg = DvlMsg {
        stamp_s: dvl.stamp_s,
        velocity_mps: Xyz {
            x: v.x,
            y: v.y,
            z: v.z,
        },
        valid: dvl.valid,
        covariance_m2ps2: dvl
            .covariance
            .map(|c| std::array::from_fn(|k| c[(k / 3, k % 3)])),
    };
    to_json(&msg, out);
}

pub(crate) fn encode_attitude(att: &Attitude, out: &mut Vec<u8>) {
    let msg = AttitudeMsg {
        stamp_s: att.stamp_s,
        roll_rad: att.roll_rad,
        pitch_rad: att.pitch_rad,
        yaw_rad: att.yaw_rad,
        yaw_rate_radps: att.yaw_rate_radps,
    };
    to_json(&msg, out);
}

pub(crate) fn encode_ground_truth(gt: &GroundTruthPose, out: &mut Vec<u8>) {
    let p = &gt.world_from_vehicle;
    let msg = GroundTruthMsg {
        stamp_s: gt.stamp_s,
        x_m: p.x(),
        y_m: p.y(),
        yaw_rad: p.theta(),
    };
    to_json(&msg, out);
}

pub(crate) fn encode_position_fix(fix: &PositionFix, out: &mut Vec<u8>) {
    let msg = PositionFixMsg {
        stamp_s: fix.stamp_s,
        x_m: fix.x_m,
        y_m: fix.y_m,
        std_m: fix.std_m,
    };
    to_json(&msg, out);
}

/// Parses one JSON message, naming the failing field by its path
/// (`velocity_mps.x`) when serde can tell it. The path is tracked only
/// when the plain parse fails (a second parse of the bad message), as
/// tracking it costs about a third of the parse.
fn from_json<'a, T: Deserialize<'a>>(data: &'a [u8]) -> Result<T, FieldError> {
    if let Ok(value) = serde_json::from_slice(data) {
        return Ok(value);
    }
    let mut de = serde_json::Deserializer::from_slice(data);
    let value: T = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let path = e.path().to_string();
        let field = if path == "." {
            "(message)".to_string()
        } else {
            path
        };
        FieldError::new(field, e.into_inner().to_string())
    })?;
    de.end()
        .map_err(|e| FieldError::new("(message)", e.to_string()))?;
    Ok(value)
}

pub(crate) fn decode_beam(data: &[u8]) -> Result<SonarBeam, FieldError> {
    let msg: BeamMsg = from_json(data)?;
    let intensities = BASE64
        .decode(msg.intensities.as_bytes())
        .map_err(|e| FieldError::new("intensities", format!("bad base64: {e}")))?;
    let beam = SonarBeam {
        stamp_s: msg.stamp_s,
        angle_rad: msg.angle_rad,
        bin_size_m: msg.bin_size_m,
        first_bin_range_m: msg.first_bin_range_m,
        intensities,
    };
    validate::beam(&beam)?;
    Ok(beam)
}

pub(crate) fn decode_dvl(data: &[u8]) -> Result<DvlVelocity, FieldError> {
    let msg: DvlMsg = from_json(data)?;
    let dvl = DvlVelocity {
        stamp_s: msg.stamp_s,
        velocity_mps: Vector3::new(msg.velocity_mps.x, msg.velocity_mps.y, msg.velocity_mps.z),
        valid: msg.valid,
        covariance: msg.covariance_m2ps2.map(|c| Matrix3::from_row_slice(&c)),
    };
    validate::dvl(&dvl)?;
    Ok(dvl)
}

pub(crate) fn decode_attitude(data: &[u8]) -> Result<Attitude, FieldError> {
    let msg: AttitudeMsg = from_json(data)?;
    let att = Attitude {
        stamp_s: msg.stamp_s,
        roll_rad: msg.roll_rad,
        pitch_rad: msg.pitch_rad,
        yaw_rad: msg.yaw_rad,
        yaw_rate_radps: msg.yaw_rate_radps,
    };
    validate::attitude(&att)?;
    Ok(att)
}

pub(crate) fn decode_ground_truth(data: &[u8]) -> Result<GroundTruthPose, FieldError> {
    let msg: GroundTruthMsg = from_json(data)?;
    // Check the raw numbers before building the pose (Se2 would hide a NaN yaw).
    validate::stamp(msg.stamp_s)?;
    for (field, v) in [("x_m", msg.x_m), ("y_m", msg.y_m), ("yaw_rad", msg.yaw_rad)] {
        if !v.is_finite() {
            return Err(FieldError::new(field, format!("value {v} is not finite")));
        }
    }
    Ok(GroundTruthPose {
        stamp_s: msg.stamp_s,
        world_from_vehicle: Se2::new(msg.x_m, msg.y_m, msg.yaw_rad),
    })
}

pub(crate) fn decode_position_fix(data: &[u8]) -> Result<PositionFix, FieldError> {
    let msg: PositionFixMsg = from_json(data)?;
    let fix = PositionFix {
        stamp_s: msg.stamp_s,
        x_m: msg.x_m,
        y_m: msg.y_m,
        std_m: msg.std_m,
    };
    validate::position_fix(&fix)?;
    Ok(fix)
}

/// Parses any JSON value of type `T` (used for the mounting metadata).
pub(crate) fn parse_owned<T: DeserializeOwned>(text: &str) -> Result<T, FieldError> {
    from_json(text.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn schemas_are_valid_json_with_their_title() {
        for (text, name) in [
            (beam_schema(), BEAM_SCHEMA_NAME),
            (dvl_schema(), DVL_SCHEMA_NAME),
            (attitude_schema(), ATTITUDE_SCHEMA_NAME),
            (ground_truth_schema(), GROUND_TRUTH_SCHEMA_NAME),
            (position_fix_schema(), POSITION_FIX_SCHEMA_NAME),
        ] {
            let v: serde_json::Value = serde_json::from_str(&text).unwrap();
            assert_eq!(v["title"], name);
            assert_eq!(v["additionalProperties"], false);
        }
    }

    #[test]
    fn beam_message_text() {
        let beam = SonarBeam {
            stamp_s: 2.5,
            angle_rad: -1.0,
            bin_size_m: 0.1,
            first_bin_range_m: 0.0,
            intensities: vec![0, 1, 255],
        };
        let mut out = Vec::new();
        encode_beam(&beam, &mut out);
        // [0, 1, 255] is "AAH/" in standard base64.
        assert_eq!(
            std::str::from_utf8(&out).unwrap(),
            r#"{"stamp_s":2.5,"angle_rad":-1.0,"bin_size_m":0.1,"first_bin_range_m":0.0,"intensities":"AAH/"}"#
        );
        assert_eq!(decode_beam(&out).unwrap(), beam);
    }

    #[test]
    fn position_fix_message_text_and_bad_fields() {
        let fix = PositionFix {
            stamp_s: 10.5,
            x_m: 482_310.25,
            y_m: 4_650_120.5,
            std_m: 2.0,
        };
        let mut out = Vec::new();
        encode_position_fix(&fix, &mut out);
        assert_eq!(
            std::str::from_utf8(&out).unwrap(),
            r#"{"stamp_s":10.5,"x_m":482310.25,"y_m":4650120.5,"std_m":2.0}"#
        );
        assert_eq!(decode_position_fix(&out).unwrap(), fix);
        for (text, field) in [
            (&br#"{"stamp_s":1,"x_m":0,"y_m":0,"std_m":0}"#[..], "std_m"),
            (br#"{"stamp_s":1,"x_m":0,"y_m":0,"std_m":-1}"#, "std_m"),
            (br#"{"stamp_s":1,"x_m":0,"y_m":0,"std_m":1e6}"#, "std_m"),
            (br#"{"stamp_s":1,"x_m":3e7,"y_m":0,"std_m":1}"#, "x_m"),
            (br#"{"stamp_s":1,"x_m":0,"y_m":null,"std_m":1}"#, "y_m"),
            (br#"{"stamp_s":-1,"x_m":0,"y_m":0,"std_m":1}"#, "stamp_s"),
            (br#"{"stamp_s":1,"x_m":0,"y_m":0}"#, "(message)"),
        ] {
            let err = decode_position_fix(text).unwrap_err();
            assert_eq!(
                err.field,
                field,
                "{}: {err:?}",
                String::from_utf8_lossy(text)
            );
        }
    }

    #[test]
    fn null_number_names_the_field() {
        let text = br#"{"stamp_s":1.0,"velocity_mps":{"x":null,"y":0,"z":0},"valid":true}"#;
        let err = decode_dvl(text).unwrap_err();
        assert_eq!(err.field, "velocity_mps.x");
    }

    #[test]
    fn unknown_field_is_rejected() {
        let text = br#"{"stamp_s":1.0,"x_m":0,"y_m":0,"yaw_rad":0,"z_m":3}"#;
        let err = decode_ground_truth(text).unwrap_err();
        assert!(err.message.contains("z_m"), "{err:?}");
    }

    #[test]
    fn escaped_base64_is_accepted() {
        // JSON may escape '/' as "\/": the reader must not require borrowing.
        let text = br#"{"stamp_s":1,"angle_rad":0,"bin_size_m":0.1,"first_bin_range_m":0,"intensities":"AAH\/"}"#;
        assert_eq!(decode_beam(text).unwrap().intensities, vec![0, 1, 255]);
    }
}
