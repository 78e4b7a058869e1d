//! Whole output folders: a run writes into a fresh folder beside its
//! target and swaps it in at the end, so that the target is always either
//! the previous complete output or the new complete output.
//!
//! [`OutputFolder::prepare`] runs before any work: it resolves the target
//! (a symbolic link is followed, so the link stays), creates its parent
//! folders, removes what killed runs left there ([`super::stale`]), checks
//! that the target may be replaced (absent, an empty folder, or an earlier
//! echofield output: a `report.json` naming an `echofield_version` and
//! nothing but the files such a run writes) and creates the fresh folder
//! `.echofield-{pid}-{tag}.new-NAME` in the target's parent, which proves
//! that the parent is writable. Every error names the path at fault.
//!
//! [`OutputFolder::commit`] checks the target again (files may have come
//! while the run worked), then swaps: on Linux with one atomic
//! `renameat2(RENAME_EXCHANGE)`; where that is not supported, by moving
//! the previous output aside (`.old-NAME`) and the new one into place, two
//! renames between which a kill leaves the previous output aside, to be
//! moved back by the next run ([`super::stale::clean`]). The previous output
//! is then renamed `.del-NAME` and deleted.
//!
//! Dropping an [`OutputFolder`] without committing it (any error, a panic)
//! removes the fresh folder and the parent folders that `prepare` created.
//! The swap needs room for both outputs at once.

use super::stale;
use anyhow::{Context, Result, bail};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};

/// A fresh output folder beside its target; see the module doc.
#[derive(Debug)]
pub struct OutputFolder {
    /// The folder that [`commit`](Self::commit) replaces.
    target: PathBuf,
    /// Where the outputs are written; `None` once committed.
    fresh: Option<PathBuf>,
    /// File names that an earlier output in `target` may hold.
    known: Vec<String>,
    /// Parent folders `prepare` created, outermost first; emptied by a
    /// commit, removed (when empty) by a drop without one.
    created: Vec<PathBuf>,
}

/// How many entries [`check_replaceable`] names in its error.
const NAMED_ENTRIES: usize = 5;

impl OutputFolder {
    /// Prepares the output folder `target` (see the module doc); `known`
    /// are the names of the files that an echofield output in `target` may
    /// hold (the marker `report.json` included), every other entry but
    /// echofield's temporary ones makes the target not replaceable.
    pub fn prepare(target: &Path, known: &[&str]) -> Result<Self> {
        let target = resolve(target)?;
        let (parent, name) = split(&target)?;
        let created = create_parents(&parent, &target)?;
        let mut folder = Self {
            target: target.clone(),
            fresh: None,
            known: known.iter().map(|s| s.to_string()).collect(),
            created,
        };
        stale::clean(&parent);
        check_replaceable(&target, &folder.known)?;
        folder.fresh = Some(
            create_fresh(&parent, &format!("new-{name}"))
                .with_context(|| format!("cannot write the output folder {}", target.display()))?,
        );
        Ok(folder)
    }

    /// The folder to write the outputs into (empty after `prepare`).
    pub fn path(&self) -> &Path {
        self.fresh.as_deref().unwrap_or(&self.target)
    }

    /// The folder the outputs will replace.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Makes the written outputs the target folder (see the module doc).
    /// On an error the target is the previous output; when the target has
    /// become something echofield may not replace, the new outputs are
    /// kept beside it and the error says where.
    pub fn commit(self) -> Result<()> {
        self.commit_with(true)
    }

    /// [`commit`](Self::commit), with the atomic exchange only when
    /// `try_exchange` (the tests exercise the two-rename path with it off).
    fn commit_with(mut self, try_exchange: bool) -> Result<()> {
        let Some(fresh) = self.fresh.clone() else {
            return Ok(());
        };
        sync_dir(&fresh);
        let (parent, name) = split(&self.target)?;
        if let Err(e) = check_replaceable(&self.target, &self.known) {
            return Err(self.keep_aside(&fresh, &parent, &name, e));
        }
        if std::fs::symlink_metadata(&self.target).is_err() && self.move_into_place(&fresh)? {
            self.committed(&parent);
            return Ok(());
        }
        let previous = self.swap_in(&fresh, &parent, &name, try_exchange)?;
        self.committed(&parent);
        delete_previous(&parent, &name, &previous);
        Ok(())
    }

    /// The new outputs are the target now: nothing to clean up on drop.
    fn committed(&mut self, parent: &Path) {
        self.fresh = None;
        self.created.clear();
        sync_dir(parent);
    }

    /// Moves the new outputs beside the target (it became something
    /// echofield may not replace: `e`), to `NAME.new` or a free variant of
    /// it; the error says where they are.
    fn keep_aside(
        &mut self,
        fresh: &Path,
        parent: &Path,
        name: &str,
        e: anyhow::Error,
    ) -> anyhow::Error {
        let aside = free_sibling(parent, &format!("{name}.new"));
        if let Err(rename) = std::fs::rename(fresh, &aside)
            .with_context(|| format!("cannot keep the new outputs in {}", aside.display()))
        {
            return rename;
        }
        self.fresh = None;
        self.created.clear();
        e.context(format!(
            "the new outputs are in {}, the target changed during the run",
            aside.display()
        ))
    }

    /// Renames the new outputs to the target, which did not exist: true
    /// when done, false when another run put its output there since (it is
    /// replaced by [`Self::swap_in`] after checking it may be).
    fn move_into_place(&self, fresh: &Path) -> Result<bool> {
        match std::fs::rename(fresh, &self.target) {
            Ok(()) => Ok(true),
            Err(e)
                if matches!(
                    e.kind(),
                    std::io::ErrorKind::DirectoryNotEmpty | std::io::ErrorKind::AlreadyExists
                ) =>
            {
                check_replaceable(&self.target, &self.known)?;
                Ok(false)
            }
            Err(e) => Err(e).with_context(|| {
                format!("cannot move the new outputs to {}", self.target.display())
            }),
        }
    }

    /// Replaces the existing target with the new outputs, by an atomic
    /// exchange when `try_exchange` and the system can, else by moving the
    /// target aside (`old-NAME...`) and the new outputs in (putting the
    /// previous output back when that fails). Returns where the previous
    /// output is now.
    fn swap_in(
        &self,
        fresh: &Path,
        parent: &Path,
        name: &str,
        try_exchange: bool,
    ) -> Result<PathBuf> {
        if try_exchange && exchange(fresh, &self.target)? {
            return Ok(fresh.to_path_buf());
        }
        let aside = fresh_name(parent, &format!("old-{name}"));
        std::fs::rename(&self.target, &aside).with_context(|| {
            format!(
                "cannot move the previous output {} aside",
                self.target.display()
            )
        })?;
        if let Err(e) = std::fs::rename(fresh, &self.target) {
            // Put the previous output back before reporting.
            let _ = std::fs::rename(&aside, &self.target);
            return Err(e).with_context(|| {
                format!("cannot move the new outputs to {}", self.target.display())
            });
        }
        Ok(aside)
    }
}

/// Deletes the previous output at `previous` (a warning when it cannot).
/// A rename first, so that a kill while deleting leaves an entry that the
/// next run removes rather than moves back.
fn delete_previous(parent: &Path, name: &str, previous: &Path) {
    let doomed = fresh_name(parent, &format!("del-{name}"));
    let doomed = match std::fs::rename(previous, &doomed) {
        Ok(()) => doomed,
        Err(_) => previous.to_path_buf(),
    };
    if let Err(e) = std::fs::remove_dir_all(&doomed) {
        tracing::warn!(
            "cannot delete the previous output, moved to {}: {e}",
            doomed.display()
        );
    }
}

impl Drop for OutputFolder {
    fn drop(&mut self) {
        if let Some(fresh) = self.fresh.take()
            && let Err(e) = std::fs::remove_dir_all(&fresh)
            && e.kind() != std::io::ErrorKind::NotFound
        {
            tracing::warn!("cannot remove {}: {e}", fresh.display());
        }
        // Not committed: the parent folders that `prepare` created go too,
        // if still empty (nothing else was put there since).
        for dir in self.created.iter().rev() {
            let _ = std::fs::remove_dir(dir);
        }
    }
}

/// `target` made absolute, through a symbolic link if it is one.
fn resolve(target: &Path) -> Result<PathBuf> {
    // `.`, `..`, `/`: replacing them would pull the folder from under the
    // user's shell (or be impossible).
    if target.file_name().is_none() {
        bail!(
            "{} names no folder that echofield can replace (give a path such as out/run)",
            target.display()
        );
    }
    let absolute = std::path::absolute(target)
        .with_context(|| format!("cannot use {} as an output folder", target.display()))?;
    match std::fs::symlink_metadata(&absolute) {
        Ok(m) if m.file_type().is_symlink() => std::fs::canonicalize(&absolute)
            .with_context(|| format!("cannot follow the link {}", target.display())),
        _ => Ok(absolute),
    }
}

/// The parent folder and the file name of `target`.
fn split(target: &Path) -> Result<(PathBuf, String)> {
    let name = target
        .file_name()
        .filter(|_| !target.ends_with(".") && !target.ends_with(".."))
        .and_then(|n| n.to_str());
    match (target.parent(), name) {
        (Some(parent), Some(name)) => Ok((parent.to_path_buf(), name.to_string())),
        _ => bail!(
            "{} names no folder that echofield can replace (give a path such as out/run)",
            target.display()
        ),
    }
}

/// `create_dir_all(dir)` for the output `output`, returning the folders it
/// created, outermost first. The error names the path at fault: an
/// ancestor that is a file, or `dir`.
pub(crate) fn create_parents(dir: &Path, output: &Path) -> Result<Vec<PathBuf>> {
    let missing: Vec<PathBuf> = dir
        .ancestors()
        .take_while(|a| std::fs::symlink_metadata(a).is_err())
        .map(Path::to_path_buf)
        .collect();
    if let Some(file) = dir
        .ancestors()
        .find(|a| std::fs::symlink_metadata(a).is_ok())
        .filter(|a| !a.is_dir())
    {
        bail!(
            "cannot create the folder {} for the output {}: {} is a file, not a folder",
            dir.display(),
            output.display(),
            file.display()
        );
    }
    std::fs::create_dir_all(dir).with_context(|| {
        format!(
            "cannot create the folder {} for the output {}",
            dir.display(),
            output.display()
        )
    })?;
    Ok(missing.into_iter().rev().collect())
}

/// Whether `target` may be replaced: absent, an empty folder, or an earlier
/// echofield output (see the module doc). The error names the target and
/// what stands in the way.
pub fn check_replaceable(target: &Path, known: &[String]) -> Result<()> {
    let meta = match std::fs::symlink_metadata(target) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(()),
        Err(e) => return Err(e).with_context(|| format!("cannot read {}", target.display())),
        Ok(m) => m,
    };
    if !meta.is_dir() {
        bail!(
            "the output {} exists and is not a folder; choose another --output",
            target.display()
        );
    }
    let mut names: Vec<(String, bool)> = std::fs::read_dir(target)
        .with_context(|| format!("cannot read the output folder {}", target.display()))?
        .filter_map(|e| {
            let e = e.ok()?;
            let is_file = e.file_type().ok()?.is_file();
            Some((e.file_name().to_string_lossy().into_owned(), is_file))
        })
        .collect();
    if names.is_empty() {
        return writable(target);
    }
    names.sort();
    if !is_echofield_report(&target.join("report.json")) {
        bail!(
            "the output folder {} is not empty and holds no echofield report.json ({}): \
             echofield replaces only an empty folder or an earlier output of its own; \
             choose another --output or empty it",
            target.display(),
            listing(names.iter().map(|(n, _)| n.as_str()))
        );
    }
    let foreign: Vec<&str> = names
        .iter()
        .filter(|(n, is_file)| {
            !(stale::parse(n).is_some() || (*is_file && known.iter().any(|k| k == n)))
        })
        .map(|(n, _)| n.as_str())
        .collect();
    if !foreign.is_empty() {
        bail!(
            "the output folder {} holds files that echofield did not write ({}); \
             echofield replaces an output folder whole: move them elsewhere or choose another --output",
            target.display(),
            listing(foreign.iter().copied())
        );
    }
    writable(target)
}

/// The first few names, and how many more.
fn listing<'a>(names: impl ExactSizeIterator<Item = &'a str>) -> String {
    let total = names.len();
    let shown: Vec<&str> = names.take(NAMED_ENTRIES).collect();
    let mut list = shown.join(", ");
    if total > shown.len() {
        list += &format!(" and {} more", total - shown.len());
    }
    list
}

/// Whether `path` is a `report.json` written by echofield.
fn is_echofield_report(path: &Path) -> bool {
    std::fs::read(path)
        .ok()
        .and_then(|bytes| serde_json::from_slice::<serde_json::Value>(&bytes).ok())
        .is_some_and(|v| v.get("echofield_version").is_some_and(|s| s.is_string()))
}

/// Its entries can be deleted: `target` is writable (for the effective
/// user; root always is).
fn writable(target: &Path) -> Result<()> {
    #[cfg(unix)]
    if let Err(e) = rustix::fs::access(target, rustix::fs::Access::WRITE_OK) {
        bail!(
            "the output folder {} is not writable ({e}), so echofield cannot replace it",
            target.display()
        );
    }
    #[cfg(not(unix))]
    if std::fs::metadata(target).is_ok_and(|m| m.permissions().readonly()) {
        bail!(
            "the output folder {} is read-only, so echofield cannot replace it",
            target.display()
        );
    }
    Ok(())
}

/// A name `.echofield-{pid}-{tag}.{kind}` in `parent` that is free now.
fn fresh_name(parent: &Path, kind: &str) -> PathBuf {
    static COUNTER: AtomicU32 = AtomicU32::new(0);
    loop {
        let tag = COUNTER.fetch_add(1, Ordering::Relaxed);
        let path = parent.join(format!("{}{tag}.{kind}", stale::own_prefix()));
        if std::fs::symlink_metadata(&path).is_err() {
            return path;
        }
    }
}

/// Creates an empty folder `.echofield-{pid}-{tag}.{kind}` in `parent`.
fn create_fresh(parent: &Path, kind: &str) -> Result<PathBuf> {
    loop {
        let path = fresh_name(parent, kind);
        match std::fs::create_dir(&path) {
            Ok(()) => return Ok(path),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => {
                return Err(e)
                    .with_context(|| format!("cannot create a folder in {}", parent.display()));
            }
        }
    }
}

/// `{name}`, or `{name}-2`, `{name}-3`, ...: the first that does not exist.
fn free_sibling(parent: &Path, name: &str) -> PathBuf {
    (1..)
        .map(|k| match k {
            1 => parent.join(name),
            k => parent.join(format!("{name}-{k}")),
        })
        .find(|p| std::fs::symlink_metadata(p).is_err())
        .unwrap_or_else(|| parent.join(name))
}

/// Swaps `a` and `b` atomically where the system can (Linux,
/// `renameat2(RENAME_EXCHANGE)`); `Ok(false)` where it cannot.
fn exchange(a: &Path, b: &Path) -> Result<bool> {
    #[cfg(target_os = "linux")]
    {
        use rustix::fs::{CWD, RenameFlags, renameat_with};
        match renameat_with(CWD, a, CWD, b, RenameFlags::EXCHANGE) {
            Ok(()) => Ok(true),
            // Not supported by this file system or kernel.
            Err(rustix::io::Errno::INVAL | rustix::io::Errno::NOSYS) => Ok(false),
            Err(e) => Err(std::io::Error::from(e)).with_context(|| {
                format!(
                    "cannot swap the new outputs {} with {}",
                    a.display(),
                    b.display()
                )
            }),
        }
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = (a, b);
        Ok(false)
    }
}

/// Flushes a folder's entries to disk (best effort: a failure only weakens
/// durability after a power loss, not the order of the renames).
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    if let Ok(f) = std::fs::File::open(dir) {
        let _ = f.sync_all();
    }
    #[cfg(not(unix))]
    let _ = dir;
}

#[cfg(test)]
mod tests {
    use super::*;

    const KNOWN: &[&str] = &["report.json", "a.txt"];
    const REPORT: &[u8] = br#"{"echofield_version": "0.1.0"}"#;

    fn write_output(folder: &OutputFolder, text: &str) {
        std::fs::write(folder.path().join("a.txt"), text).unwrap();
        std::fs::write(folder.path().join("report.json"), REPORT).unwrap();
    }

    fn entries(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    #[test]
    fn a_new_output_replaces_the_previous_whole_and_leaves_nothing_beside_it() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("deep/er/out");
        let first = OutputFolder::prepare(&target, KNOWN).unwrap();
        assert!(!target.exists(), "nothing appears before the commit");
        write_output(&first, "first");
        first.commit().unwrap();
        assert_eq!(
            std::fs::read_to_string(target.join("a.txt")).unwrap(),
            "first"
        );
        let second = OutputFolder::prepare(&target, KNOWN).unwrap();
        std::fs::write(second.path().join("report.json"), REPORT).unwrap();
        second.commit().unwrap();
        // `a.txt` of the first output is gone: no mix.
        assert_eq!(entries(&target), ["report.json"]);
        assert_eq!(entries(target.parent().unwrap()), ["out"]);
    }

    #[test]
    fn temporary_files_an_earlier_version_left_in_an_output_go_with_it() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out");
        std::fs::create_dir(&target).unwrap();
        std::fs::write(target.join("report.json"), REPORT).unwrap();
        std::fs::write(target.join("a.txt"), "old").unwrap();
        std::fs::write(target.join(".echofield-Xy12Ab.tmp"), "half").unwrap();
        let folder = OutputFolder::prepare(&target, KNOWN).unwrap();
        write_output(&folder, "new");
        folder.commit().unwrap();
        assert_eq!(entries(&target), ["a.txt", "report.json"]);
    }

    #[test]
    fn the_swap_by_two_renames_gives_the_same_result() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out");
        let first = OutputFolder::prepare(&target, KNOWN).unwrap();
        write_output(&first, "first");
        first.commit_with(false).unwrap();
        let second = OutputFolder::prepare(&target, KNOWN).unwrap();
        write_output(&second, "second");
        second.commit_with(false).unwrap();
        assert_eq!(
            std::fs::read_to_string(target.join("a.txt")).unwrap(),
            "second"
        );
        assert_eq!(entries(dir.path()), ["out"]);
    }

    #[test]
    fn an_output_dropped_before_its_commit_leaves_the_previous_one_and_no_trace() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out");
        let first = OutputFolder::prepare(&target, KNOWN).unwrap();
        write_output(&first, "first");
        first.commit().unwrap();
        let second = OutputFolder::prepare(&target, KNOWN).unwrap();
        write_output(&second, "second");
        drop(second);
        assert_eq!(
            std::fs::read_to_string(target.join("a.txt")).unwrap(),
            "first"
        );
        assert_eq!(entries(dir.path()), ["out"]);
        // Parents that prepare created go as well, also when it fails
        // after creating them (a name too long for the fresh folder).
        let nested = dir.path().join("x/y/out");
        drop(OutputFolder::prepare(&nested, KNOWN).unwrap());
        assert_eq!(entries(dir.path()), ["out"]);
        let long = dir.path().join("x/y").join("z".repeat(250));
        assert!(OutputFolder::prepare(&long, KNOWN).is_err());
        assert_eq!(entries(dir.path()), ["out"]);
    }

    #[test]
    fn folders_echofield_did_not_write_are_refused_with_their_content_named() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out");
        std::fs::create_dir(&target).unwrap();
        std::fs::write(target.join("notes.txt"), "mine").unwrap();
        let err = format!("{:#}", OutputFolder::prepare(&target, KNOWN).unwrap_err());
        assert!(
            err.contains(&target.display().to_string())
                && err.contains("notes.txt")
                && err.contains("no echofield report.json"),
            "{err}"
        );
        // An echofield output with a file of the user's added.
        std::fs::write(target.join("report.json"), REPORT).unwrap();
        let err = format!("{:#}", OutputFolder::prepare(&target, KNOWN).unwrap_err());
        assert!(err.contains("did not write (notes.txt)"), "{err}");
        // A report.json of something else.
        std::fs::remove_file(target.join("notes.txt")).unwrap();
        std::fs::write(target.join("report.json"), "{}").unwrap();
        assert!(OutputFolder::prepare(&target, KNOWN).is_err());
        assert_eq!(
            std::fs::read_to_string(target.join("report.json")).unwrap(),
            "{}"
        );
        // A file where the folder should be.
        let file = dir.path().join("file");
        std::fs::write(&file, "x").unwrap();
        let err = format!("{:#}", OutputFolder::prepare(&file, KNOWN).unwrap_err());
        assert!(err.contains("exists and is not a folder"), "{err}");
        let err = format!(
            "{:#}",
            OutputFolder::prepare(&file.join("out"), KNOWN).unwrap_err()
        );
        assert!(err.contains(&file.display().to_string()), "{err}");
        assert_eq!(entries(dir.path()), ["file", "out"]);
    }

    #[test]
    fn a_target_that_changed_during_the_run_keeps_both() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out");
        let folder = OutputFolder::prepare(&target, KNOWN).unwrap();
        write_output(&folder, "new");
        std::fs::create_dir(&target).unwrap();
        std::fs::write(target.join("notes.txt"), "mine").unwrap();
        let err = format!("{:#}", folder.commit().unwrap_err());
        assert!(err.contains("out.new"), "{err}");
        assert_eq!(
            std::fs::read_to_string(target.join("notes.txt")).unwrap(),
            "mine"
        );
        assert_eq!(
            std::fs::read_to_string(dir.path().join("out.new/a.txt")).unwrap(),
            "new"
        );
    }

    #[test]
    fn a_link_to_a_folder_stays_a_link() {
        let dir = tempfile::tempdir().unwrap();
        let real = dir.path().join("real");
        std::fs::create_dir(&real).unwrap();
        #[cfg(unix)]
        {
            let link = dir.path().join("link");
            std::os::unix::fs::symlink(&real, &link).unwrap();
            let folder = OutputFolder::prepare(&link, KNOWN).unwrap();
            write_output(&folder, "via link");
            folder.commit().unwrap();
            assert!(
                std::fs::symlink_metadata(&link)
                    .unwrap()
                    .file_type()
                    .is_symlink()
            );
            assert_eq!(
                std::fs::read_to_string(real.join("a.txt")).unwrap(),
                "via link"
            );
        }
    }

    #[test]
    fn paths_that_name_no_folder_are_refused() {
        for path in [".", "..", "/"] {
            let err = OutputFolder::prepare(Path::new(path), KNOWN);
            assert!(err.is_err(), "{path}");
        }
    }
}
