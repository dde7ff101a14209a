//! Runs into one output folder and what they leave beside it: a held lock file per run, its
//! staging folder and the earlier result moved aside at commit. Dead runs' leftovers are cleaned.
//!
//! Names beside the target `NAME` (run id `PID-SEQ`): `.NAME.s2t-lock-ID` (a file, locked for
//! the run's whole life), `.NAME.s2t-tmp-ID` (staging), `.NAME.s2t-old-ID` (the earlier result
//! during the commit). A run is alive while its lock file is locked; the lock dies with the
//! process (also on an out-of-memory kill), so the next run can tell leftovers from live work.

use super::OutputError;
use std::collections::BTreeSet;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

/// A lock file younger than this is treated as live even when unlocked (its owner may be
/// between creating and locking it).
const FRESH: Duration = Duration::from_secs(10);

/// The three kinds of sibling a run creates.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// The lock file.
    Lock,
    /// The staging folder.
    Tmp,
    /// The earlier result, moved aside.
    Old,
}

impl Kind {
    fn tag(self) -> &'static str {
        match self {
            Kind::Lock => "lock",
            Kind::Tmp => "tmp",
            Kind::Old => "old",
        }
    }
}

/// Path of the `kind` sibling of run `id` for the target `name` in `parent`.
pub fn sibling(parent: &Path, name: &str, kind: Kind, id: &str) -> PathBuf {
    parent.join(format!(".{name}.s2t-{}-{id}", kind.tag()))
}

/// Opens (creating it) and locks run `id`'s lock file; the lock lasts as long as the `File`.
pub fn lock(parent: &Path, name: &str, id: &str) -> std::io::Result<File> {
    let path = sibling(parent, name, Kind::Lock, id);
    let f = File::options()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(&path)?;
    f.try_lock().map_err(|e| match e {
        std::fs::TryLockError::Error(e) => e,
        std::fs::TryLockError::WouldBlock => {
            std::io::Error::other("the new lock file is already locked")
        }
    })?;
    Ok(f)
}

/// Whether run `id` (not ours) is still alive, judged by its lock file.
fn alive(parent: &Path, name: &str, id: &str) -> bool {
    let path = sibling(parent, name, Kind::Lock, id);
    let Ok(f) = File::options().read(true).write(true).open(&path) else {
        // No lock file: the run is gone (its lock is created first and removed last).
        return false;
    };
    match f.try_lock() {
        Err(std::fs::TryLockError::WouldBlock) => true,
        Err(std::fs::TryLockError::Error(_)) => true,
        Ok(()) => {
            let _ = f.unlock();
            let age = f
                .metadata()
                .and_then(|m| m.modified())
                .ok()
                .and_then(|t| SystemTime::now().duration_since(t).ok());
            age.is_none_or(|a| a < FRESH) && !process_gone(id)
        }
    }
}

/// Whether the process of run `id` (`PID-SEQ`) is known to be gone (Linux `/proc`); `false`
/// when this cannot be told.
fn process_gone(id: &str) -> bool {
    let Some(pid) = id.split('-').next().filter(|p| p.parse::<u32>().is_ok()) else {
        return false;
    };
    Path::new("/proc/self").exists() && !Path::new("/proc").join(pid).exists()
}

/// Run ids with any sibling of `name` in `parent`, except `ours`.
fn other_runs(parent: &Path, name: &str, ours: &str) -> BTreeSet<String> {
    let prefix = format!(".{name}.s2t-");
    let mut ids = BTreeSet::new();
    let Ok(entries) = std::fs::read_dir(parent) else {
        return ids;
    };
    for e in entries.flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        let Some(rest) = file.strip_prefix(&prefix) else {
            continue;
        };
        for kind in [Kind::Lock, Kind::Tmp, Kind::Old] {
            if let Some(id) = rest.strip_prefix(&format!("{}-", kind.tag()))
                && id != ours
                && !id.is_empty()
            {
                ids.insert(id.to_string());
            }
        }
    }
    ids
}

/// Refuses when another live run writes `target`; removes dead runs' staging folders and lock
/// files, and puts a dead run's moved-aside earlier result back when the target is missing.
/// Returns notes for the user (what was cleaned, what could not be).
pub fn clean(
    target: &Path,
    parent: &Path,
    name: &str,
    ours: &str,
) -> Result<Vec<String>, OutputError> {
    let mut notes = Vec::new();
    let runs = other_runs(parent, name, ours);
    if let Some(id) = runs.iter().find(|id| alive(parent, name, id)) {
        let pid = id.split('-').next().unwrap_or(id);
        return Err(OutputError::Busy {
            path: target.to_path_buf(),
            why: format!(
                "another splat2tiles run (process {pid}) is writing this output right now; \
                 wait for it to finish or choose another -o"
            ),
        });
    }
    for id in &runs {
        let old = sibling(parent, name, Kind::Old, id);
        if old.exists() {
            if !target.exists() {
                match std::fs::rename(&old, target) {
                    Ok(()) => notes.push(format!(
                        "{}: restored the earlier result that an interrupted run had moved aside",
                        target.display()
                    )),
                    Err(e) => {
                        return Err(OutputError::io(
                            target,
                            "restoring the earlier result an interrupted run moved aside (it is in the hidden folder beside it)",
                            e,
                        ));
                    }
                }
            } else if let Err(e) = std::fs::remove_dir_all(&old) {
                notes.push(format!(
                    "warning: could not delete {} (an earlier result left by an interrupted run): {e}",
                    old.display()
                ));
            }
        }
        let tmp = sibling(parent, name, Kind::Tmp, id);
        if tmp.exists() {
            match std::fs::remove_dir_all(&tmp) {
                Ok(()) => notes.push(format!(
                    "{}: removed the unfinished output of an interrupted run ({})",
                    target.display(),
                    tmp.display()
                )),
                Err(e) => notes.push(format!(
                    "warning: could not delete {} (unfinished output of an interrupted run): {e}",
                    tmp.display()
                )),
            }
        }
        let lock = sibling(parent, name, Kind::Lock, id);
        if let Err(e) = std::fs::remove_file(&lock)
            && e.kind() != std::io::ErrorKind::NotFound
        {
            notes.push(format!("warning: could not delete {}: {e}", lock.display()));
        }
    }
    Ok(notes)
}
