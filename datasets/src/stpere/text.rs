//! Line splitting and field parsing shared by the St Pere text logs.
//!
//! The logs are bytes, not UTF-8: header lines carry Latin-1 characters
//! (`º` in the DGPS column names). Only data lines are decoded, and a data
//! field must be ASCII. Lines end in CRLF (a final line may lack it); lines
//! starting with `%` and blank lines are skipped; fields are separated by any
//! run of spaces or tabs, so an empty `[idSensor]` column between two tabs
//! disappears. A leading UTF-8 byte-order mark is skipped.

use crate::error::DatasetError;
use std::path::{Path, PathBuf};

/// Why a data line was left out instead of failing the whole file.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum SkipReason {
    /// The last line of the file has too few columns and no line end: the
    /// logger was stopped while writing it.
    TruncatedFinalLine { columns: usize, expected: usize },
    /// The line repeats the time stamp of the line before it.
    DuplicateStamp,
    /// A DGPS fix whose status column says there is no position fix.
    NoGpsFix { status: i64 },
}

/// A data line that the reader skipped on purpose, with where it was.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SkippedLine {
    pub path: PathBuf,
    /// 1-based physical line number (header lines included).
    pub line: usize,
    pub reason: SkipReason,
}

/// One data line split into fields.
pub(crate) struct DataLine<'a> {
    /// 1-based physical line number.
    pub line: usize,
    /// True when this is the last line and it has no line end.
    pub unterminated: bool,
    pub fields: Vec<&'a [u8]>,
}

/// A whole text log in memory, with its path for error messages.
pub(crate) struct TextLog {
    pub path: PathBuf,
    bytes: Vec<u8>,
}

impl TextLog {
    pub fn read(path: &Path) -> Result<Self, DatasetError> {
        let bytes = std::fs::read(path).map_err(|e| DatasetError::io(path, e))?;
        Ok(Self {
            path: path.to_path_buf(),
            bytes,
        })
    }

    #[cfg(test)]
    pub fn from_bytes(path: &str, bytes: &[u8]) -> Self {
        Self {
            path: PathBuf::from(path),
            bytes: bytes.to_vec(),
        }
    }

    /// The data lines in file order (a leading UTF-8 byte-order mark is
    /// skipped).
    pub fn data_lines(&self) -> impl Iterator<Item = DataLine<'_>> {
        let bytes = self
            .bytes
            .strip_prefix(b"\xEF\xBB\xBF")
            .unwrap_or(&self.bytes);
        let total = bytes.len();
        let mut start = 0usize;
        bytes
            .split(|&b| b == b'\n')
            .enumerate()
            .filter_map(move |(index, raw)| {
                let end = start + raw.len();
                let unterminated = end >= total;
                start = end + 1;
                let trimmed = raw.trim_ascii();
                if trimmed.is_empty() || trimmed[0] == b'%' {
                    return None;
                }
                let fields = trimmed
                    .split(|b| b.is_ascii_whitespace())
                    .filter(|f| !f.is_empty())
                    .collect();
                Some(DataLine {
                    line: index + 1,
                    unterminated,
                    fields,
                })
            })
    }

    /// A parse error at `line`, field `field`.
    pub fn error(&self, line: usize, field: &str, message: impl Into<String>) -> DatasetError {
        DatasetError::parse(&self.path, format!("line {line}"), field, message)
    }

    /// Field `index` of `line` as a finite `f64`; `name` names the column in
    /// errors.
    pub fn float(
        &self,
        line: &DataLine<'_>,
        index: usize,
        name: &str,
    ) -> Result<f64, DatasetError> {
        let field = self.column_label(index, name);
        let raw = line
            .fields
            .get(index)
            .ok_or_else(|| self.error(line.line, &field, "missing"))?;
        let text = std::str::from_utf8(raw)
            .map_err(|_| self.error(line.line, &field, "not ASCII text"))?;
        let value: f64 = text
            .parse()
            .map_err(|_| self.error(line.line, &field, format!("`{text}` is not a number")))?;
        if !value.is_finite() {
            return Err(self.error(line.line, &field, format!("`{text}` is not finite")));
        }
        Ok(value)
    }

    /// Field `index` as an integer (written with or without a `.0` tail).
    pub fn integer(
        &self,
        line: &DataLine<'_>,
        index: usize,
        name: &str,
    ) -> Result<i64, DatasetError> {
        let value = self.float(line, index, name)?;
        if value.fract() != 0.0 || value.abs() > 9.0e15 {
            let field = self.column_label(index, name);
            return Err(self.error(line.line, &field, format!("{value} is not an integer")));
        }
        Ok(value as i64)
    }

    /// Checks the column count; `Ok(Some(skip))` for a truncated final line.
    pub fn check_columns(
        &self,
        line: &DataLine<'_>,
        expected: usize,
    ) -> Result<Option<SkippedLine>, DatasetError> {
        let columns = line.fields.len();
        if columns == expected {
            return Ok(None);
        }
        if line.unterminated && columns < expected {
            return Ok(Some(self.skip(
                line.line,
                SkipReason::TruncatedFinalLine { columns, expected },
            )));
        }
        Err(self.error(
            line.line,
            "columns",
            format!("{columns} columns, expected {expected}"),
        ))
    }

    pub fn skip(&self, line: usize, reason: SkipReason) -> SkippedLine {
        SkippedLine {
            path: self.path.clone(),
            line,
            reason,
        }
    }

    fn column_label(&self, index: usize, name: &str) -> String {
        format!("column {} ({name})", index + 1)
    }
}

/// The column layout of one log, for [`TextLog::for_each_record`].
pub(crate) struct Layout<'n> {
    /// Data columns with the `[idSensor]` column empty.
    pub columns: usize,
    /// The log has an optional `[idSensor]` column after the time: a line
    /// with one column more has it filled, shifting every later column.
    pub optional_id: bool,
    /// Name of the time column (column 1) in errors.
    pub time: &'n str,
}

/// One record: its line, the shift of the columns after the time (1 when
/// the `[idSensor]` column is filled) and its time stamp.
pub(crate) struct Record<'l, 'a> {
    pub line: &'l DataLine<'a>,
    pub shift: usize,
    pub stamp_s: f64,
}

impl TextLog {
    /// Calls `visit` on every data line with the right column count and a
    /// time not earlier than the line before, and returns the lines it
    /// skipped: a truncated final line, a repeated stamp, and every record
    /// for which `visit` returns a reason to skip it. A wrong column count
    /// elsewhere, a bad number or a time going back is an error naming the
    /// line and column.
    pub fn for_each_record(
        &self,
        layout: &Layout<'_>,
        mut visit: impl FnMut(Record<'_, '_>) -> Result<Option<SkipReason>, DatasetError>,
    ) -> Result<Vec<SkippedLine>, DatasetError> {
        let mut skipped = Vec::new();
        let mut order = StampOrder::new();
        for line in self.data_lines() {
            let shift = usize::from(layout.optional_id && line.fields.len() == layout.columns + 1);
            if let Some(skip) = self.check_columns(&line, layout.columns + shift)? {
                skipped.push(skip);
                continue;
            }
            let stamp_s = self.float(&line, 0, layout.time)?;
            if !order.accept(self, line.line, stamp_s)? {
                skipped.push(self.skip(line.line, SkipReason::DuplicateStamp));
                continue;
            }
            let number = line.line;
            let record = Record {
                line: &line,
                shift,
                stamp_s,
            };
            if let Some(reason) = visit(record)? {
                skipped.push(self.skip(number, reason));
            }
        }
        Ok(skipped)
    }
}

/// Tracks the time column of one log: equal stamps are skipped (a logger
/// glitch), a stamp earlier than the previous one is an error.
pub(crate) struct StampOrder {
    previous_s: Option<f64>,
}

impl StampOrder {
    pub fn new() -> Self {
        Self { previous_s: None }
    }

    /// `Ok(true)` to keep the line, `Ok(false)` to skip a duplicate.
    pub fn accept(
        &mut self,
        log: &TextLog,
        line: usize,
        stamp_s: f64,
    ) -> Result<bool, DatasetError> {
        match self.previous_s {
            Some(prev) if stamp_s < prev => Err(log.error(
                line,
                "column 1 (time)",
                format!("time {stamp_s} is earlier than the previous line's {prev}"),
            )),
            Some(prev) if stamp_s == prev => Ok(false),
            _ => {
                self.previous_s = Some(stamp_s);
                Ok(true)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_crlf_headers_tabs_and_latin1() {
        let log = TextLog::from_bytes("x.log", b"% head\xba\r\n\r\n1.5\t\t2 3\r\n4 5 6");
        let lines: Vec<_> = log.data_lines().collect();
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[0].line, 3);
        assert_eq!(lines[0].fields, vec![&b"1.5"[..], b"2", b"3"]);
        assert!(!lines[0].unterminated);
        assert_eq!(lines[1].line, 4);
        assert!(lines[1].unterminated);
    }

    #[test]
    fn a_leading_byte_order_mark_is_skipped() {
        let log = TextLog::from_bytes("x.log", b"\xEF\xBB\xBF% head\r\n1 2\r\n");
        let lines: Vec<_> = log.data_lines().collect();
        assert_eq!(lines.len(), 1);
        assert_eq!((lines[0].line, lines[0].fields.len()), (2, 2));
    }

    #[test]
    fn nan_and_text_fields_name_line_and_column() {
        let log = TextLog::from_bytes("x.log", b"1 nan\n2 abc\n");
        let lines: Vec<_> = log.data_lines().collect();
        let err = log.float(&lines[0], 1, "roll").unwrap_err().to_string();
        assert!(
            err.contains("line 1") && err.contains("column 2 (roll)"),
            "{err}"
        );
        let err = log.float(&lines[1], 1, "roll").unwrap_err().to_string();
        assert!(err.contains("line 2") && err.contains("`abc`"), "{err}");
    }

    #[test]
    fn stamps_going_back_are_errors_and_repeats_are_skipped() {
        let log = TextLog::from_bytes("x.log", b"");
        let mut order = StampOrder::new();
        assert!(order.accept(&log, 1, 10.0).unwrap());
        assert!(!order.accept(&log, 2, 10.0).unwrap());
        assert!(order.accept(&log, 3, 11.0).unwrap());
        let err = order.accept(&log, 4, 10.5).unwrap_err().to_string();
        assert!(err.contains("line 4") && err.contains("earlier"), "{err}");
    }
}
