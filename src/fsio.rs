//! Files written so that a crash, a full disk or a kill at any instant leaves either the
//! old complete file or the new complete one under the real name, never a torn one: the
//! bytes go to a temporary name in the same directory, are synced, and the temporary file
//! is renamed over the real one (a rename within a directory is atomic on POSIX file
//! systems), then the directory is synced so the rename itself survives a power cut.
//!
//! Every file cdlab writes goes through [`write_file`] (whole files: summaries, figures,
//! sample files) or, for a file that grows while a run goes (the record and its CSV copy),
//! through `crate::record::Recorder`, which stages its start with [`tmp_path`],
//! `FaultFile` and [`rename`]. The fault hooks of [`fault`] sit under both, so tests can
//! fail or kill the process at any of their writes. This module sits low in the module
//! map (it knows only [`crate::error`]) so that every module that writes can use it.
//!
//! A temporary file is always created new ([`create_tmp`]), never opened through whatever
//! already holds its name, and a rename never replaces anything but a regular file
//! ([`check_replaceable`]): an output path that is a link, a FIFO or a device is refused.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result, RunFault};

/// Suffix of the temporary names.
pub const TMP_SUFFIX: &str = ".tmp";

/// `path` with [`TMP_SUFFIX`] appended to its file name (same directory, so the rename
/// stays within one file system). Only for a writer that alone writes its directory (the
/// recorder holds the run's lock); [`write_file`] takes [`process_tmp_path`].
pub fn tmp_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(TMP_SUFFIX);
    path.with_file_name(name)
}

/// `path`'s temporary name unique to this process, `NAME.PID.tmp` in the same directory:
/// two processes writing the same file (two shards of a sweep writing a shared sample)
/// each write their own temporary file, and the last rename wins whole.
pub fn process_tmp_path(path: &Path) -> PathBuf {
    let mut name = path.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".{}{TMP_SUFFIX}", std::process::id()));
    path.with_file_name(name)
}

/// Writes `bytes` as the file `path`: to its temporary name ([`process_tmp_path`]),
/// synced, renamed into place, the directory synced. On error the real file is untouched
/// and the temporary one removed. A path that names no file (`/`, `..`) is refused, and so
/// is one that exists and is not a regular file ([`check_replaceable`]).
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<()> {
    if path.file_name().is_none() {
        return Err(Error::NotAFile {
            path: path.to_path_buf(),
        });
    }
    // Before any byte is written: the rename checks again, but a refusal there would
    // have written the temporary file for nothing.
    check_replaceable(path)?;
    // The next write of a file replaces the temporary files earlier writes were killed
    // with, whichever process made them.
    if let (Some(dir), Some(name)) = (path.parent(), path.file_name()) {
        let dir = if dir.as_os_str().is_empty() {
            Path::new(".")
        } else {
            dir
        };
        remove_stale_tmps(dir, Some(name));
    }
    let tmp = process_tmp_path(path);
    let written = (|| -> std::io::Result<()> {
        let mut f = FaultFile::create_tmp(&tmp)?;
        f.write_all(bytes)?;
        f.sync()
    })();
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::io(&tmp, e));
    }
    rename(&tmp, path)
}

/// Reads the whole file `path`, through the read hook of [`fault`] (a test can make the
/// read of a record fail at a chosen point).
pub fn read(path: &Path) -> std::io::Result<Vec<u8>> {
    fault::read_point()?;
    std::fs::read(path)
}

/// Renames `from` to `to` (replacing it) and syncs the directory of `to`. A `to` that
/// exists and is not a regular file is refused ([`check_replaceable`]).
///
/// Once the rename is done, the file is complete under its name for every later reader;
/// only its survival of a power cut waits on the directory's sync. A failed sync is
/// therefore a warning on stderr naming the directory, not an error: reporting the write
/// as failed left a finished test's `summary.json` in place while the command exited 1.
pub fn rename(from: &Path, to: &Path) -> Result<()> {
    check_replaceable(to)?;
    fault::point(false).map_err(|e| Error::io(to, e))?;
    fault::rename_point().map_err(|e| Error::io(to, e))?;
    std::fs::rename(from, to).map_err(|e| Error::io(to, e))?;
    if let Err(e) = sync_dir(to) {
        // A warning that cannot be shown (stderr closed or full) must not stop the work.
        let _ = writeln!(
            std::io::stderr(),
            "warning: {} was written, but syncing its directory failed ({e}): it may not survive \
             a power cut",
            to.display()
        );
    }
    Ok(())
}

/// Creates the directory `dir` and its parents, with an error that says what stands in the
/// way when `dir` exists as something else: a symbolic link that loops or leads nowhere, a
/// file. The system's own answer there, "File exists", named no cause.
pub fn create_dir_all(dir: &Path) -> Result<()> {
    let Err(e) = std::fs::create_dir_all(dir) else {
        return Ok(());
    };
    if e.kind() != std::io::ErrorKind::AlreadyExists {
        return Err(Error::io(dir, e));
    }
    Err(in_the_way(dir).unwrap_or_else(|| Error::io(dir, e)))
}

/// Refuses `dir` as a directory to work in when it exists as something else (a symbolic
/// link that loops or leads nowhere, a file, a FIFO), naming it and what it is, as
/// [`create_dir_all`] does: for a command that must know before it starts, or that only
/// says what it would do (a sweep's `--dry-run` said "would start" for each test of an
/// `out` that was a file). A `dir` that does not exist, or is a directory (through links),
/// passes.
pub fn check_directory(dir: &Path) -> Result<()> {
    match std::fs::metadata(dir) {
        Ok(m) if m.is_dir() => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound && std::fs::symlink_metadata(dir).is_err() => {
            Ok(())
        }
        _ => match in_the_way(dir) {
            Some(e) => Err(e),
            None => Ok(()),
        },
    }
}

/// What stands where the directory `dir` should be, as an error naming it; `None` when
/// nothing can be said (`dir` cannot be examined).
fn in_the_way(dir: &Path) -> Option<Error> {
    let what = match (std::fs::symlink_metadata(dir), std::fs::metadata(dir)) {
        (Ok(m), Err(target)) if m.file_type().is_symlink() => {
            #[cfg(unix)]
            let looped = target.raw_os_error() == Some(libc::ELOOP);
            #[cfg(not(unix))]
            let looped = false;
            if looped {
                "a symbolic link that loops (it leads back to itself)".to_string()
            } else {
                format!("a symbolic link to nothing usable ({target})")
            }
        }
        (Ok(m), Ok(_)) if m.file_type().is_symlink() => {
            "a symbolic link to something else than a directory".into()
        }
        (Ok(m), _) => file_kind(&m.file_type()).to_string(),
        (Err(_), _) => return None,
    };
    Some(Error::Run {
        path: dir.to_path_buf(),
        fault: RunFault::NotRegular,
        message: format!(
            "{} is {what}, not a directory: remove it or name another directory",
            dir.display()
        ),
        remedy: None,
    })
}

/// Refuses `path` as a file to replace when it exists and is not a regular file: a
/// symbolic link, a FIFO, a device node, a socket or a directory. A rename would replace
/// the link or the node itself, which is never what an output path means (as root it
/// replaced a device file of the system), and writing through it would reach whatever it
/// points to. The error names the path and what it is. A path that cannot be examined
/// (it does not exist, or its directory does not) passes: the write itself then says why
/// it fails.
pub fn check_replaceable(path: &Path) -> Result<()> {
    let Ok(meta) = std::fs::symlink_metadata(path) else {
        return Ok(());
    };
    let kind = meta.file_type();
    if kind.is_file() {
        return Ok(());
    }
    let what = file_kind(&kind);
    Err(Error::Run {
        path: path.to_path_buf(),
        fault: RunFault::NotRegular,
        message: format!(
            "{} is {what}, not a regular file: cdlab replaces only regular files; remove it or \
             write elsewhere",
            path.display()
        ),
        remedy: None,
    })
}

/// What a file type is, in words ("a FIFO (named pipe)", "a regular file"), for errors
/// that refuse a path for what it is.
pub fn file_kind(kind: &std::fs::FileType) -> &'static str {
    if kind.is_symlink() {
        return "a symbolic link";
    }
    if kind.is_dir() {
        return "a directory";
    }
    if kind.is_file() {
        return "a regular file";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if kind.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if kind.is_char_device() {
            return "a character device";
        }
        if kind.is_block_device() {
            return "a block device";
        }
        if kind.is_socket() {
            return "a socket";
        }
    }
    "a special file"
}

/// Removes `path` if it exists and syncs its directory, so that the removal is on disk
/// before whatever follows (a stale summary must be gone before a new run starts).
pub fn remove_file(path: &Path) -> Result<()> {
    match std::fs::remove_file(path) {
        Ok(()) => sync_dir(path),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(Error::io(path, e)),
    }
}

/// Creates the temporary file `path`, new and empty, for writing. It is created
/// exclusively (`O_CREAT | O_EXCL`), which never follows a symbolic link nor opens a FIFO
/// or a device already there: opening an existing `run.mcap.tmp` that was a link used to
/// truncate and overwrite the link's target. A stale temporary file (left by a kill, or
/// planted) is first unlinked by its name, which removes a link and leaves its target
/// alone. Should another process create the name in between, the creation fails rather
/// than share the file.
pub fn create_tmp(path: &Path) -> std::io::Result<File> {
    match std::fs::remove_file(path) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
        Err(e) => return Err(e),
    }
    std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)
}

/// Removes the temporary files of whole-file writes ([`process_tmp_path`]: `NAME.PID.tmp`)
/// in `dir` whose process has ended, only those of the file `only` when given. A kill
/// between the creation of such a file and its rename leaves it behind, and the next write
/// of `NAME`, by another process, takes another name: without this it stayed forever and
/// was carried into archives. A temporary file of a live process (this one included) is
/// kept: it is that process's write in progress. Best effort: a name that cannot be
/// removed is left, and nothing is removed where a process's liveness cannot be checked
/// (not Unix). Returns the names removed.
pub fn remove_stale_tmps(dir: &Path, only: Option<&std::ffi::OsStr>) -> Vec<PathBuf> {
    let mut removed = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return removed;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let Some((file, pid)) = name.to_str().and_then(split_process_tmp) else {
            continue;
        };
        if only.is_some_and(|o| o != std::ffi::OsStr::new(file)) || process_alive(pid) {
            continue;
        }
        // A directory under such a name is not one of ours.
        if e.file_type().is_ok_and(|t| t.is_dir()) {
            continue;
        }
        let path = e.path();
        if std::fs::remove_file(&path).is_ok() {
            removed.push(path);
        }
    }
    removed
}

/// `NAME` and `PID` of a temporary name `NAME.PID.tmp`; `None` for any other name.
fn split_process_tmp(name: &str) -> Option<(&str, u32)> {
    let stem = name.strip_suffix(TMP_SUFFIX)?;
    let (file, pid) = stem.rsplit_once('.')?;
    let digits = !pid.is_empty() && pid.bytes().all(|b| b.is_ascii_digit());
    if file.is_empty() || !digits {
        return None;
    }
    Some((file, pid.parse().ok()?))
}

/// Whether the process `pid` exists (on this machine). Where that cannot be told, and for
/// a PID the system cannot have, it counts as alive, so that its file is kept.
fn process_alive(pid: u32) -> bool {
    if pid == std::process::id() {
        return true;
    }
    #[cfg(unix)]
    {
        let Ok(p) = libc::pid_t::try_from(pid) else {
            return true;
        };
        if p <= 0 {
            return true;
        }
        // SAFETY: signal 0 sends nothing; kill only checks that the process exists.
        let r = unsafe { libc::kill(p, 0) };
        r == 0 || std::io::Error::last_os_error().raw_os_error() != Some(libc::ESRCH)
    }
    #[cfg(not(unix))]
    true
}

/// Syncs the directory holding `path` (its entries: creations, renames, removals). Where
/// directories cannot be opened for syncing (not Unix), does nothing.
pub fn sync_dir(path: &Path) -> Result<()> {
    #[cfg(unix)]
    {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        fault::dir_sync_point()
            .and_then(|()| File::open(dir))
            .and_then(|d| d.sync_all())
            .map_err(|e| Error::io(dir, e))?;
    }
    #[cfg(not(unix))]
    let _ = path;
    Ok(())
}

/// A file whose writes pass through the [`fault`] hooks.
pub(crate) struct FaultFile(pub(crate) File);

impl FaultFile {
    /// Creates the temporary file `path` for writing ([`create_tmp`]).
    pub(crate) fn create_tmp(path: &Path) -> std::io::Result<Self> {
        Ok(FaultFile(create_tmp(path)?))
    }

    /// Syncs the data and metadata of the file.
    pub(crate) fn sync(&self) -> std::io::Result<()> {
        self.0.sync_all()
    }
}

impl Write for FaultFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match fault::point(true) {
            Ok(()) => self.0.write(buf),
            // A torn write: the first half lands, then the process dies or the disk is full.
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {
                let half = buf.len() / 2;
                self.0.write_all(&buf[..half])?;
                if fault::abort_now() {
                    std::process::abort();
                }
                Ok(half)
            }
            Err(e) => Err(e),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.0.flush()
    }
}

/// Fault injection for the reliability tests: makes the n-th write of a record or summary
/// fail as on a full disk, or aborts the process there as `kill -9` would. Nothing in
/// cdlab sets a plan; only tests do, through this hidden API, so that the fault lands on
/// a chosen write rather than at a time.
#[doc(hidden)]
pub mod fault {
    use std::sync::atomic::{AtomicU64, Ordering};

    const NONE: u64 = 0;
    const ENOSPC: u64 = 1;
    const ABORT: u64 = 2;
    const READ: u64 = 3;
    const RENAME: u64 = 4;
    const DIR_SYNC: u64 = 5;

    static MODE: AtomicU64 = AtomicU64::new(NONE);
    static AT: AtomicU64 = AtomicU64::new(0);
    static COUNT: AtomicU64 = AtomicU64::new(0);

    /// What to do at the fault points (each write to a record, CSV or summary file, and
    /// each rename into place), counted from 1 since the last [`set`].
    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    pub enum Plan {
        /// Nothing (the default).
        None,
        /// The `n`-th point writes half its bytes, every later write fails with ENOSPC
        /// (the disk stays full; renames still pass).
        DiskFull(u64),
        /// The `n`-th point writes half its bytes (a rename: nothing) and aborts the
        /// process.
        Abort(u64),
        /// The `n`-th whole read of a record ([`super::read`]) fails with an I/O error;
        /// the reads before and after it, and every write, pass. Only reads are counted.
        ReadFails(u64),
        /// The `n`-th rename into place fails with an I/O error before anything is
        /// renamed; only renames are counted, every write passes.
        RenameFails(u64),
        /// The `n`-th sync of a directory ([`super::sync_dir`]) fails with an I/O error
        /// (after whatever it was to make durable happened); only those syncs are counted.
        DirSyncFails(u64),
    }

    /// Installs `plan` and restarts the count.
    pub fn set(plan: Plan) {
        let (mode, at) = match plan {
            Plan::None => (NONE, 0),
            Plan::DiskFull(n) => (ENOSPC, n),
            Plan::Abort(n) => (ABORT, n),
            Plan::ReadFails(n) => (READ, n),
            Plan::RenameFails(n) => (RENAME, n),
            Plan::DirSyncFails(n) => (DIR_SYNC, n),
        };
        COUNT.store(0, Ordering::SeqCst);
        AT.store(at, Ordering::SeqCst);
        MODE.store(mode, Ordering::SeqCst);
    }

    /// Fault points passed since the last [`set`].
    pub fn count() -> u64 {
        COUNT.load(Ordering::SeqCst)
    }

    pub(super) fn abort_now() -> bool {
        MODE.load(Ordering::SeqCst) == ABORT
    }

    /// Passes one point. `Err(Interrupted)` asks a write to tear (write half, then abort
    /// or report a short write); a rename at its abort point aborts here.
    pub(crate) fn point(write: bool) -> std::io::Result<()> {
        let mode = MODE.load(Ordering::Relaxed);
        if mode != ENOSPC && mode != ABORT {
            return Ok(());
        }
        let k = COUNT.fetch_add(1, Ordering::SeqCst) + 1;
        let at = AT.load(Ordering::SeqCst);
        if k < at {
            return Ok(());
        }
        match (mode, k == at, write) {
            (ABORT, true, true) | (ENOSPC, true, true) => {
                Err(std::io::Error::from(std::io::ErrorKind::Interrupted))
            }
            (ABORT, true, false) => std::process::abort(),
            (ENOSPC, false, true) => Err(disk_full()),
            _ => Ok(()),
        }
    }

    /// Passes one read point: under [`Plan::ReadFails`], the planned read fails (EIO).
    pub(crate) fn read_point() -> std::io::Result<()> {
        counted_point(READ)
    }

    /// Passes one rename point: under [`Plan::RenameFails`], the planned rename fails.
    pub(crate) fn rename_point() -> std::io::Result<()> {
        counted_point(RENAME)
    }

    /// Passes one directory sync: under [`Plan::DirSyncFails`], the planned sync fails.
    pub(crate) fn dir_sync_point() -> std::io::Result<()> {
        counted_point(DIR_SYNC)
    }

    /// A point counted only under the plan `mode`, failing (EIO) at its planned count.
    fn counted_point(mode: u64) -> std::io::Result<()> {
        if MODE.load(Ordering::Relaxed) != mode {
            return Ok(());
        }
        let k = COUNT.fetch_add(1, Ordering::SeqCst) + 1;
        if k != AT.load(Ordering::SeqCst) {
            return Ok(());
        }
        #[cfg(unix)]
        {
            Err(std::io::Error::from_raw_os_error(libc::EIO))
        }
        #[cfg(not(unix))]
        {
            Err(std::io::Error::other("injected fault"))
        }
    }

    fn disk_full() -> std::io::Error {
        #[cfg(unix)]
        {
            std::io::Error::from_raw_os_error(libc::ENOSPC)
        }
        #[cfg(not(unix))]
        {
            std::io::Error::from(std::io::ErrorKind::StorageFull)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The PID of a process that has ended (a child waited for).
    fn dead_pid() -> u32 {
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        child.wait().unwrap();
        pid
    }

    /// Stale temporary files of whole-file writes are removed by the next write of their
    /// file (issue 36, item 12: they stayed forever and went into archives), those of live
    /// processes and of other files are kept, and other names are never touched.
    #[cfg(unix)]
    #[test]
    fn the_next_write_removes_the_stale_temporaries_of_dead_processes() {
        let d = TempDir::new("stale-tmps");
        let dead = dead_pid();
        let names = [
            format!("summary.json.{dead}.tmp"),
            "summary.json.1.tmp".to_string(),
            format!("summary.txt.{dead}.tmp"),
            format!("summary.json.{}.x", dead),
            "summary.json.tmp".to_string(),
            "notes.1x.tmp".to_string(),
        ];
        for n in &names {
            std::fs::write(d.0.join(n), b"stale").unwrap();
        }
        write_file(&d.0.join("summary.json"), b"{}").unwrap();
        let mut want: Vec<String> = names[1..].to_vec();
        want.push("summary.json".into());
        want.sort();
        assert_eq!(d.names(), want);
        let gone = remove_stale_tmps(&d.0, None);
        assert_eq!(gone, vec![d.0.join(&names[2])]);
        assert_eq!(split_process_tmp("a.b.12.tmp"), Some(("a.b", 12)));
        assert_eq!(split_process_tmp(".12.tmp"), None);
        assert!(process_alive(std::process::id()) && process_alive(1) && !process_alive(dead));
    }

    /// A fresh directory under the system temp dir, removed when dropped.
    struct TempDir(PathBuf);

    impl TempDir {
        fn new(name: &str) -> Self {
            let p = std::env::temp_dir().join(format!("cdlab-fsio-{name}-{}", std::process::id()));
            let _ = std::fs::remove_dir_all(&p);
            std::fs::create_dir_all(&p).unwrap();
            TempDir(p)
        }

        fn names(&self) -> Vec<String> {
            let mut v: Vec<String> = std::fs::read_dir(&self.0)
                .unwrap()
                .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
                .collect();
            v.sort();
            v
        }
    }

    impl Drop for TempDir {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    /// The temporary name is in the target's directory and carries this process's id (two
    /// shards writing one sample each write their own), and a write leaves the new content
    /// under the real name and nothing else.
    #[test]
    fn write_file_replaces_whole_through_a_temporary_of_this_process() {
        let tmp = TempDir::new("write");
        let f = tmp.0.join("seed1.bin");
        let t = process_tmp_path(&f);
        assert_eq!(t.parent(), Some(tmp.0.as_path()));
        assert_eq!(
            t.file_name().unwrap().to_string_lossy(),
            format!("seed1.bin.{}.tmp", std::process::id())
        );
        write_file(&f, b"old").unwrap();
        write_file(&f, b"new content").unwrap();
        assert_eq!(std::fs::read(&f).unwrap(), b"new content");
        assert_eq!(tmp.names(), vec!["seed1.bin".to_string()]);
    }

    /// A write that fails (here its temporary name is taken by a directory) leaves the old
    /// file as it was and names the temporary file in the error.
    #[test]
    fn a_failed_write_leaves_the_old_file() {
        let tmp = TempDir::new("fail");
        let f = tmp.0.join("summary.json");
        write_file(&f, b"old").unwrap();
        std::fs::create_dir(process_tmp_path(&f)).unwrap();
        let e = write_file(&f, b"new").unwrap_err();
        match &e {
            Error::Io { path, .. } => assert_eq!(path, &process_tmp_path(&f)),
            other => panic!("expected an I/O error on the temporary file, got {other:?}"),
        }
        assert_eq!(std::fs::read(&f).unwrap(), b"old");
    }

    /// A path that names no file is refused before anything is created.
    #[test]
    fn a_path_without_a_file_name_is_refused() {
        let e = write_file(Path::new("/"), b"x").unwrap_err();
        assert!(
            matches!(&e, Error::NotAFile { path } if path == Path::new("/")),
            "{e:?}"
        );
        assert_eq!(e.to_string(), "/: not a file name");
    }

    /// A stale temporary file that is a symbolic link (to a file, or dangling) is replaced
    /// by a new file: the link's target is neither truncated nor created. Opening the name
    /// used to follow the link.
    #[cfg(unix)]
    #[test]
    fn a_stale_temporary_link_is_removed_not_followed() {
        let tmp = TempDir::new("link");
        let f = tmp.0.join("summary.json");
        let victim = tmp.0.join("victim");
        std::fs::write(&victim, b"precious").unwrap();
        std::os::unix::fs::symlink(&victim, process_tmp_path(&f)).unwrap();
        write_file(&f, b"new").unwrap();
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
        assert_eq!(std::fs::read(&f).unwrap(), b"new");
        let nowhere = tmp.0.join("nowhere");
        std::os::unix::fs::symlink(&nowhere, process_tmp_path(&f)).unwrap();
        write_file(&f, b"newer").unwrap();
        assert!(
            nowhere.symlink_metadata().is_err(),
            "the dangling link's target was created"
        );
        assert_eq!(std::fs::read(&f).unwrap(), b"newer");
        assert_eq!(
            tmp.names(),
            vec!["summary.json".to_string(), "victim".to_string()]
        );
    }

    /// A file to replace that is a link, a FIFO, a directory or a device is refused, by
    /// [`write_file`] and by [`rename`], with its path and what it is; nothing changes.
    #[cfg(unix)]
    #[test]
    fn only_regular_files_are_replaced() {
        let tmp = TempDir::new("special");
        let victim = tmp.0.join("victim");
        std::fs::write(&victim, b"precious").unwrap();
        let link = tmp.0.join("link.bin");
        std::os::unix::fs::symlink(&victim, &link).unwrap();
        let fifo = tmp.0.join("fifo.bin");
        let c = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: a valid NUL-terminated path and mode.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let dir = tmp.0.join("dir.bin");
        std::fs::create_dir(&dir).unwrap();
        for (path, what) in [
            (&link, "a symbolic link"),
            (&fifo, "a FIFO"),
            (&dir, "a directory"),
        ] {
            let e = write_file(path, b"x").unwrap_err();
            assert!(
                matches!(&e, Error::Run { path: p, fault: RunFault::NotRegular, .. } if p == path),
                "{e:?}"
            );
            let text = e.to_string();
            assert!(
                text.contains(&path.display().to_string()) && text.contains(what),
                "{text}"
            );
            let from = tmp.0.join("new");
            std::fs::write(&from, b"x").unwrap();
            assert!(rename(&from, path).is_err());
        }
        assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
        assert!(link.symlink_metadata().unwrap().file_type().is_symlink());
        let e = check_replaceable(Path::new("/dev/null")).unwrap_err().to_string();
        assert!(e.contains("/dev/null is a character device"), "{e}");
        check_replaceable(&victim).unwrap();
        check_replaceable(&tmp.0.join("absent")).unwrap();
    }
}
