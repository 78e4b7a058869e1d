//! Whitespace-separated records with typed field access and precise errors.

use super::IoError;
use std::path::Path;

/// The UTF-8 byte-order mark some editors put at the start of a text file.
const BOM: char = '\u{feff}';

/// Largest magnitude accepted for a position or translation, metres: no
/// pose graph or trajectory spans a million kilometres, and squares of
/// larger values overflow the solver's and the evaluation's sums.
pub const MAX_ABS_POSITION_M: f64 = 1e9;
/// Largest magnitude accepted for an angle, radians (files write angles
/// within a few turns; a larger one is a corrupted value).
pub const MAX_ABS_ANGLE_RAD: f64 = 1e3;
/// Largest magnitude accepted for an information-matrix entry (a standard
/// deviation of 1e-9 m); the standard data sets stay below 1e9.
pub const MAX_ABS_INFORMATION: f64 = 1e18;

/// One non-empty, non-comment line split into tokens.
pub(crate) struct Record<'a> {
    /// 1-based line number.
    pub line: usize,
    pub tokens: Vec<&'a str>,
    /// The last line of the text, without a line end: the file may have
    /// been cut inside it.
    pub unterminated: bool,
}

/// The text without a leading byte-order mark.
pub(crate) fn strip_bom(text: &str) -> &str {
    text.strip_prefix(BOM).unwrap_or(text)
}

/// The records of a text: a leading byte-order mark is skipped, blank
/// lines and lines starting with `#` are skipped; CRLF line ends are
/// accepted.
pub(crate) fn records(text: &str) -> impl Iterator<Item = Record<'_>> {
    let text = strip_bom(text);
    let ends_with_newline = text.ends_with('\n');
    let count = text.lines().count();
    text.lines().enumerate().filter_map(move |(i, line)| {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            return None;
        }
        Some(Record {
            line: i + 1,
            tokens: line.split_whitespace().collect(),
            unterminated: i + 1 == count && !ends_with_newline,
        })
    })
}

/// Decodes a file's bytes as UTF-8; an invalid sequence is an error naming
/// its line, column and byte offset.
pub(crate) fn decode_utf8(bytes: Vec<u8>, path: &Path) -> Result<String, IoError> {
    String::from_utf8(bytes).map_err(|e| {
        let bytes = e.as_bytes();
        let offset = e.utf8_error().valid_up_to();
        let before = &bytes[..offset];
        let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
        let line_start = before.iter().rposition(|&b| b == b'\n').map_or(0, |k| k + 1);
        IoError::parse(
            path,
            line,
            "text",
            format!(
                "invalid UTF-8 at byte {offset} (column {}, byte 0x{:02x}): the file must be UTF-8 or ASCII text",
                offset - line_start + 1,
                bytes[offset]
            ),
        )
    })
}

impl<'a> Record<'a> {
    pub fn tag(&self) -> &'a str {
        self.tokens[0]
    }

    /// Checks the number of tokens after the tag, and that the record is
    /// not the unterminated last line of the file (see
    /// [`Record::expect_terminated`]).
    pub fn expect_fields(&self, path: &Path, names: &[&str]) -> Result<(), IoError> {
        let got = self.tokens.len() - 1;
        if got == names.len() {
            return self.expect_terminated(path, names.last().copied().unwrap_or("tag"));
        }
        let field = names.get(got).copied().unwrap_or("end of line");
        let message = if got < names.len() {
            format!(
                "{} expects {} values ({}), found {got} (truncated line?)",
                self.tag(),
                names.len(),
                names.join(" ")
            )
        } else {
            format!(
                "{} expects {} values ({}), found {got}",
                self.tag(),
                names.len(),
                names.join(" ")
            )
        };
        Err(IoError::parse(path, self.line, field, message))
    }

    /// A record on the last line of a file that does not end with a line
    /// end may have lost the end of its last value when the file was cut
    /// (`...0 1000` written, `...0 10` kept): refused, since the value
    /// cannot be trusted. `last_field` names that value.
    pub fn expect_terminated(&self, path: &Path, last_field: &str) -> Result<(), IoError> {
        if !self.unterminated {
            return Ok(());
        }
        let last = self.tokens.last().copied().unwrap_or_default();
        Err(IoError::parse(
            path,
            self.line,
            last_field,
            format!(
                "the file ends inside this line, without a line end: its last value `{last}` \
                 may be cut off (truncated file?); if the line is complete, end the file with a newline"
            ),
        ))
    }

    /// Token `index` (1-based after the tag) as a finite f64.
    pub fn f64(&self, path: &Path, index: usize, name: &str) -> Result<f64, IoError> {
        let token = self.token(path, index, name)?;
        let value: f64 = token.parse().map_err(|_| {
            IoError::parse(path, self.line, name, format!("`{token}` is not a number"))
        })?;
        if !value.is_finite() {
            return Err(IoError::parse(
                path,
                self.line,
                name,
                format!("`{token}` is not finite"),
            ));
        }
        Ok(value)
    }

    /// Token `index` as a finite f64 of magnitude at most `limit`; `what`
    /// says what the limit is for in the error.
    pub fn bounded(
        &self,
        path: &Path,
        index: usize,
        name: &str,
        limit: f64,
        what: &str,
    ) -> Result<f64, IoError> {
        let value = self.f64(path, index, name)?;
        if value.abs() > limit {
            return Err(IoError::parse(
                path,
                self.line,
                name,
                format!("{value} is out of range: {what} must lie within ±{limit:e}"),
            ));
        }
        Ok(value)
    }

    /// Token `index` as a non-negative integer id.
    pub fn id(&self, path: &Path, index: usize, name: &str) -> Result<u64, IoError> {
        let token = self.token(path, index, name)?;
        token.parse().map_err(|_| {
            IoError::parse(
                path,
                self.line,
                name,
                format!("`{token}` is not a non-negative integer id"),
            )
        })
    }

    fn token(&self, path: &Path, index: usize, name: &str) -> Result<&'a str, IoError> {
        self.tokens
            .get(index)
            .copied()
            .ok_or_else(|| IoError::parse(path, self.line, name, "missing value (truncated line?)"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_leading_bom_is_skipped_and_the_last_line_is_marked() {
        let found: Vec<_> = records("\u{feff}A 1\r\nB 2").collect();
        assert_eq!(found[0].tokens, ["A", "1"]);
        assert!(!found[0].unterminated);
        assert_eq!((found[1].line, found[1].unterminated), (2, true));
        assert!(records("A 1\n").all(|r| !r.unterminated));
    }

    #[test]
    fn invalid_utf8_names_line_column_and_offset() {
        let err = decode_utf8(b"A 1\nB \xff2\n".to_vec(), Path::new("x.g2o")).unwrap_err();
        let message = err.to_string();
        assert_eq!(err.line(), Some(2));
        assert!(
            message.contains("x.g2o:2")
                && message.contains("byte 6")
                && message.contains("column 3")
                && message.contains("0xff"),
            "{message}"
        );
    }
}
