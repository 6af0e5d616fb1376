//! A finished (or stopped) run read back, and its figures.

use std::path::{Path, PathBuf};

use super::summary::summary_fault;
use crate::config::Config;
use crate::error::{Error, Result, RunFault};
use crate::figures::{self, ContactsFigure, StressStrainFigure};
use crate::measure::summary::Summary;
use crate::record::{RunRecord, read_run, read_series};

/// A run read back from its directory.
#[derive(Clone, Debug)]
pub struct FinishedRun {
    /// The run directory.
    pub dir: PathBuf,
    /// The configuration the run was recorded with.
    pub config: Config,
    /// The summary beside the record; `None` while the run is not finished.
    pub summary: Option<Summary>,
    /// The record: series rows, snapshots, last checkpoint, and whether it is complete.
    pub record: RunRecord,
}

/// Reads the run in `dir`: its record (checked as [`read_run`] checks it), the
/// configuration in it, and its `summary.json` when there is one. A summary that is
/// damaged, not a cdlab summary, or another record's is an error ([`RunFault::Damaged`]),
/// never returned as this run's.
pub fn open(dir: &Path) -> Result<FinishedRun> {
    let record = read_run(dir)?;
    let config = record.config()?;
    let path = dir.join("summary.json");
    let summary = match summary_fault(dir, &record) {
        None => {
            let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
            Some(serde_json::from_str(&text).map_err(|e| Error::Run {
                path: path.clone(),
                fault: RunFault::Damaged,
                message: format!("{}: {e}", path.display()),
                remedy: None,
            })?)
        }
        Some(_) if !path.exists() => None,
        Some(fault) => {
            return Err(Error::Run {
                message: format!("{} {fault}", path.display()),
                path,
                fault: RunFault::Damaged,
                remedy: None,
            });
        }
    };
    Ok(FinishedRun {
        dir: dir.to_path_buf(),
        config,
        summary,
        record,
    })
}

/// A title naming the run's friction, confining stress and size.
fn run_title(config: Result<Config>, run: &Path) -> String {
    match config {
        Ok(c) => format!(
            "μ = {}, σ₃ = {} MPa, {} disks",
            c.test.mu,
            c.test.sigma3.0 / 1e6,
            c.sample.disks
        ),
        Err(_) => run.display().to_string(),
    }
}

/// Draws a run's curves against axial strain into `out`: `stress_strain` (sigma_1 and
/// dV/V0) and `contacts` (rolling, sliding, zero-force counts), each as PNG and SVG. `run`
/// may be a run directory or an archived test (drawn from its thinned series). Returns the
/// files written.
pub fn write_curves(run: &Path, out: &Path) -> Result<Vec<PathBuf>> {
    let (series, config) = read_series(run)?;
    crate::fsio::create_dir_all(out)?;
    let title = run_title(config, run);
    let mut written = Vec::with_capacity(4);
    written.extend(figures::save_both(
        &StressStrainFigure {
            rows: &series,
            title: title.clone(),
        },
        out,
        "stress_strain",
    )?);
    written.extend(figures::save_both(
        &ContactsFigure { rows: &series, title },
        out,
        "contacts",
    )?);
    Ok(written)
}
