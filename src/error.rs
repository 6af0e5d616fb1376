//! The crate's error type: every failure a user can cause names the field or file at fault.

use std::path::PathBuf;

/// Errors reported by cdlab. None of them is a panic: bad input, numerical blow-ups and
/// missing adapters all come back here with a message that says what to change.
///
/// Matches on it need a wildcard arm: variants may be added.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// A parameter outside its allowed range (names the field, the value and the range).
    #[error("invalid parameter `{field}` = {value}: {allowed}")]
    Invalid {
        /// Name of the field, as it appears in the configuration.
        field: String,
        /// The offending value, printed.
        value: String,
        /// The allowed range or form.
        allowed: String,
    },
    /// A file that cannot be parsed.
    #[error("{}", parse_text(path, *line, message))]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number (0 when unknown).
        line: usize,
        /// What was wrong.
        message: String,
    },
    /// A time step that produced a non-finite value or an overlap above the limit.
    #[error("step {step} failed: {message}")]
    Numerical {
        /// The step index at which the failure happened.
        step: u64,
        /// Which contact or body, and what went wrong.
        message: String,
    },
    /// Input/output error with the path involved.
    #[error("{path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A run stopped by a signal ([`crate::interrupt`]) after writing a checkpoint at `step`
    /// (0 when it stopped before its test began, with nothing to resume).
    #[error("stopped by {}{}", crate::interrupt::signal_name(*signal), if *step > 0 { format!(" at step {step}, where a checkpoint was written") } else { String::new() })]
    Interrupted {
        /// The signal received.
        signal: i32,
        /// The step of the checkpoint written, 0 when none was.
        step: u64,
    },
    /// The GPU: no adapter, a device or shader that fails, a buffer over a limit, a bad
    /// `WGPU_BACKEND` ([`GpuError`]).
    #[error(transparent)]
    Gpu(#[from] GpuError),
    // Files a caller can act on (read again, prepare again, wait, skip): each names what
    // is at fault; the messages are those the command line prints.
    /// A path that names no file (`/`, `..`) where a file is to be written
    /// ([`crate::fsio::write_file`]).
    #[error("{}: not a file name", path.display())]
    NotAFile {
        /// The path.
        path: PathBuf,
    },
    /// A run directory held by another cdlab process (it holds the directory's lock file):
    /// let that run end or stop it, then try again.
    #[error(
        "{} is in use by another cdlab process (it holds the lock on {}): let that run end or stop it first",
        dir.display(),
        lock.display()
    )]
    InUse {
        /// The run directory.
        dir: PathBuf,
        /// Its lock file.
        lock: PathBuf,
    },
    /// A test directory kept by `cdlab archive` (configuration, summary, thinned series)
    /// asked for its full record, which went with the run's own directory.
    #[error(
        "{} is an archived test (its configuration, summary and time series thinned to {}, \
         without the record {}); this needs the full record, which only the run's own directory holds \
         (its curves can be drawn from the thinned series)",
        dir.display(),
        thinned,
        record
    )]
    Archived {
        /// The archived test's directory.
        dir: PathBuf,
        /// The file name of the thinned series it keeps.
        thinned: &'static str,
        /// The file name of the record it lacks.
        record: &'static str,
    },
    /// A run record that is not a cdlab record, or is damaged before anything usable (a
    /// record damaged later is read up to the damage: `RunRecord::damaged`). `path` is
    /// `None` where bytes were parsed (`crate::record::parse_run`).
    #[error("{}{message}", path.as_ref().map(|p| format!("{}: ", p.display())).unwrap_or_default())]
    BadRecord {
        /// The record file, when known.
        path: Option<PathBuf>,
        /// What is wrong.
        message: String,
    },
    /// A record that failed a check (a chunk or checkpoint CRC, a message that does not
    /// decode), refused where a damaged one is not wanted (`run::open_test` without
    /// `allow_damaged`). What precedes the damage is intact.
    #[error("{}: {reason}: resuming the run recomputes it from its last intact checkpoint", file.display())]
    DamagedRecord {
        /// The record file.
        file: PathBuf,
        /// The check it failed, and where.
        reason: String,
    },
    /// A checkpoint that does not decode (`crate::protocol::checkpoint::decode`): foreign
    /// or damaged bytes.
    #[error("{message}")]
    BadCheckpoint {
        /// The byte of the checkpoint at which decoding stopped.
        offset: usize,
        /// What is wrong.
        message: String,
    },
    /// A prepared-sample file that cannot be used (`crate::protocol::sample_file`): prepare it
    /// again.
    #[error("{}: {}", path.display(), problem.describe())]
    BadSample {
        /// The sample file.
        path: PathBuf,
        /// What is wrong with it.
        problem: SampleProblem,
    },
    /// Input in which a figure finds nothing to draw (no compression rows, no friction,
    /// no disk): the figure is skipped, the others can still be drawn.
    #[error("{0}")]
    NothingToDraw(String),
    /// The drawing or the encoding of a figure failed.
    #[error("{0}")]
    Drawing(String),
    /// The shear-band analysis cannot run on the snapshots given (too few snapshots, not
    /// the same sample, too few local strain values).
    #[error("{0}")]
    BandAnalysis(String),
    // Runs and campaigns (`crate::run`, `crate::campaign`): what a caller can act on.
    /// A run directory, record or file that does not allow what was asked: `fault` says
    /// why in a form a program can match, `message` says it to a person.
    #[error("{message}")]
    Run {
        /// The run directory or file concerned.
        path: PathBuf,
        /// What is in the way.
        fault: RunFault,
        /// The full message, naming the path.
        message: String,
        /// What the caller can do about it, when something can be done.
        remedy: Option<Remedy>,
    },
    /// A campaign that cannot run as asked: its sweep file, grid or directory, or tests
    /// that failed.
    #[error("{message}")]
    Campaign {
        /// The sweep file or campaign directory.
        path: PathBuf,
        /// The tests concerned, with why, when the fault is theirs (failed tests).
        tests: Vec<(PathBuf, String)>,
        /// The full message.
        message: String,
    },
    /// A recorded snapshot that cannot be analysed or drawn as asked
    /// (`crate::record::Snapshot::fabric`, `cdlab render`): `fault` says why, so a caller
    /// can pick another snapshot or another test.
    #[error("{message}")]
    Snapshot {
        /// The run directory or archived test.
        path: PathBuf,
        /// What is missing.
        fault: SnapshotFault,
        /// The full message, naming the path.
        message: String,
    },
    /// Any other failure, with its message.
    #[error("{0}")]
    Other(String),
}

/// What went wrong with the GPU ([`Error::Gpu`]).
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum GpuError {
    /// The device failed (validation, memory, a lost device), or could not be opened.
    #[error("GPU: {0}")]
    Failure(String),
    /// The environment variable `WGPU_BACKEND` names a backend wgpu does not know: wgpu
    /// would ignore it and find no adapter. Unset it, or name those of `accepted`.
    #[error(
        "GPU: the environment variable WGPU_BACKEND = `{value}` names no GPU backend ({}): use one \
         or more, comma-separated, of {} (e.g. WGPU_BACKEND=vulkan), or unset it to try them all",
        unknown.iter().map(|b| format!("`{b}`")).collect::<Vec<_>>().join(", "),
        accepted.join(", ")
    )]
    BackendEnv {
        /// The variable's value.
        value: String,
        /// The names in it that are no backend.
        unknown: Vec<String>,
        /// The names wgpu accepts (`crate::gpu::device::BACKEND_NAMES`).
        accepted: &'static [&'static str],
    },
    /// No GPU adapter at all: the machine has no driver wgpu can use. Kept apart from the
    /// others so that a caller can tell "no GPU here" (a test may skip) from a GPU that
    /// fails (a shader rejected, a buffer over a limit: always an error).
    #[error("GPU: {0}")]
    NoAdapter(String),
    /// A buffer the sample needs is larger than the adapter allows (checked before any
    /// allocation). The way out: a sample of about `fits_disks` disks, an adapter with
    /// larger limits, or the CPU path.
    #[error(
        "GPU: the {what} buffer needs {bytes} bytes but the adapter's {limit_name} is {limit}: \
         the largest sample that fits is about {fits_disks} disks"
    )]
    Limit {
        /// Which buffer (disk, contact, integer scratch, ...).
        what: String,
        /// Bytes it needs.
        bytes: u64,
        /// The wgpu limit it exceeds (`max_storage_buffer_binding_size`, `max_buffer_size`).
        limit_name: &'static str,
        /// That limit's value on this adapter (bytes).
        limit: u64,
        /// Estimate of the largest sample that fits (disks; sizes grow linearly with them).
        fits_disks: u64,
    },
    /// A compute shader of cdlab that naga rejects before it reaches the driver: a bug in
    /// the crate (the shaders are checked by tests/gpu.rs and tests/gpu_layout.rs), not in
    /// the input; the CPU path still runs.
    #[error("GPU: shader {file} is invalid (a bug in cdlab; the CPU backend runs without it): {message}")]
    Shader {
        /// The phase shader file in `shaders/`.
        file: String,
        /// naga's diagnostic, with the line in the composed source.
        message: String,
    },
}

/// A failure of the GPU device ([`GpuError::Failure`]) as an [`Error`].
pub fn gpu_failure(message: impl Into<String>) -> Error {
    Error::Gpu(GpuError::Failure(message.into()))
}

impl Error {
    /// What a user can do about this error, for the front end to say in its own terms
    /// (the command line's flags, the Python package's calls): the library's messages name
    /// no command and no flag.
    pub fn remedy(&self) -> Option<Remedy> {
        match self {
            Error::Run { remedy, .. } => remedy.clone(),
            Error::DamagedRecord { file, .. } => Some(Remedy::Resume(
                file.parent().unwrap_or(std::path::Path::new(".")).to_path_buf(),
            )),
            Error::BadSample {
                path,
                problem: SampleProblem::OldFormat { .. } | SampleProblem::Checksum { .. },
            } => Some(Remedy::PrepareAgain(path.clone())),
            Error::Gpu(GpuError::Failure(_) | GpuError::Shader { .. }) => Some(Remedy::UseCpu),
            Error::Archived { dir, .. } => Some(Remedy::UseThinnedSeries(dir.clone())),
            _ => None,
        }
    }
}

/// What a user can do about an error ([`Error::remedy`]).
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum Remedy {
    /// Resume the run in this directory: it goes on from its last intact checkpoint
    /// (recomputing what follows a damaged part) and writes the summary at its end.
    Resume(PathBuf),
    /// Start the run again, replacing its files: nothing in its record can be resumed.
    StartAgain,
    /// The output directory holds another test's files: replace them, resume that run, or
    /// write elsewhere.
    ReplaceResumeOrElsewhere(PathBuf),
    /// Prepare the sample in this file again, with its settings (a sweep prepares it again
    /// once the file is deleted).
    PrepareAgain(PathBuf),
    /// Write the summary of the run in this directory again from its record.
    Summarize(PathBuf),
    /// Run on the CPU backend instead; a run the GPU stopped continues there from its last
    /// checkpoint.
    UseCpu,
    /// Use what this archived test keeps: its summary and thinned series, from which its
    /// curves can be drawn.
    UseThinnedSeries(PathBuf),
}

/// Why a recorded snapshot cannot be analysed or drawn ([`Error::Snapshot`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum SnapshotFault {
    /// The test holds no snapshot (an archived test kept without `--keep-last-snapshot`).
    NoSnapshot,
    /// The test holds no series row to take the sample's area from.
    NoSeriesRow,
    /// The series row nearest the snapshot gives no finite positive area.
    NoArea,
    /// No disk-disk contact of the snapshot carries force.
    NoForce,
    /// What was asked compares the snapshot with an earlier one, and it is the first.
    NoEarlier,
}

/// Why a run directory or file cannot be used as asked ([`Error::Run`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum RunFault {
    /// No run directory, or no record in it.
    NoRun,
    /// The output (a run directory, a sample file) already holds another test's files:
    /// replace them, resume, or write elsewhere.
    Occupied,
    /// The record holds no intact checkpoint: the run can only start again.
    NoCheckpoint,
    /// The run is already complete (with a sound summary): nothing to resume.
    Complete,
    /// The record is not finished: resume it before summarising.
    Unfinished,
    /// A test, sample or record of other settings than those asked for.
    OtherSettings,
    /// A record or file whose content cannot be used (damaged, or not what it should be).
    Damaged,
    /// An output path that exists and is not a regular file (a symbolic link, a FIFO, a
    /// device node, a directory): cdlab never replaces one ([`crate::fsio::check_replaceable`]).
    NotRegular,
}

/// What makes a prepared-sample file unusable ([`Error::BadSample`]).
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum SampleProblem {
    /// A format that holds no checksum (`version`), which cannot be checked for damage.
    OldFormat {
        /// The format version found.
        version: u32,
    },
    /// Not a cdlab sample file at all (its magic is someone else's).
    NotASample,
    /// Shorter than the header.
    ShortHeader {
        /// Bytes in the file.
        len: usize,
        /// Bytes of the header.
        header: usize,
    },
    /// The payload's length differs from the header's.
    Length {
        /// Bytes of payload the header announces.
        announced: u64,
        /// Bytes of payload the file holds.
        found: u64,
    },
    /// The payload's CRC-32 differs from the header's.
    Checksum {
        /// CRC-32 of the payload as read.
        computed: u32,
        /// CRC-32 the header records.
        recorded: u32,
    },
    /// The payload passed its checks but does not decode as a sample.
    Payload(String),
    /// Not a regular file (a device such as `/dev/zero`, a FIFO, a directory): what it is.
    NotAFile(&'static str),
    /// Larger than any sample this machine can run: read whole, it would fill the memory.
    TooLarge {
        /// Bytes in the file.
        len: u64,
        /// The most bytes a sample of the most disks this machine can run takes.
        limit: u64,
    },
    /// The scene holds another number of disks than its parameters record.
    DiskCount {
        /// Disks in the scene.
        found: usize,
        /// Disks the parameters record.
        recorded: usize,
    },
}

impl SampleProblem {
    /// The problem in words, with what to do about it ([`Error::remedy`] says it as a
    /// value).
    pub fn describe(&self) -> String {
        match self {
            SampleProblem::OldFormat { .. } => "a sample in the old format without a checksum, which \
                 cannot be checked for damage: prepare it again with its settings (for a sweep, delete \
                 the file and run the sweep again, which prepares it)"
                .into(),
            SampleProblem::NotASample => {
                "not a cdlab sample (bad magic; a sample preparation writes them)".into()
            }
            SampleProblem::ShortHeader { len, header } => {
                format!("truncated: {len} bytes, shorter than the {header}-byte header")
            }
            SampleProblem::Length { announced, found } => {
                format!(
                    "damaged or truncated: the header announces {announced} bytes of data, the file holds {found}"
                )
            }
            SampleProblem::Checksum { computed, recorded } => {
                format!(
                    "damaged: CRC-32 {computed:08x} of its data, {recorded:08x} recorded; prepare the sample again"
                )
            }
            SampleProblem::Payload(why) => why.clone(),
            SampleProblem::NotAFile(what) => {
                format!("{what}, not a sample file (a sample preparation writes them)")
            }
            SampleProblem::TooLarge { len, limit } => format!(
                "{len} bytes, more than the {limit} bytes a sample of the most disks this \
                 machine can run takes: not a sample, and not read"
            ),
            SampleProblem::DiskCount { found, recorded } => {
                format!("the sample holds {found} disks but records {recorded} (a corrupt or foreign file)")
            }
        }
    }
}

/// The crate's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// Builds an [`Error::Invalid`].
    pub fn invalid(field: &str, value: impl std::fmt::Display, allowed: &str) -> Self {
        Error::Invalid {
            field: field.to_string(),
            value: value.to_string(),
            allowed: allowed.to_string(),
        }
    }

    /// Wraps an I/O error with the path it concerns.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}

/// Checks that `value` is finite and strictly positive.
pub fn check_positive(field: &str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(Error::invalid(field, value, "must be a finite number > 0"))
    }
}

/// Checks that `value` is finite and non-negative.
pub fn check_non_negative(field: &str, value: f64) -> Result<()> {
    if value.is_finite() && value >= 0.0 {
        Ok(())
    } else {
        Err(Error::invalid(field, value, "must be a finite number >= 0"))
    }
}

/// Checks that `value` lies in the closed interval `[lo, hi]` (and is not NaN).
pub fn check_range(field: &str, value: f64, lo: f64, hi: f64) -> Result<()> {
    if value >= lo && value <= hi {
        Ok(())
    } else {
        Err(Error::invalid(field, value, &format!("must lie in [{lo}, {hi}]")))
    }
}

/// What an [`Error::Parse`] says: the file, the line where it is known, and what was wrong.
fn parse_text(path: &std::path::Path, line: usize, message: &str) -> String {
    match line {
        0 => format!("{}: {message}", path.display()),
        _ => format!("{}: line {line}: {message}", path.display()),
    }
}
