//! A job's directory: where its process writes the files it produces (the exported
//! stock) until the worker has stored them. Made per job in the temporary directory
//! (`millsim-job-XXXXXX`), removed once the job's outcome is committed or dropped.
//!
//! A worker process that was killed cannot remove its own, so the next worker process
//! removes those whose owner is gone. The owner is known by a lock, not a PID: the worker
//! holds an exclusive `flock` on the directory's `owner` file while the directory lives,
//! and the kernel drops it when the process dies, however it dies. A PID would name
//! another process once reused, and another container's processes when worker
//! containers share one /tmp (each with its own PID namespace), whose live directories
//! would then be removed under them.

use std::fs::File;
use std::path::Path;

use rustix::fs::{flock, FlockOperation};

const PREFIX: &str = "millsim-job-";
const OWNER: &str = "owner";
/// A directory younger than this is left alone, even unlocked.
const NEW: std::time::Duration = std::time::Duration::from_secs(60);

/// A job's directory, owned by this process until dropped (then removed).
pub struct JobDir {
    dir: tempfile::TempDir,
    /// Holds the lock; dropped after the directory is removed (fields drop in order).
    _owner: File,
}

impl JobDir {
    pub fn path(&self) -> &Path {
        self.dir.path()
    }
}

/// A new directory for a job of this process.
pub fn create() -> std::io::Result<JobDir> {
    let dir = tempfile::Builder::new().prefix(PREFIX).tempdir()?;
    let owner = File::create(dir.path().join(OWNER))?;
    flock(&owner, FlockOperation::NonBlockingLockExclusive)?;
    Ok(JobDir { dir, _owner: owner })
}

/// Removes the job directories in `dir` whose owner is gone: their `owner` file's lock
/// can be taken. A directory still owned, or without an owner file yet, or made in the
/// last minute (its maker may not have locked it yet), is left alone. Returns how many
/// were removed.
pub fn remove_stale(dir: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mut removed = 0;
    // Bounded by what the directory lists; each entry is looked at once.
    for entry in entries.flatten() {
        let owned_by_a_job = entry
            .file_name()
            .to_str()
            .is_some_and(|n| n.starts_with(PREFIX));
        if !owned_by_a_job {
            continue;
        }
        let Ok(owner) = File::open(entry.path().join(OWNER)) else {
            continue;
        };
        // A directory made this minute may be between its owner file and its lock.
        let recent = owner
            .metadata()
            .and_then(|m| m.modified())
            .map(|t| t.elapsed().map_or(true, |age| age < NEW))
            .unwrap_or(true);
        if recent {
            continue;
        }
        if flock(&owner, FlockOperation::NonBlockingLockExclusive).is_err() {
            continue; // its worker holds it
        }
        match std::fs::remove_dir_all(entry.path()) {
            Ok(()) => removed += 1,
            Err(e) => {
                tracing::warn!(dir = %entry.path().display(), error = %e, "could not remove a dead worker's job directory")
            }
        }
    }
    removed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directories_whose_owner_is_gone_go_and_owned_ones_stay() {
        let tmp = tempfile::tempdir().unwrap();
        let make = |name: &str| {
            let d = tmp.path().join(name);
            std::fs::create_dir(&d).unwrap();
            std::fs::write(d.join("stock.stl"), b"solid").unwrap();
            d
        };
        // Left by a dead worker: an owner file nobody locks.
        let old = |f: &File| {
            let then = std::time::SystemTime::now() - 2 * NEW;
            f.set_times(std::fs::FileTimes::new().set_modified(then))
                .unwrap();
        };
        let dead = make(&format!("{PREFIX}abc123"));
        old(&File::create(dead.join(OWNER)).unwrap());
        // Unlocked but just made: its maker may be about to lock it.
        let just_made = make(&format!("{PREFIX}jkl012"));
        File::create(just_made.join(OWNER)).unwrap();
        // Owned: locked by an open file description, as a live worker (in this or any
        // other process, container or PID namespace) holds it.
        let alive = make(&format!("{PREFIX}def456"));
        let held = File::create(alive.join(OWNER)).unwrap();
        old(&held);
        flock(&held, FlockOperation::NonBlockingLockExclusive).unwrap();
        // Being made (no owner file yet), and not a job's.
        let new = make(&format!("{PREFIX}ghi789"));
        let other = make("millsim-other");

        assert_eq!(remove_stale(tmp.path()), 1);
        assert!(!dead.exists());
        assert!(alive.exists() && new.exists() && other.exists() && just_made.exists());
        drop(held); // the owner dies
        assert_eq!(remove_stale(tmp.path()), 1);
        assert!(!alive.exists());
    }

    #[test]
    fn a_job_directory_is_owned_while_it_lives_and_removed_after() {
        let tmp_root = std::env::temp_dir();
        let d = create().unwrap();
        let path = d.path().to_path_buf();
        let other = File::open(path.join(OWNER)).unwrap();
        assert!(
            flock(&other, FlockOperation::NonBlockingLockExclusive).is_err(),
            "another open of the owner file cannot take the lock"
        );
        assert!(path.starts_with(&tmp_root));
        drop(d);
        assert!(!path.exists());
    }
}
