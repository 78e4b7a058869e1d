//! Names of the temporary files and folders echofield writes beside its
//! outputs, and the recognition and removal of those that a killed run
//! left behind.
//!
//! Every temporary entry is named `.echofield-{pid}-{tag}.{rest}`: the id
//! of the process that owns it, a tag unique within that process, and what
//! it is (`tmp` and `mcap.tmp` for a file being written, `new-NAME` for
//! the fresh folder that becomes the output folder `NAME`, `old-NAME` for
//! a previous output folder moved aside during the swap, `del-NAME` for
//! one being deleted). An entry is *stale* when its process is gone (on
//! Unix: `kill(pid, 0)` fails with `ESRCH`); a live process's entries are
//! never touched, even when the pid was reused by an unrelated program
//! (they are then left for a later run). Entries of the form
//! `.echofield-{random}.tmp` (earlier versions, no pid) are stale when
//! older than [`UNOWNED_MAX_AGE`].
//!
//! The pid test assumes that the runs sharing a folder run on one machine
//! (and in one pid namespace); on a folder shared between machines an
//! entry of a live run elsewhere would look stale.

use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

/// The prefix of every temporary entry.
pub const PREFIX: &str = ".echofield-";

/// Age from which a temporary entry without a pid counts as stale.
pub const UNOWNED_MAX_AGE: Duration = Duration::from_secs(24 * 3600);

/// `.echofield-{pid}-`: the prefix of this process's temporary entries;
/// a tag without `.` and the entry's kind follow.
pub fn own_prefix() -> String {
    format!("{PREFIX}{}-", std::process::id())
}

/// A temporary entry's name, parsed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TempName<'a> {
    /// The owning process; `None` for the names of earlier versions.
    pub pid: Option<u32>,
    /// What follows the tag: `tmp`, `mcap.tmp`, `new-NAME`, ...
    pub kind: &'a str,
}

/// Parses `name` as a temporary entry of echofield; `None` when it is not
/// one.
pub fn parse(name: &str) -> Option<TempName<'_>> {
    let rest = name.strip_prefix(PREFIX)?;
    if let Some((pid, after)) = rest.split_once('-')
        && !pid.is_empty()
        && pid.bytes().all(|b| b.is_ascii_digit())
        && let Ok(pid) = pid.parse::<u32>()
    {
        let (_tag, kind) = after.split_once('.')?;
        return Some(TempName {
            pid: Some(pid),
            kind,
        });
    }
    // Earlier versions: `.echofield-XXXXXX.tmp`, `.echofield-XXXXXX.mcap.tmp`.
    let (tag, kind) = rest.split_once('.')?;
    (tag.bytes().all(|b| b.is_ascii_alphanumeric()) && kind.ends_with("tmp"))
        .then_some(TempName { pid: None, kind })
}

/// Whether process `pid` is running (or might be: when it cannot be told,
/// `true`).
fn process_alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    #[cfg(unix)]
    {
        let Some(pid) = i32::try_from(pid)
            .ok()
            .and_then(rustix::process::Pid::from_raw)
        else {
            return false;
        };
        // EPERM: it exists but belongs to another user.
        !matches!(
            rustix::process::test_kill_process(pid),
            Err(rustix::io::Errno::SRCH)
        )
    }
    #[cfg(not(unix))]
    {
        true
    }
}

fn older_than(path: &Path, age: Duration) -> bool {
    std::fs::symlink_metadata(path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| SystemTime::now().duration_since(t).ok())
        .is_some_and(|a| a > age)
}

/// Whether the entry `dir/name` is a temporary entry that no running
/// echofield owns.
pub fn is_stale(dir: &Path, name: &str) -> bool {
    match parse(name) {
        None => false,
        Some(TempName { pid: Some(pid), .. }) if cfg!(unix) => !process_alive(pid),
        Some(_) => older_than(&dir.join(name), UNOWNED_MAX_AGE),
    }
}

/// What [`clean`] did with one stale entry.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Cleaned {
    Removed(PathBuf),
    /// A previous output folder that a run killed in the middle of its
    /// swap had moved aside, moved back to its place (the second path).
    Restored(PathBuf, PathBuf),
}

/// Removes the stale temporary entries of `dir` (see the module doc) and
/// moves back a previous output folder that a killed run left moved aside
/// when nothing took its place; logs a warning for each. Entries it cannot
/// read or remove are left (with a warning): they never stop a run.
pub fn clean(dir: &Path) -> Vec<Cleaned> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut names: Vec<String> = entries
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .filter(|name| is_stale(dir, name))
        .collect();
    names.sort();
    let mut done = Vec::new();
    for name in names {
        let path = dir.join(&name);
        let pid = parse(&name).and_then(|t| t.pid).map_or_else(
            || "an earlier version".to_string(),
            |p| format!("process {p}"),
        );
        let kind = parse(&name).map(|t| t.kind.to_string()).unwrap_or_default();
        if let Some(target) = kind.strip_prefix("old-") {
            let target = dir.join(target);
            if std::fs::symlink_metadata(&target).is_err() {
                match std::fs::rename(&path, &target) {
                    Ok(()) => {
                        tracing::warn!(
                            "restored the previous output {} that an interrupted echofield run ({pid}) had moved aside to {}",
                            target.display(),
                            path.display()
                        );
                        done.push(Cleaned::Restored(path, target));
                    }
                    Err(e) => tracing::warn!(
                        "cannot move {} back to {}: {e}",
                        path.display(),
                        target.display()
                    ),
                }
                continue;
            }
        }
        let removed = match std::fs::symlink_metadata(&path) {
            Ok(m) if m.is_dir() => std::fs::remove_dir_all(&path),
            Ok(_) => std::fs::remove_file(&path),
            Err(e) => Err(e),
        };
        match removed {
            Ok(()) => {
                tracing::warn!(
                    "removed {}, left by an interrupted echofield run ({pid})",
                    path.display()
                );
                done.push(Cleaned::Removed(path));
            }
            Err(e) => tracing::warn!(
                "cannot remove {}, left by an interrupted echofield run ({pid}): {e}",
                path.display()
            ),
        }
    }
    done
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_parsed_with_their_owner() {
        assert_eq!(
            parse(".echofield-123-aB9xYz.tmp"),
            Some(TempName {
                pid: Some(123),
                kind: "tmp"
            })
        );
        assert_eq!(
            parse(".echofield-77-3f.new-out.run"),
            Some(TempName {
                pid: Some(77),
                kind: "new-out.run"
            })
        );
        assert_eq!(
            parse(".echofield-Ab3dE9.mcap.tmp"),
            Some(TempName {
                pid: None,
                kind: "mcap.tmp"
            })
        );
        for other in [
            "report.json",
            ".echofield",
            ".echofield-",
            ".echofield-12-notag",
            ".echofield-notes.txt",
            "echofield-1-a.tmp",
        ] {
            assert_eq!(parse(other), None, "{other}");
        }
        assert!(own_prefix().starts_with(PREFIX));
        let own = format!("{}x.tmp", own_prefix());
        assert_eq!(parse(&own).unwrap().pid, Some(std::process::id()));
    }

    /// A pid that no process has: one above the kernel's maximum.
    #[cfg(target_os = "linux")]
    fn dead_pid() -> u32 {
        let max = std::fs::read_to_string("/proc/sys/kernel/pid_max")
            .ok()
            .and_then(|s| s.trim().parse::<u32>().ok())
            .unwrap_or(4_194_304);
        max + 1
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn entries_of_dead_processes_go_those_of_live_ones_and_other_files_stay() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let dead = dead_pid();
        let own = std::process::id();
        let stale_file = format!(".echofield-{dead}-abc.tmp");
        let stale_dir = format!(".echofield-{dead}-abc.new-out");
        let live_file = format!(".echofield-{own}-abc.tmp");
        std::fs::write(d.join(&stale_file), b"x").unwrap();
        std::fs::create_dir(d.join(&stale_dir)).unwrap();
        std::fs::write(d.join(&stale_dir).join("report.json"), b"{}").unwrap();
        std::fs::write(d.join(&live_file), b"x").unwrap();
        std::fs::write(d.join("notes.txt"), b"x").unwrap();
        // A fresh file of an earlier version: perhaps in use, kept.
        std::fs::write(d.join(".echofield-Ab3dE9.tmp"), b"x").unwrap();
        let cleaned = clean(d);
        assert_eq!(cleaned.len(), 2, "{cleaned:?}");
        assert!(!d.join(&stale_file).exists() && !d.join(&stale_dir).exists());
        for kept in [&live_file, "notes.txt", ".echofield-Ab3dE9.tmp"] {
            assert!(d.join(kept).exists(), "{kept}");
        }
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn a_previous_output_moved_aside_comes_back_when_nothing_took_its_place() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let dead = dead_pid();
        let aside = d.join(format!(".echofield-{dead}-a1.old-out"));
        std::fs::create_dir(&aside).unwrap();
        std::fs::write(aside.join("report.json"), b"{}").unwrap();
        let cleaned = clean(d);
        assert_eq!(
            cleaned,
            vec![Cleaned::Restored(aside.clone(), d.join("out"))]
        );
        assert!(d.join("out/report.json").is_file());
        // With the target in place, the one moved aside is removed.
        std::fs::create_dir(&aside).unwrap();
        assert_eq!(clean(d), vec![Cleaned::Removed(aside.clone())]);
        assert!(d.join("out/report.json").is_file() && !aside.exists());
    }
}
