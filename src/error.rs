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
    /// A GPU adapter or device problem.
    #[error("GPU: {0}")]
    Gpu(String),
    /// No GPU adapter at all: the machine has no driver wgpu can use. Kept apart from
    /// [`Error::Gpu`] so that a caller can tell "no GPU here" (a test may skip) from a GPU
    /// that fails (a shader rejected, a buffer over a limit: always an error).
    #[error("GPU: {0}")]
    NoAdapter(String),
    /// A buffer the sample needs is larger than the adapter allows (checked before any
    /// allocation). The way out: a sample of about `fits_disks` disks, an adapter with
    /// larger limits, or the CPU path.
    #[error(
        "GPU: the {what} buffer needs {bytes} bytes but the adapter's {limit_name} is {limit}: \
         the largest sample that fits is about {fits_disks} disks"
    )]
    GpuLimit {
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
    #[error("GPU: shader {file} is invalid (a bug in cdlab; use --backend cpu): {message}")]
    GpuShader {
        /// The phase shader file in `shaders/`.
        file: String,
        /// naga's diagnostic, with the line in the composed source.
        message: String,
    },
    /// Any other failure, with its message.
    #[error("{0}")]
    Other(String),
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
