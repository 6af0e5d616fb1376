//! The prepared-sample file (`cdlab prepare`, a sweep's `samples/seedS.bin`): writing it
//! safely and reading it only once its integrity is proved.
//!
//! Layout (little endian), version 2:
//!
//! ```text
//! magic    8 bytes   "CDLABSP2"
//! length   u64       byte length of the payload
//! crc      u32       CRC-32 (IEEE) of the payload
//! payload  length    a checkpoint (`crate::protocol::checkpoint`) of the compacted sample
//! ```
//!
//! The file must be exactly `20 + length` bytes long and the CRC must match before a single
//! byte of the payload is decoded: a flipped bit in a disk position would otherwise start a
//! test from overlapping disks, and a file cut short by a full disk or a kill would be read
//! as a smaller sample. CRC-32 detects every single-bit flip and every burst of up to 32 bits;
//! truncation or extension is caught by the length before the CRC is even computed.
//!
//! Version 1 files (a bare checkpoint, magic `CDLABCK1`, no checksum) are refused with the
//! command that writes them again: nothing can tell whether such a file is intact, and
//! compacting a sample again costs minutes, while a test run from a damaged one costs hours
//! and gives a wrong answer.
//!
//! Writes go to a temporary name in the same directory, are fsynced, then renamed over the
//! target, and the directory is fsynced: a reader (another shard of a sweep) sees either no
//! file or the whole file, never half of one.

use std::fs::{File, OpenOptions, TryLockError};
use std::path::{Path, PathBuf};

use super::{LabState, ProtocolParams, checkpoint};
use crate::error::{Error, Result, SampleProblem};
use crate::model::Scene;

/// Magic of the current sample format (version 2, with a CRC-32 of the payload).
pub const MAGIC: &[u8; 8] = b"CDLABSP2";
/// Magic of the version 1 format: a bare checkpoint without a checksum.
const MAGIC_V1: &[u8; 8] = b"CDLABCK1";
/// Bytes before the payload: magic, length, CRC.
pub const HEADER_LEN: usize = 8 + 8 + 4;

/// A sample written by `cdlab prepare`.
#[derive(Clone, Debug)]
pub struct PreparedSample {
    /// The compacted scene.
    pub scene: Scene,
    /// The parameters it was deposited and compacted with.
    pub params: ProtocolParams,
}

/// The bytes of a sample file holding `state` and `scene`.
pub fn encode_sample(state: &LabState, scene: &Scene) -> Vec<u8> {
    let payload = checkpoint::encode(state, scene, &[], &[], None);
    let mut out = Vec::with_capacity(HEADER_LEN + payload.len());
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    out.extend_from_slice(&crc32fast::hash(&payload).to_le_bytes());
    out.extend_from_slice(&payload);
    out
}

/// Writes the sample of `state` and `scene` to `path` (temporary file, fsync, rename).
pub fn write_sample(path: &Path, state: &LabState, scene: &Scene) -> Result<()> {
    write_atomic(path, &encode_sample(state, scene))
}

/// Writes `bytes` to `path` so that `path` holds either its old content or all of `bytes`,
/// whenever the process or the machine stops ([`crate::fsio::write_file`]: a temporary file
/// unique to the process, so two shards never share one, fsynced, renamed, the directory
/// fsynced).
pub use crate::fsio::write_file as write_atomic;

/// Decodes the bytes of a sample file; `path` names the file in errors. The length and
/// CRC are checked before any of the payload is decoded.
pub fn decode_sample(bytes: &[u8], path: &Path) -> Result<PreparedSample> {
    let fail = |problem: SampleProblem| Error::BadSample {
        path: path.to_path_buf(),
        problem,
    };
    if bytes.len() >= 8 && &bytes[..8] == MAGIC_V1 {
        return Err(fail(SampleProblem::OldFormat { version: 1 }));
    }
    if bytes.len() < HEADER_LEN || &bytes[..8] != MAGIC {
        return Err(fail(if bytes.len() >= 8 && &bytes[..8] == MAGIC {
            SampleProblem::ShortHeader {
                len: bytes.len(),
                header: HEADER_LEN,
            }
        } else {
            SampleProblem::NotASample
        }));
    }
    let length = u64::from_le_bytes(bytes[8..16].try_into().expect("8 bytes"));
    let crc = u32::from_le_bytes(bytes[16..20].try_into().expect("4 bytes"));
    let payload = &bytes[HEADER_LEN..];
    if payload.len() as u64 != length {
        return Err(fail(SampleProblem::Length {
            announced: length,
            found: payload.len() as u64,
        }));
    }
    let found = crc32fast::hash(payload);
    if found != crc {
        return Err(fail(SampleProblem::Checksum {
            computed: found,
            recorded: crc,
        }));
    }
    let ck = checkpoint::decode(payload).map_err(|e| fail(SampleProblem::Payload(e.to_string())))?;
    let (scene, params) = (ck.scene, ck.state.params);
    if scene.disks.len() != params.disks {
        return Err(fail(SampleProblem::DiskCount {
            found: scene.disks.len(),
            recorded: params.disks,
        }));
    }
    Ok(PreparedSample { scene, params })
}

/// Reads a sample written by [`write_sample`], checking its integrity first.
///
/// Only a regular file no larger than a sample of the most disks this machine can run
/// ([`max_sample_bytes`]) is read: `--sample /dev/zero` or a huge sparse file was read
/// whole into memory until the machine ran out of it.
pub fn read_sample(path: &Path) -> Result<PreparedSample> {
    use std::io::Read;
    let fail = |problem: SampleProblem| Error::BadSample {
        path: path.to_path_buf(),
        problem,
    };
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    // Judged on the file opened, not the name: it cannot change in between.
    let meta = file.metadata().map_err(|e| Error::io(path, e))?;
    if !meta.is_file() {
        return Err(fail(SampleProblem::NotAFile(crate::fsio::file_kind(
            &meta.file_type(),
        ))));
    }
    let limit = max_sample_bytes();
    if meta.len() > limit {
        return Err(fail(SampleProblem::TooLarge {
            len: meta.len(),
            limit,
        }));
    }
    let mut bytes = Vec::new();
    // A file that grows while it is read stops at the limit too (then fails its length).
    file.take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(fail(SampleProblem::TooLarge {
            len: bytes.len() as u64,
            limit,
        }));
    }
    decode_sample(&bytes, path)
}

/// Bytes a sample file of one disk takes at most: its 15 values of 8 bytes in the
/// checkpoint layout (`checkpoint::encode`), and a reference position (2 more).
const SAMPLE_BYTES_PER_DISK: u64 = 17 * 8;

/// Bytes of a sample file beyond its disks, generously: the header, the protocol state's
/// JSON, the walls and the scene's values take a few kilobytes.
const SAMPLE_FIXED_BYTES: u64 = 1 << 20;

/// The largest sample file worth reading: one of the most disks this machine can run
/// ([`crate::config::validate::max_disks_here`]); a larger one would be refused for its
/// disk count once read.
pub fn max_sample_bytes() -> u64 {
    SAMPLE_FIXED_BYTES + crate::config::validate::max_disks_here() as u64 * SAMPLE_BYTES_PER_DISK
}

/// An exclusive claim on the preparation of one sample file, shared by processes (the
/// shards of a sweep): an advisory lock on `FILE.lock` beside it, released with the value or
/// when the process ends, however it ends.
///
/// The holder removes the lock file before releasing it, so a campaign's `samples/` holds
/// only samples. A waiter may therefore get the lock of a file already removed: it checks
/// that the path still names the file it locked, and starts again if not.
#[derive(Debug)]
pub struct SampleLock {
    file: File,
    path: PathBuf,
}

impl SampleLock {
    /// Takes the lock of the sample `path`, waiting while another process holds it;
    /// `waiting` is called once, before the first wait, when the lock is taken elsewhere.
    pub fn acquire(path: &Path, waiting: impl FnOnce()) -> Result<SampleLock> {
        let mut name = path.as_os_str().to_owned();
        name.push(".lock");
        let lock = PathBuf::from(name);
        let mut waiting = Some(waiting);
        loop {
            let file = OpenOptions::new()
                .create(true)
                .truncate(false)
                .write(true)
                .open(&lock)
                .map_err(|e| Error::io(&lock, e))?;
            match file.try_lock() {
                Ok(()) => {}
                Err(TryLockError::WouldBlock) => {
                    if let Some(say) = waiting.take() {
                        say();
                    }
                    file.lock().map_err(|e| Error::io(&lock, e))?;
                }
                Err(TryLockError::Error(e)) => return Err(Error::io(&lock, e)),
            }
            if same_file(&file, &lock) {
                return Ok(SampleLock { file, path: lock });
            }
        }
    }
}

/// Whether `path` still names the open `file` (not removed, nor replaced by another).
#[cfg(unix)]
fn same_file(file: &File, path: &Path) -> bool {
    use std::os::unix::fs::MetadataExt;
    match (file.metadata(), std::fs::metadata(path)) {
        (Ok(a), Ok(b)) => (a.dev(), a.ino()) == (b.dev(), b.ino()),
        _ => false,
    }
}

/// Without inode numbers the lock file is never removed (see `Drop`), so it is the same.
#[cfg(not(unix))]
fn same_file(_: &File, _: &Path) -> bool {
    true
}

impl Drop for SampleLock {
    fn drop(&mut self) {
        // Removed while still locked (the file closes after this), so no one can lock it
        // between the removal and the release without seeing it removed.
        #[cfg(unix)]
        let _ = std::fs::remove_file(&self.path);
        let _ = &self.file;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64-disk sample: small enough to flip every bit of its file.
    pub(super) fn tiny() -> (LabState, Scene) {
        let mut params = crate::config::Config::default().protocol();
        params.disks = 64;
        let mut scene = Scene::default();
        for k in 0..64 {
            let pos = glam::DVec2::new(2.5 * (k % 8) as f64, 2.5 * (k / 8) as f64);
            scene.disks.push(pos, 1.0, 1.0).unwrap();
        }
        let state = LabState::new(params, Default::default(), Default::default(), 0.0);
        (state, scene)
    }

    /// Every single-bit flip and every truncation of a small sample file is refused with
    /// the file's name; the intact bytes read back the same scene.
    #[test]
    fn flips_and_cuts_are_detected() {
        let (state, scene) = tiny();
        let bytes = encode_sample(&state, &scene);
        let path = Path::new("s.bin");
        let back = decode_sample(&bytes, path).unwrap();
        assert_eq!(back.scene.disks.pos, scene.disks.pos);
        for bit in 0..bytes.len() * 8 {
            let mut b = bytes.clone();
            b[bit / 8] ^= 1 << (bit % 8);
            let e = decode_sample(&b, path).unwrap_err().to_string();
            assert!(e.contains("s.bin"), "bit {bit}: {e}");
        }
        for cut in 0..bytes.len() {
            let e = decode_sample(&bytes[..cut], path).unwrap_err().to_string();
            assert!(e.contains("s.bin"), "cut {cut}: {e}");
        }
    }

    /// The lock excludes a second holder, leaves no file behind once released, and a
    /// waiter that got the lock of a removed file takes a fresh one.
    #[test]
    fn sample_lock_is_exclusive_and_leaves_no_file() {
        let dir = std::env::temp_dir().join(format!("cdlab-samplelock-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("seed1.bin");
        let first = SampleLock::acquire(&path, || panic!("free")).unwrap();
        let lock = dir.join("seed1.bin.lock");
        assert!(lock.exists());
        // A second open file description cannot take it while the first holds it.
        let other = File::open(&lock).unwrap();
        assert!(matches!(other.try_lock(), Err(TryLockError::WouldBlock)));
        drop(other);
        drop(first);
        assert!(!lock.exists(), "the lock file stays after release");
        let again = SampleLock::acquire(&path, || panic!("free")).unwrap();
        drop(again);
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// A version 1 file (a bare checkpoint) is refused with how to prepare it again.
    #[test]
    fn old_format_is_refused_with_the_fix() {
        let (state, scene) = tiny();
        let v1 = checkpoint::encode(&state, &scene, &[], &[], None);
        let e = decode_sample(&v1, Path::new("old.bin")).unwrap_err();
        let text = e.to_string();
        assert!(
            text.contains("old.bin") && text.contains("prepare it again"),
            "{text}"
        );
        assert_eq!(
            e.remedy(),
            Some(crate::error::Remedy::PrepareAgain("old.bin".into()))
        );
    }

    /// Each kind of damage comes back as its own [`SampleProblem`], so that a caller (a
    /// sweep) can tell an old format from a damaged file, with the numbers it found.
    #[test]
    fn damage_is_told_by_its_kind() {
        let (state, scene) = tiny();
        let good = encode_sample(&state, &scene);
        let path = Path::new("k.bin");
        let problem = |bytes: &[u8]| match decode_sample(bytes, path) {
            Err(Error::BadSample { path: p, problem }) => {
                assert_eq!(p, path);
                problem
            }
            other => panic!("expected a bad sample, got {other:?}"),
        };
        let payload = (good.len() - HEADER_LEN) as u64;
        let recorded = u32::from_le_bytes(good[16..20].try_into().unwrap());
        let mut flipped = good.clone();
        *flipped.last_mut().unwrap() ^= 1;
        match problem(&flipped) {
            SampleProblem::Checksum {
                computed,
                recorded: r,
            } => {
                assert_eq!(r, recorded);
                assert_eq!(computed, crc32fast::hash(&flipped[HEADER_LEN..]));
                assert_ne!(computed, r);
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(
            problem(&good[..good.len() - 7]),
            SampleProblem::Length {
                announced: payload,
                found: payload - 7
            }
        );
        assert_eq!(
            problem(&good[..12]),
            SampleProblem::ShortHeader {
                len: 12,
                header: HEADER_LEN
            }
        );
        assert_eq!(problem(b"PNG and not a sample at all"), SampleProblem::NotASample);
        let v1 = checkpoint::encode(&state, &scene, &[], &[], None);
        assert_eq!(problem(&v1), SampleProblem::OldFormat { version: 1 });
    }
}
