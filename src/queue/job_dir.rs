//! A job's directory: where its process writes the files it produces (the exported
//! stock) until the worker has stored them. Made per job in the temporary directory,
//! named after the worker process (`millsim-job-PID-XXXXXX`), removed once the job's
//! outcome is committed or dropped. A worker process that was killed cannot remove its
//! own: the next worker process on the host removes those whose process is gone.

use std::path::Path;

const PREFIX: &str = "millsim-job-";

/// A new directory for a job of this process.
pub fn create() -> std::io::Result<tempfile::TempDir> {
    tempfile::Builder::new()
        .prefix(&format!("{PREFIX}{}-", std::process::id()))
        .tempdir()
}

/// Removes the job directories in `dir` left by worker processes that are gone (no
/// `/proc/PID`). A directory whose process still runs (or whose PID was reused) is
/// left alone. Returns how many were removed.
pub fn remove_stale(dir: &Path) -> usize {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    let mut removed = 0;
    // Bounded by what the directory lists; each entry is looked at once.
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name
            .to_str()
            .and_then(|n| n.strip_prefix(PREFIX))
            .and_then(|rest| rest.split_once('-'))
            .and_then(|(pid, _)| pid.parse::<u32>().ok())
        else {
            continue;
        };
        if Path::new(&format!("/proc/{pid}")).exists() {
            continue;
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
    fn directories_of_dead_processes_go_and_live_ones_stay() {
        let tmp = tempfile::tempdir().unwrap();
        // PID 0 is never a process's; this process is alive.
        let dead = tmp.path().join(format!("{PREFIX}0-abc123"));
        let alive = tmp
            .path()
            .join(format!("{PREFIX}{}-def456", std::process::id()));
        let other = tmp.path().join("millsim-job-notapid-x");
        for d in [&dead, &alive, &other] {
            std::fs::create_dir(d).unwrap();
            std::fs::write(d.join("stock.stl"), b"solid").unwrap();
        }
        assert_eq!(remove_stale(tmp.path()), 1);
        assert!(!dead.exists());
        assert!(alive.exists() && other.exists());
    }
}
