//! Running biaxial tests from a program: the library face of what `cdlab biaxial`,
//! `cdlab prepare` and `cdlab summarize` do, with typed outcomes instead of printed text.
//!
//! - [`configure`] builds a configuration (a TOML file or the default, then overrides);
//! - [`prepare`] deposits and compacts a sample and writes it, [`read_sample`] reads one back
//!   and [`adopt_sample`] makes a configuration describe it;
//! - [`start`] runs a new test into the configuration's output directory, [`resume`]
//!   continues one from its last checkpoint; both report their progress to a [`Progress`]
//!   (any `FnMut(&Event)` closure is one) and stop at a checkpoint when their
//!   [`Cancel`] token is set, returning [`crate::Error::Interrupted`];
//! - [`open`] reads a finished run back: configuration, summary, series and snapshots;
//!   [`open_test`] reads a run or an archived test alike, with the same checks (what the
//!   Python package's `cdlab.open` is);
//! - [`write_curves`] draws a run's figures, [`write_comparison`] several runs' curves on
//!   common axes, [`summarize`] writes its summary again from its record.
//!
//! Nothing here installs a signal handler: a caller that wants Ctrl-C to stop a run at a
//! checkpoint calls [`crate::interrupt::install`] and passes the token it returns, as the
//! command line does.
//!
//! ```no_run
//! use cdlab::config::{Backend, Overrides};
//! use cdlab::interrupt::Cancel;
//! use cdlab::run::{self, Event};
//!
//! let config = run::configure(None, &Overrides {
//!     disks: Some(300),
//!     strain: Some(0.002),
//!     backend: Some(Backend::Cpu),
//!     out: Some("runs/tiny".into()),
//!     ..Default::default()
//! })?;
//! let mut rows = 0;
//! let mut progress = |e: &Event| {
//!     if let Event::Row { .. } = e {
//!         rows += 1;
//!     }
//! };
//! let outcome = run::start(&config, None, run::Existing::Replace, &mut progress, &Cancel::new())?;
//! println!("peak sigma1 {:.3} MPa after {rows} rows", outcome.summary.sigma1_peak_mpa);
//! let finished = run::open(&outcome.dir)?;
//! println!("{} snapshots", finished.record.snapshots.len());
//! # Ok::<(), cdlab::Error>(())
//! ```
//!
//! `examples/run_test.rs` is the same, runnable (`cargo run --release --example run_test`),
//! and `docs/library.md` describes the API.

mod backend;
pub mod bench;
mod compare;
pub mod machine;
mod open;
mod recording;
mod sample;
mod summary;
mod test;

use std::path::{Path, PathBuf};

pub use crate::interrupt::Cancel;
use backend::open_backend_told;
pub use backend::{AUTO_GPU_FROM_DISKS, open_backend, open_backend_noted};
pub use compare::write_comparison;
pub use open::{FinishedRun, OpenedTest, TestKind, open, open_test, write_curves};
pub use recording::{Recording, snapshot};
pub use sample::{
    Prepared, PreparedSample, adopt_sample, differences, prepare, read_sample, sample_differences,
};
pub use summary::{
    SUMMARY_FILE, Summarized, read_checked_summary, rebuild_summary, summarize, summary_fault, summary_of,
    write_summary,
};
pub use test::{Existing, RESULT_FILES, check_out_dir, resume, start};
#[doc(hidden)]
pub use test::{clear_results, run_fresh, run_resume};

use crate::config::units::{Dimension, parse_with_unit};
use crate::config::{Config, Overrides, Pressure};
use crate::error::{Error, Result};
use crate::measure::SeriesRow;
use crate::measure::summary::Summary;
use crate::protocol::prepare::DepositionReport;
use crate::protocol::{Phase, PhaseEnd, Settling};

/// What a run reports while it goes, in the order it happens. Borrowed: a receiver that
/// keeps something copies it.
#[derive(Debug)]
#[non_exhaustive]
pub enum Event<'a> {
    /// The grains were deposited (a test without a prepared sample, or [`prepare`]).
    Deposited {
        /// Number of disks.
        disks: usize,
        /// Packing, coordination, grading and wall time of the deposit.
        report: &'a DepositionReport,
    },
    /// A resume could not use the whole record: it continues from the last intact
    /// checkpoint before the damage, and recomputes the run from there.
    FellBack {
        /// The record file.
        file: &'a Path,
        /// What is wrong with the record.
        why: &'a str,
        /// The checkpoint's step.
        step: u64,
        /// The checkpoint's phase.
        phase: Phase,
        /// The axial strain at the checkpoint, when it is in the compression.
        strain: Option<f64>,
    },
    /// A complete record's summary was missing or could not stand, and was written again
    /// from the record; nothing is run.
    SummaryRewritten {
        /// The run directory.
        dir: &'a Path,
        /// What was wrong with the summary ("is missing", "is damaged (...)").
        fault: &'a str,
    },
    /// Where a phase's time went on the backend ([`crate::backend::Backend::activity`]).
    Activity {
        /// The phase that ended.
        phase: Phase,
        /// The backend's account, one line.
        text: &'a str,
    },
    /// A resumed run goes on from its checkpoint.
    Resuming {
        /// The run directory.
        dir: &'a Path,
        /// The checkpoint's step.
        step: u64,
        /// Simulated time at the checkpoint (s).
        time_s: f64,
        /// The phase the run resumes in.
        phase: Phase,
    },
    /// Why the run is on the backend it is on, where a user may not expect it (`auto`
    /// leaving a hardware GPU unused for a small sample).
    BackendNote(&'a str),
    /// The steps begin.
    Running {
        /// The backend's name, with its device.
        backend: &'a str,
        /// The run directory.
        dir: &'a Path,
    },
    /// A row of the series, as recorded (its `wall_s` counts the run's earlier parts).
    Row {
        /// The row.
        row: &'a SeriesRow,
        /// The axial strain at which the test ends: the compression's progress is
        /// `row.strain_axial / strain_end`.
        strain_end: f64,
    },
    /// The largest overlap passed docs/method.md's bound ([`crate::analysis::report::OVERLAP_BOUND_REL`]
    /// of r_min) for the first time in this run (or this part of it).
    OverlapBound {
        /// The row where it did.
        row: &'a SeriesRow,
        /// Step and axial strain of the last row whose largest overlap was within half the
        /// bound, if one was: how fast it then grew tells a small step from slow sinking.
        within_half: Option<(u64, f64)>,
    },
    /// A preparation phase's equilibrium check, after each window of its steps: the
    /// kinetic ratio and force imbalance against their thresholds ([`settle_time_left`]
    /// estimates the time left from a series of them).
    Settling(&'a Settling),
    /// A phase ended (settled or at its time cap; the compression at its end strain).
    PhaseEnd(&'a PhaseEnd),
    /// No more steps run (the test ended, failed or was stopped): a display can close.
    StepsEnded,
    /// The summary has no shear-band analysis, for this reason.
    NoShearBands(&'a Error),
}

/// Receives a run's [`Event`]s. Any `FnMut(&Event)` closure is one; [`Silent`] ignores them.
pub trait Progress {
    /// Called for each event, on the thread that runs the test.
    fn event(&mut self, event: &Event<'_>);
}

impl<F: FnMut(&Event<'_>)> Progress for F {
    fn event(&mut self, event: &Event<'_>) {
        self(event)
    }
}

/// A [`Progress`] that ignores every event.
#[derive(Clone, Copy, Debug, Default)]
pub struct Silent;

impl Progress for Silent {
    fn event(&mut self, _: &Event<'_>) {}
}

/// A test that ran to its end (or whose complete record got its summary back).
#[derive(Clone, Debug)]
pub struct RunOutcome {
    /// The run directory: record, `summary.json`, `summary.txt`.
    pub dir: PathBuf,
    /// The summary written there.
    pub summary: Summary,
    /// The checkpoint step a resumed run continued from; `None` for a new test.
    pub resumed_from: Option<u64>,
    /// True when nothing ran: the record was complete and only its summary was written
    /// again from it.
    pub summary_only: bool,
}

/// The configuration of a new run: `file` (TOML) or the built-in default, then `overrides`,
/// validated. A confining stress given as text with its unit (the command line's
/// `--sigma3 8MPa`) is parsed with [`sigma3`].
pub fn configure(file: Option<&Path>, overrides: &Overrides) -> Result<Config> {
    let mut config = match file {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    };
    config.apply(overrides);
    config.validate()?;
    Ok(config)
}

/// A confining stress written with its unit (`8MPa`, `500 kPa`), for [`Overrides::sigma3`];
/// `field` names it in the error.
pub fn sigma3(text: &str, field: &str) -> Result<Pressure> {
    parse_with_unit(text, Dimension::Pressure)
        .map(Pressure)
        .map_err(|e| Error::invalid(field, text, &e.0))
}

/// Seconds left to axial strain `end` at the mean rate since (`w0` s of wall time, axial
/// strain `e0`), at wall time `wall` (s) and axial strain `strain`, once the compression
/// has gone a measurable way (none before): what a progress display shows as the time
/// left.
pub fn time_left(w0: f64, e0: f64, wall: f64, strain: f64, end: f64) -> Option<f64> {
    let (done, spent) = (strain - e0, wall - w0);
    (done > 1e-4 && spent > 0.0).then(|| (end - strain).max(0.0) * spent / done)
}

/// Checks of a preparation phase that [`settle_time_left`] fits: the last this many, so
/// that the estimate follows the phase's recent decay rather than its violent start.
pub const SETTLE_FIT_CHECKS: usize = 10;

/// Simulated seconds a preparation phase has left, from its equilibrium checks
/// `(phase time s, kinetic ratio)` in order: `(estimate, at most)`. The estimate extends
/// the exponential decay of the kinetic ratio fitted over the last [`SETTLE_FIT_CHECKS`]
/// checks (least squares on its logarithm) down to `threshold`; none while the ratio is
/// not decaying (by 5% or more over those checks) or fewer than three checks have come,
/// and 0 once it is below (the force balance may still hold the phase). The bound is the time to the phase's cap
/// `max_time_s`, which ends it in any case. A frictionless compaction's ratio fluctuates
/// near its threshold once the packing is dense (docs/protocol.md, "Equilibrium"), so the
/// estimate is a trend, not a promise; the bound is one.
pub fn settle_time_left(checks: &[(f64, f64)], threshold: f64, max_time_s: f64) -> (Option<f64>, f64) {
    let Some(&(now, last)) = checks.last() else {
        return (None, max_time_s);
    };
    let cap = (max_time_s - now).max(0.0);
    if last < threshold {
        return (Some(0.0), cap);
    }
    let pts: Vec<(f64, f64)> = checks[checks.len().saturating_sub(SETTLE_FIT_CHECKS)..]
        .iter()
        .filter(|p| p.1 > 0.0 && p.1.is_finite())
        .map(|&(t, k)| (t, k.ln()))
        .collect();
    if pts.len() < 3 {
        return (None, cap);
    }
    let n = pts.len() as f64;
    let (mt, ml) = pts.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0 / n, a.1 + p.1 / n));
    let (sxy, sxx) = pts.iter().fold((0.0, 0.0), |a, p| {
        (a.0 + (p.0 - mt) * (p.1 - ml), a.1 + (p.0 - mt) * (p.0 - mt))
    });
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let span = pts[pts.len() - 1].0 - pts[0].0;
    // A trend of less than 5% over the fitted checks is no decay (nor a rounding error).
    if !(slope.is_finite() && slope * span < -0.05) {
        return (None, cap);
    }
    // From the fitted value now, which the fluctuations of one check move less than the last.
    let fitted = ml + slope * (now - mt);
    let left = ((fitted - threshold.ln()) / -slope).max(0.0);
    (Some(left.min(cap)), cap)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ratio falling tenfold per simulated second from 1e-5 reaches 1e-7 two seconds
    /// after it reads 1e-5; a flat or rising ratio gives no estimate but the cap's bound;
    /// one below the threshold leaves nothing to wait for on its side; the estimate never
    /// passes the cap.
    #[test]
    fn settle_time_left_extends_the_decay_to_the_threshold() {
        let decay: Vec<(f64, f64)> = (0..12)
            .map(|k| (0.1 * k as f64, 1e-5 * 10f64.powf(1.1 - 0.1 * k as f64)))
            .collect();
        let (est, cap) = settle_time_left(&decay, 1e-7, 60.0);
        assert!((est.unwrap() - 2.0).abs() < 1e-9, "{est:?}");
        assert!((cap - 58.9).abs() < 1e-9);
        let flat: Vec<(f64, f64)> = (0..12).map(|k| (0.1 * k as f64, 3e-7)).collect();
        assert_eq!(settle_time_left(&flat, 1e-7, 60.0).0, None);
        let below = [(1.0, 1e-6), (1.1, 5e-7), (1.2, 5e-8)];
        assert_eq!(settle_time_left(&below, 1e-7, 60.0).0, Some(0.0));
        let (est, cap) = settle_time_left(&decay, 1e-30, 2.0);
        assert_eq!(est, Some(cap));
        assert_eq!(settle_time_left(&decay[..2], 1e-7, 60.0).0, None);
    }

    /// The estimate extrapolates the mean rate of this part: 0.01 of strain in 100 s leaves
    /// 800 s for the remaining 0.08; none before the strain has moved, none past the end.
    #[test]
    fn time_left_follows_the_mean_rate_of_the_compression() {
        assert_eq!(time_left(100.0, 0.01, 200.0, 0.02, 0.1), Some(800.0));
        assert_eq!(time_left(100.0, 0.01, 100.5, 0.01, 0.1), None);
        assert_eq!(time_left(100.0, 0.01, 300.0, 0.11, 0.1), Some(0.0));
    }
}
