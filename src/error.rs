//! The crate's error type: every failure a user can cause names the field or file at fault.

use std::path::PathBuf;

/// Errors reported by cdlab. None of them is a panic: bad input, numerical blow-ups and
/// missing adapters all come back here with a message that says what to change.
#[derive(Debug, thiserror::Error)]
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
    #[error("{path}: line {line}: {message}")]
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
    /// A GPU adapter or device problem.
    #[error("GPU: {0}")]
    Gpu(String),
    /// No GPU adapter at all: the machine has no driver wgpu can use. Kept apart from
    /// [`Error::Gpu`] so that a caller can tell "no GPU here" (a test may skip) from a GPU
    /// that fails (a shader rejected, a buffer over a limit: always an error).
    #[error("GPU: {0}")]
    NoAdapter(String),
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
    // Runs and campaigns (`crate::run`, `crate::campaign`): what a caller can act on.
    /// A run directory, record or file that does not allow what was asked: `fault` says
    /// why in a form a program can match, `message` says it to a person.
    #[error("{message}")]
    Run {
        /// The run directory or file concerned.
        path: PathBuf,
        /// What is in the way.
        fault: RunFault,
        /// The full message, naming the path and what to do.
        message: String,
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
    /// Any other failure, with its message.
    #[error("{0}")]
    Other(String),
}

/// Why a run directory or file cannot be used as asked ([`Error::Run`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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
