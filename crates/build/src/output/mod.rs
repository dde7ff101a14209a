//! Safe output folders for `convert`: a staging folder beside the target, a per-run lock, checks
//! that only empty folders or earlier splat2tiles outputs are replaced, and interrupt handling.
//!
//! The life of a run: [`Staging::prepare`] locks the run, cleans dead runs' leftovers (refusing
//! when another live run writes the same target), checks the target, and creates the staging
//! folder; the pipeline writes into [`Staging::path`], polling [`interrupted`] so that worker
//! threads stop before anything is removed; [`Staging::commit`] writes the marker and renames the
//! folder into place. Dropping an uncommitted `Staging` removes its folder (after the workers
//! stopped, since the pipeline only returns then).

pub mod guard;
pub mod leftovers;
pub mod marker;

use leftovers::Kind;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Why an output folder cannot be written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum OutputError {
    /// The target is not something we may replace.
    #[error("{path}: {why}")]
    Refused {
        /// The user's output path.
        path: PathBuf,
        /// Why not, and what the folder holds.
        why: String,
    },
    /// Another live run writes the same target.
    #[error("{path}: {why}")]
    Busy {
        /// The user's output path.
        path: PathBuf,
        /// Which run.
        why: String,
    },
    /// A file operation failed.
    #[error("{path}: {what}: {source}")]
    Io {
        /// The user's output path (or the file named in `what`).
        path: PathBuf,
        /// What was being done.
        what: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// Ctrl-C or SIGTERM arrived; nothing was written.
    #[error("interrupted; no output written")]
    Interrupted,
}

impl OutputError {
    /// An I/O error about `path`.
    pub fn io(path: &Path, what: &str, source: std::io::Error) -> Self {
        OutputError::Io {
            path: path.to_path_buf(),
            what: what.to_string(),
            source,
        }
    }
}

/// Set by the interrupt handler while a conversion runs; the pipeline polls it.
static INTERRUPTED: AtomicBool = AtomicBool::new(false);
/// Staging folders of runs in progress in this process (the handler exits at once when empty).
static ACTIVE: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
/// Distinguishes runs of one process.
static SEQ: AtomicU64 = AtomicU64::new(0);

/// Whether an interrupt asked the running conversion to stop.
pub fn interrupted() -> bool {
    INTERRUPTED.load(Ordering::SeqCst)
}

/// What an interrupt (Ctrl-C / SIGTERM) means now.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interrupt {
    /// No conversion is writing: exit at once.
    Idle,
    /// A conversion is writing: it stops (the workers finish their tile, the staging folder is
    /// removed, then the command exits with 130).
    Stopping,
    /// The second interrupt during a conversion: exit at once (the next run into that output
    /// removes the staging folder left).
    Again,
}

/// Records an interrupt and says what it means. The binary's signal handler calls this and
/// prints and exits accordingly; the pipeline polls [`interrupted`].
pub fn interrupt() -> Interrupt {
    let busy = ACTIVE.lock().map(|a| !a.is_empty()).unwrap_or(false);
    if !busy {
        Interrupt::Idle
    } else if INTERRUPTED.swap(true, Ordering::SeqCst) {
        Interrupt::Again
    } else {
        Interrupt::Stopping
    }
}

/// The staging folder of one run into `target`, with the run's lock.
#[derive(Debug)]
pub struct Staging {
    path: PathBuf,
    target: PathBuf,
    parent: PathBuf,
    name: String,
    id: String,
    lock: Option<File>,
    committed: bool,
    /// Notes for the user (leftovers cleaned, deletions that failed).
    pub notes: Vec<String>,
}

impl Staging {
    /// Locks the run, cleans dead runs' leftovers, checks `target` and creates the staging
    /// folder beside it. Errors name `target`, never the internal names.
    pub fn prepare(target: &Path) -> Result<Staging, OutputError> {
        let name = target
            .file_name()
            .ok_or_else(|| OutputError::Refused {
                path: target.to_path_buf(),
                why: "the output must name a folder".into(),
            })?
            .to_string_lossy()
            .into_owned();
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => PathBuf::from("."),
        };
        std::fs::create_dir_all(&parent)
            .map_err(|e| OutputError::io(target, "creating the folder it goes into", e))?;
        let id = format!(
            "{}-{}",
            std::process::id(),
            SEQ.fetch_add(1, Ordering::SeqCst)
        );
        let shown_parent = parent.display().to_string();
        let cannot_write = |e| {
            OutputError::io(
                target,
                &format!(
                    "cannot write the output here (a hidden staging folder in {shown_parent})"
                ),
                e,
            )
        };
        let lock = leftovers::lock(&parent, &name, &id).map_err(cannot_write)?;
        let path = leftovers::sibling(&parent, &name, Kind::Tmp, &id);
        let mut staging = Staging {
            path,
            target: target.to_path_buf(),
            parent,
            name,
            id,
            lock: Some(lock),
            committed: false,
            notes: Vec::new(),
        };
        staging.notes = leftovers::clean(target, &staging.parent, &staging.name, &staging.id)?;
        guard::check_target(target)?;
        if let Ok(mut a) = ACTIVE.lock() {
            a.push(staging.path.clone());
        }
        std::fs::create_dir(&staging.path).map_err(cannot_write)?;
        Ok(staging)
    }

    /// The folder to write into.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes the marker and moves the finished folder into place, replacing an earlier result
    /// only now. A failure to delete the earlier result is a note, never silent.
    pub fn commit(mut self) -> Result<Vec<String>, OutputError> {
        let target = self.target.clone();
        if interrupted() {
            return Err(OutputError::Interrupted);
        }
        marker::write(&self.path)
            .map_err(|e| OutputError::io(&target, "writing its marker file", e))?;
        // The interrupt handler waits on this lock, so it never runs between the two renames.
        let mut active = ACTIVE.lock().unwrap_or_else(|p| p.into_inner());
        if interrupted() {
            return Err(OutputError::Interrupted);
        }
        // The user may have put files into the target while we worked.
        let had_old = guard::check_target(&target)?;
        let old = leftovers::sibling(&self.parent, &self.name, Kind::Old, &self.id);
        if had_old {
            std::fs::rename(&target, &old)
                .map_err(|e| OutputError::io(&target, "moving the earlier result aside", e))?;
        }
        if let Err(e) = std::fs::rename(&self.path, &target) {
            if had_old {
                let _ = std::fs::rename(&old, &target);
            }
            return Err(OutputError::io(
                &target,
                "moving the new result into place",
                e,
            ));
        }
        self.committed = true;
        active.retain(|d| d != &self.path);
        drop(active);
        let mut notes = std::mem::take(&mut self.notes);
        if had_old {
            notes.push(format!(
                "replaced the earlier splat2tiles output in {}",
                target.display()
            ));
        }
        if had_old && let Err(e) = std::fs::remove_dir_all(&old) {
            notes.push(format!(
                "warning: the new output is in place, but the earlier result could not be deleted \
                 and remains in {}: {e}; delete it by hand",
                old.display()
            ));
        }
        Ok(notes)
    }
}

/// Refuses an output folder `target` that is one of `inputs`, lies inside one, or holds one:
/// replacing it would destroy what the run reads (a merge into one of its parts, a part into a
/// samples folder it reads).
pub fn check_not_over_inputs(target: &Path, inputs: &[&Path]) -> Result<(), OutputError> {
    // The target as it will be: resolved through its parent when it does not exist yet.
    let resolve = |p: &Path| -> Option<PathBuf> {
        std::fs::canonicalize(p).ok().or_else(|| {
            let parent = match p.parent() {
                Some(d) if !d.as_os_str().is_empty() => d,
                _ => Path::new("."),
            };
            Some(std::fs::canonicalize(parent).ok()?.join(p.file_name()?))
        })
    };
    let Some(out) = resolve(target) else {
        return Ok(());
    };
    for input in inputs {
        let Some(inp) = resolve(input) else { continue };
        if out == inp || inp.starts_with(&out) || out.starts_with(&inp) {
            return Err(OutputError::Refused {
                path: target.to_path_buf(),
                why: format!(
                    "the output would replace {}, which this run reads; choose another folder",
                    input.display()
                ),
            });
        }
    }
    Ok(())
}

impl Drop for Staging {
    fn drop(&mut self) {
        if !self.committed
            && let Err(e) = std::fs::remove_dir_all(&self.path)
            && e.kind() != std::io::ErrorKind::NotFound
        {
            log::warn!(
                "could not remove the unfinished output {}: {e}",
                self.path.display()
            );
        }
        if let Ok(mut a) = ACTIVE.lock() {
            a.retain(|d| d != &self.path);
        }
        // The lock file goes last: while it exists and is locked, other runs keep off.
        let lock = leftovers::sibling(&self.parent, &self.name, Kind::Lock, &self.id);
        let _ = std::fs::remove_file(lock);
        self.lock.take();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn staging_is_removed_on_drop_and_commit_writes_the_marker() {
        let tmp = tempfile::tempdir().unwrap();
        let target = tmp.path().join("out");
        let st = Staging::prepare(&target).unwrap();
        let staged = st.path().to_path_buf();
        assert!(staged.is_dir());
        drop(st);
        assert!(!staged.exists());
        assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 0);
        let st = Staging::prepare(&target).unwrap();
        std::fs::write(st.path().join("tileset.json"), "{}").unwrap();
        assert!(st.commit().unwrap().is_empty());
        assert_eq!(
            marker::read(&target).unwrap().entries,
            ["tileset.json".to_string()].into()
        );
        // Nothing hidden is left beside it; a second run may replace it.
        assert_eq!(std::fs::read_dir(tmp.path()).unwrap().count(), 1);
        assert!(guard::check_target(&target).unwrap());
        // Replacing it says so.
        let st = Staging::prepare(&target).unwrap();
        std::fs::write(st.path().join("tileset.json"), "{\"v\":2}").unwrap();
        let notes = st.commit().unwrap();
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(notes[0].starts_with("replaced the earlier splat2tiles output in "));
        assert_eq!(
            std::fs::read_to_string(target.join("tileset.json")).unwrap(),
            "{\"v\":2}"
        );
    }

    #[test]
    fn two_stagings_for_one_target_in_one_process_refuse() {
        let tmp = tempfile::tempdir().unwrap();
        let target = tmp.path().join("out");
        let first = Staging::prepare(&target).unwrap();
        let e = Staging::prepare(&target).unwrap_err();
        assert!(matches!(e, OutputError::Busy { .. }), "{e}");
        assert!(
            first.path().is_dir(),
            "the first run's staging is untouched"
        );
    }
}
