//! rosbag2 folders: a `metadata.yaml` beside the storage files that
//! `ros2 bag record` writes.
//!
//! MCAP storage (each file an MCAP file of ROS 2 messages) and sqlite3
//! storage (`.db3` files, [`crate::ros::sqlite`]) are read, their files in
//! the order `relative_file_paths` lists them; another storage is an error
//! that says how to convert it (`ros2 bag convert`). Compressed files
//! (`compression_mode: FILE`) are refused the same way; MCAP's own chunk
//! compression is read as usual.

use crate::DatasetError;
use std::path::{Path, PathBuf};
use yaml_rust2::{Yaml, YamlLoader};

/// The name of the rosbag2 metadata file.
pub const METADATA_FILE: &str = "metadata.yaml";

/// Whether `dir` looks like a rosbag2 folder (it holds `metadata.yaml`).
pub fn is_rosbag2(dir: &Path) -> bool {
    dir.join(METADATA_FILE).is_file()
}

/// The storage of a rosbag2 folder.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Storage {
    Mcap,
    Sqlite3,
}

/// The MCAP files of the rosbag2 folder `dir`, in recording order (an
/// error for another storage).
pub fn mcap_files(dir: &Path) -> Result<Vec<PathBuf>, DatasetError> {
    let (storage, files) = storage_files(dir)?;
    if storage != Storage::Mcap {
        return Err(DatasetError::Format {
            path: dir.join(METADATA_FILE),
            message: "the recording's storage is sqlite3, not MCAP".to_string(),
        });
    }
    Ok(files)
}

/// The storage and the files of the rosbag2 folder `dir`, in recording
/// order.
pub fn storage_files(dir: &Path) -> Result<(Storage, Vec<PathBuf>), DatasetError> {
    let path = dir.join(METADATA_FILE);
    if !path.is_file() {
        return Err(DatasetError::Missing {
            path: dir.to_path_buf(),
            what: format!("{METADATA_FILE} (the folder is not a rosbag2 recording)"),
        });
    }
    let text = std::fs::read_to_string(&path).map_err(|e| DatasetError::io(&path, e))?;
    let docs = YamlLoader::load_from_str(&text).map_err(|e| DatasetError::Format {
        path: path.clone(),
        message: format!("not valid YAML: {e}"),
    })?;
    let info = docs
        .first()
        .map(|d| &d["rosbag2_bagfile_information"])
        .filter(|i| !i.is_badvalue())
        .ok_or_else(|| {
            DatasetError::parse(&path, "document", "rosbag2_bagfile_information", "missing")
        })?;
    let metadata = Metadata {
        dir,
        path: &path,
        info,
    };
    let storage = metadata.storage()?;
    Ok((storage, metadata.files()?))
}

/// The `rosbag2_bagfile_information` of `path` in the folder `dir`.
struct Metadata<'a> {
    dir: &'a Path,
    path: &'a Path,
    info: &'a Yaml,
}

impl Metadata<'_> {
    fn field(&self, name: &str, message: &str) -> DatasetError {
        DatasetError::parse(self.path, "rosbag2_bagfile_information", name, message)
    }

    /// The storage (MCAP or sqlite3); an error for another, or for
    /// whole-file compression.
    fn storage(&self) -> Result<Storage, DatasetError> {
        let info = self.info;
        let storage = info["storage_identifier"]
            .as_str()
            .ok_or_else(|| self.field("storage_identifier", "missing or not a string"))?;
        let storage = match storage {
            "mcap" => Storage::Mcap,
            "sqlite3" => Storage::Sqlite3,
            _ => {
                return Err(self.field(
                    "storage_identifier",
                    &format!(
                        "`{storage}` storage is not read (mcap and sqlite3 are); convert the recording to MCAP with \
                 `ros2 bag convert -i {} -o out.yaml` (out.yaml: `output_bags: [{{uri: bag_mcap, storage_id: mcap}}]`)",
                        self.dir.display()
                    ),
                ));
            }
        };
        if let Some(mode) = info["compression_mode"].as_str()
            && !mode.is_empty()
            && mode != "NONE"
        {
            return Err(self.field(
                "compression_mode",
                &format!(
                    "`{mode}` compression of whole files is not read; decompress with `ros2 bag convert`"
                ),
            ));
        }
        Ok(storage)
    }

    /// The listed storage files, each of which must exist; at least one.
    fn files(&self) -> Result<Vec<PathBuf>, DatasetError> {
        let Yaml::Array(files) = &self.info["relative_file_paths"] else {
            return Err(self.field("relative_file_paths", "missing or not a list"));
        };
        let mut out = Vec::with_capacity(files.len());
        for (i, file) in files.iter().enumerate() {
            let name = file
                .as_str()
                .ok_or_else(|| self.field(&format!("relative_file_paths[{i}]"), "not a string"))?;
            let file_path = self.dir.join(name);
            if !file_path.is_file() {
                return Err(DatasetError::Missing {
                    path: file_path,
                    what: format!("storage file listed in {}", self.path.display()),
                });
            }
            out.push(file_path);
        }
        if out.is_empty() {
            return Err(self.field("relative_file_paths", "lists no file"));
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn folder(metadata: &str, files: &[&str]) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join(METADATA_FILE), metadata).unwrap();
        for f in files {
            std::fs::write(dir.path().join(f), b"").unwrap();
        }
        dir
    }

    const MCAP: &str = "rosbag2_bagfile_information:\n  storage_identifier: mcap\n  compression_mode: ''\n  relative_file_paths:\n  - a_0.mcap\n  - a_1.mcap\n";

    #[test]
    fn lists_the_mcap_files_in_order() {
        let dir = folder(MCAP, &["a_0.mcap", "a_1.mcap"]);
        let files = mcap_files(dir.path()).unwrap();
        assert_eq!(
            files,
            [dir.path().join("a_0.mcap"), dir.path().join("a_1.mcap")]
        );
        assert!(is_rosbag2(dir.path()));
    }

    #[test]
    fn other_storage_missing_files_and_bad_yaml_are_named() {
        let dir = folder(
            &MCAP.replace("mcap\n  compression", "leveldb\n  compression"),
            &[],
        );
        let e = mcap_files(dir.path()).unwrap_err().to_string();
        assert!(
            e.contains("storage_identifier") && e.contains("ros2 bag convert"),
            "{e}"
        );
        let dir = folder(MCAP, &["a_0.mcap"]);
        let e = mcap_files(dir.path()).unwrap_err().to_string();
        assert!(e.contains("a_1.mcap"), "{e}");
        let dir = folder("rosbag2_bagfile_information: [\n", &[]);
        let e = mcap_files(dir.path()).unwrap_err().to_string();
        assert!(e.contains("metadata.yaml") && e.contains("YAML"), "{e}");
        let dir = folder("other: 1\n", &[]);
        let e = mcap_files(dir.path()).unwrap_err().to_string();
        assert!(e.contains("rosbag2_bagfile_information"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        assert!(!is_rosbag2(dir.path()));
        assert!(
            mcap_files(dir.path())
                .unwrap_err()
                .to_string()
                .contains("not a rosbag2")
        );
    }
}
