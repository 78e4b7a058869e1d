use crate::GraphError;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Errors from reading or writing graph and trajectory files.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum IoError {
    // The OS error is the `source`, not part of this message, so that error
    // chains (`{:#}` in the CLI) print it once.
    #[error("I/O error on {}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: the file holds no records", path.display())]
    Empty { path: PathBuf },
    /// A line whose content cannot be used.
    #[error("{}:{line}: field `{field}`: {message}", path.display())]
    Parse {
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        field: String,
        message: String,
    },
    /// A record that parses but does not fit the graph (duplicate vertex,
    /// edge to a missing vertex, information not positive definite).
    // `error` is part of this message and deliberately not a `source`:
    // an error chain (`{:#}`) would print its text a second time.
    #[error("{}:{line}: {error}", path.display())]
    Graph {
        path: PathBuf,
        line: usize,
        error: GraphError,
    },
}

impl IoError {
    pub(crate) fn parse(
        path: &Path,
        line: usize,
        field: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        IoError::Parse {
            path: path.to_path_buf(),
            line,
            field: field.into(),
            message: message.into(),
        }
    }

    pub(crate) fn graph(path: &Path, line: usize, error: GraphError) -> Self {
        IoError::Graph {
            path: path.to_path_buf(),
            line,
            error,
        }
    }

    /// The 1-based line the error refers to, if any.
    pub fn line(&self) -> Option<usize> {
        match self {
            IoError::Parse { line, .. } | IoError::Graph { line, .. } => Some(*line),
            _ => None,
        }
    }
}
