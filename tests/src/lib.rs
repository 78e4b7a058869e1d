//! End-to-end scenarios across the echofield crates live in `tests/tests/`;
//! this library holds helpers they share (paths to the committed datasets).

use std::path::PathBuf;

/// The repository's `datasets/` folder.
pub fn datasets_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .join("datasets")
}
