//! Whitespace-separated records with typed field access and precise errors.

use super::IoError;
use std::path::Path;

/// One non-empty, non-comment line split into tokens.
pub(crate) struct Record<'a> {
    /// 1-based line number.
    pub line: usize,
    pub tokens: Vec<&'a str>,
}

/// The records of a text: blank lines and lines starting with `#` are
/// skipped; CRLF line ends are accepted.
pub(crate) fn records(text: &str) -> impl Iterator<Item = Record<'_>> {
    text.lines().enumerate().filter_map(|(i, line)| {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            return None;
        }
        Some(Record {
            line: i + 1,
            tokens: line.split_whitespace().collect(),
        })
    })
}

impl<'a> Record<'a> {
    pub fn tag(&self) -> &'a str {
        self.tokens[0]
    }

    /// Checks the number of tokens after the tag.
    pub fn expect_fields(&self, path: &Path, names: &[&str]) -> Result<(), IoError> {
        let got = self.tokens.len() - 1;
        if got == names.len() {
            return Ok(());
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
