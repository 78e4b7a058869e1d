//! Atomic outputs. A file is written to a temporary file in the
//! destination folder, flushed, then renamed over the destination
//! ([`write_atomic`]), so a reader never sees a half-written file and an
//! interrupted run leaves the previous file intact. A folder of outputs is
//! written into a fresh folder beside its target and swapped in whole
//! ([`folder::OutputFolder`]). Both are checked before any work
//! ([`prepare_output_file`], [`folder::OutputFolder::prepare`]), and what a
//! killed run left behind is recognised and removed by the next one
//! ([`stale`]).

pub mod folder;
pub mod stale;

use anyhow::{Context, Result};
use std::io::{BufWriter, Write};
use std::path::Path;

/// Writes `path` atomically with the bytes produced by `fill`.
pub fn write_atomic<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> Result<()>,
{
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create folder {}", dir.display()))?;
    // Finished outputs are ordinary files (0644 before the umask), not the
    // 0600 that temporary files get by default.
    let mut builder = tempfile::Builder::new();
    let prefix = stale::own_prefix();
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o644));
    let tmp = builder
        .tempfile_in(dir)
        .with_context(|| format!("cannot create a temporary file in {}", dir.display()))?;
    {
        let mut writer = BufWriter::new(tmp.as_file());
        fill(&mut writer).with_context(|| format!("while writing {}", path.display()))?;
        writer
            .flush()
            .with_context(|| format!("while writing {}", path.display()))?;
    }
    tmp.as_file()
        .sync_all()
        .with_context(|| format!("while syncing {}", path.display()))?;
    // Keep only the io::Error: the PersistError owns the temporary file,
    // which would otherwise live (on disk) as long as the error does.
    tmp.persist(path)
        .map_err(|e| e.error)
        .with_context(|| format!("cannot move the finished file to {}", path.display()))?;
    Ok(())
}

/// Checks before any work that the output file `path` can be written:
/// it is not a folder, its parent folders exist (created if needed) and a
/// file can be created there. Removes the temporary files that killed runs
/// left in that folder ([`stale::clean`]). The error names the path.
pub fn prepare_output_file(path: &Path) -> Result<()> {
    if path.file_name().is_none() || path.is_dir() {
        anyhow::bail!("the output {} is a folder, not a file", path.display());
    }
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    folder::create_parents(dir, path)?;
    stale::clean(dir);
    let prefix = stale::own_prefix();
    tempfile::Builder::new()
        .prefix(&prefix)
        .suffix(".tmp")
        .tempfile_in(dir)
        .with_context(|| format!("cannot write the output {}", path.display()))?;
    Ok(())
}

/// Writes a byte buffer atomically.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |w| {
        w.write_all(bytes)?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failed_write_keeps_previous_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.txt");
        write_bytes_atomic(&path, b"first").unwrap();
        let err = write_atomic(&path, |w| {
            w.write_all(b"partial")?;
            anyhow::bail!("simulated failure")
        });
        assert!(err.is_err());
        assert_eq!(std::fs::read(&path).unwrap(), b"first");
        // No temporary files are left behind.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode();
            assert_eq!(
                mode & 0o044,
                0o044,
                "outputs are readable by others: {mode:o}"
            );
        }
    }
}
