//! The ASCII PCD v0.7 point sets of the keyframe folders.
//!
//! Written here rather than taken from a PCD crate: only this one layout
//! is accepted, and every rejection must name the line and the field.

use crate::error::DatasetError;
use std::path::Path;

/// A point of a PCD file with its line.
pub(super) struct Point {
    pub line: usize,
    pub x: f64,
    pub y: f64,
}

/// Reads an ASCII PCD v0.7 file with fields `x y z` (a leading byte-order
/// mark is skipped). Errors name the line and field: a header without
/// `DATA ascii` or `POINTS`, fields other than `x y z` of count 1, a data
/// line without three finite numbers, a point count other than declared.
pub(super) fn read_pcd(path: &Path) -> Result<Vec<Point>, DatasetError> {
    let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, e))?;
    let text = utf8(path, &bytes)?;
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = text.lines().enumerate().map(|(i, l)| (i + 1, l.trim()));
    let declared = read_header(path, &mut lines)?;
    // The declared count is only trusted as far as the file could hold it
    // (a point takes at least six bytes): a corrupted POINTS line must not
    // reserve memory the data cannot fill.
    let mut points = Vec::with_capacity(declared.min(bytes.len() / 6));
    for (line, content) in lines {
        if !content.is_empty() {
            points.push(parse_point(path, line, content)?);
        }
    }
    if points.len() != declared {
        return Err(DatasetError::Format {
            path: path.to_path_buf(),
            message: format!(
                "the header declares {declared} points, the data holds {} (a truncated file?)",
                points.len()
            ),
        });
    }
    Ok(points)
}

/// `bytes` as text; an error names the line of the first invalid byte.
fn utf8<'a>(path: &Path, bytes: &'a [u8]) -> Result<&'a str, DatasetError> {
    std::str::from_utf8(bytes).map_err(|e| {
        let offset = e.valid_up_to();
        let line = bytes[..offset].iter().filter(|&&b| b == b'\n').count() + 1;
        DatasetError::parse(
            path,
            format!("line {line}"),
            "text",
            format!("invalid UTF-8 at byte {offset}: a PCD header and ASCII data are expected"),
        )
    })
}

fn line_error(path: &Path, line: usize, field: &str, message: String) -> DatasetError {
    DatasetError::parse(path, format!("line {line}"), field, message)
}

/// Reads the header, `KEY value...` lines up to and including `DATA`, from
/// `lines` (numbered, trimmed); returns the declared point count.
fn read_header<'a>(
    path: &Path,
    lines: &mut impl Iterator<Item = (usize, &'a str)>,
) -> Result<usize, DatasetError> {
    let err = |line: usize, field: &str, message: String| line_error(path, line, field, message);
    let mut declared_points: Option<usize> = None;
    loop {
        let Some((line, content)) = lines.next() else {
            return Err(DatasetError::Format {
                path: path.to_path_buf(),
                message: "the header ends without a DATA line".into(),
            });
        };
        if content.is_empty() || content.starts_with('#') {
            continue;
        }
        let mut words = content.split_whitespace();
        let key = words.next().unwrap_or_default();
        let values: Vec<&str> = words.collect();
        match key {
            "FIELDS" if values != ["x", "y", "z"] => {
                return Err(err(
                    line,
                    "FIELDS",
                    format!("`{}`: only `x y z` point sets are read", values.join(" ")),
                ));
            }
            "COUNT" if values.iter().any(|&v| v != "1") => {
                return Err(err(line, "COUNT", "every field must have count 1".into()));
            }
            "POINTS" => {
                let n = values
                    .first()
                    .and_then(|v| v.parse().ok())
                    .ok_or_else(|| err(line, "POINTS", "not a point count".into()))?;
                declared_points = Some(n);
            }
            "DATA" if values != ["ascii"] => {
                return Err(err(
                    line,
                    "DATA",
                    format!(
                        "`{}`: only ASCII PCD files are read (convert binary ones with \
                         `pcl_convert_pcd_ascii_binary IN OUT 0`)",
                        values.join(" ")
                    ),
                ));
            }
            "DATA" => break,
            _ => {}
        }
    }
    declared_points.ok_or_else(|| DatasetError::Format {
        path: path.to_path_buf(),
        message: "the header has no POINTS line".into(),
    })
}

/// One data line (not empty): three finite numbers `x y z`.
fn parse_point(path: &Path, line: usize, content: &str) -> Result<Point, DatasetError> {
    let fields: Vec<&str> = content.split_whitespace().collect();
    if fields.len() != 3 {
        return Err(line_error(
            path,
            line,
            "x y z",
            format!("{} values, expected 3", fields.len()),
        ));
    }
    let value = |i: usize| -> Result<f64, DatasetError> {
        let name = ["x", "y", "z"][i];
        match fields[i].parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(v),
            _ => Err(line_error(
                path,
                line,
                name,
                format!("`{}` is not a finite number", fields[i]),
            )),
        }
    };
    let (x, y) = (value(0)?, value(1)?);
    value(2)?;
    Ok(Point { line, x, y })
}
