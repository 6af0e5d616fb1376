//! One process at a time per run directory.
//!
//! Two processes writing one record (a sweep started twice on one output directory, or a
//! `cdlab biaxial --resume` beside the sweep that runs the test) would interleave their
//! writes into a record neither could resume. A run takes an advisory lock on
//! [`LOCK_FILE`] in its directory for as long as it writes there; the operating system
//! drops the lock when the process ends, however it ends, so a killed run leaves no stale
//! lock behind. The empty file stays.

use std::fs::{File, OpenOptions, TryLockError};
use std::path::Path;

use crate::error::{Error, Result};

/// The lock file in a run directory.
pub const LOCK_FILE: &str = ".lock";

/// The claim of this process on a run directory, released when dropped.
#[derive(Debug)]
pub struct RunLock {
    _file: File,
}

impl RunLock {
    /// Creates `dir` if needed and claims it; an error naming the directory when another
    /// process holds it.
    pub fn acquire(dir: &Path) -> Result<RunLock> {
        crate::fsio::create_dir_all(dir)?;
        let path = dir.join(LOCK_FILE);
        let file = OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| Error::io(&path, e))?;
        match file.try_lock() {
            Ok(()) => Ok(RunLock { _file: file }),
            Err(TryLockError::WouldBlock) => Err(Error::InUse {
                dir: dir.to_path_buf(),
                lock: path.clone(),
            }),
            Err(TryLockError::Error(e)) => Err(Error::io(&path, e)),
        }
    }

    /// Whether another process holds `dir` now; creates nothing (a directory without a
    /// lock file is held by no one).
    pub fn held_elsewhere(dir: &Path) -> bool {
        let Ok(file) = File::open(dir.join(LOCK_FILE)) else {
            return false;
        };
        matches!(file.try_lock(), Err(TryLockError::WouldBlock))
    }
}
