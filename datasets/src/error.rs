//! One error type for every reader and writer of this crate. Each variant
//! names the file and, for bad content, the record (line, message index,
//! byte offset) and the field, so a user can find the problem in their log.

use std::path::PathBuf;
use thiserror::Error;

#[derive(Debug, Error)]
#[non_exhaustive]
pub enum DatasetError {
    /// The file or folder could not be opened, read or written.
    // The OS error is the `source`, not part of this message, so that error
    // chains (`{:#}` in the CLI) print it once.
    #[error("I/O error on {}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A record holds a value that cannot be used.
    #[error("{}: {record}: field `{field}`: {message}", path.display())]
    Parse {
        path: PathBuf,
        /// Where in the file: "line 12", "message 5 (channel /dvl)", "byte 1024".
        record: String,
        /// The field or column that is wrong.
        field: String,
        message: String,
    },
    /// The file as a whole is not in the expected format (bad magic, truncated
    /// container, wrong schema).
    #[error("{}: {message}", path.display())]
    Format { path: PathBuf, message: String },
    /// A required sensor stream or file is absent.
    #[error("{}: missing {what}", path.display())]
    Missing { path: PathBuf, what: String },
}

impl DatasetError {
    /// Shorthand for [`DatasetError::Parse`].
    pub fn parse(
        path: impl Into<PathBuf>,
        record: impl Into<String>,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        DatasetError::Parse {
            path: path.into(),
            record: record.into(),
            field: field.into(),
            message: message.into(),
        }
    }

    /// Shorthand for [`DatasetError::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        DatasetError::Io {
            path: path.into(),
            source,
        }
    }
}

pub type Result<T, E = DatasetError> = std::result::Result<T, E>;
