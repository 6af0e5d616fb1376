//! `cdlab biaxial`: one biaxial test, from deposition (or a prepared sample, or a resumed
//! record) to the summary.

use std::path::{Path, PathBuf};

use crate::config::{Config, Overrides};
use crate::error::{Error, Result};
use crate::interrupt::Cancel;
use crate::measure::summary::Summary;
use crate::run;

use super::run::Progress;

/// Options of `cdlab biaxial`.
#[derive(clap::Args, Debug, Default)]
pub struct Args {
    /// Configuration file (TOML); the built-in default when absent (`cdlab config --print-default`).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Number of disks (the paper uses 5000).
    #[arg(long)]
    pub disks: Option<usize>,
    /// Disk-disk friction coefficient.
    #[arg(long)]
    pub mu: Option<f64>,
    /// Confining stress with its unit, e.g. 8MPa, 500kPa.
    #[arg(long)]
    pub sigma3: Option<String>,
    /// Axial strain at which the test ends, in (0, 1).
    #[arg(long)]
    pub strain: Option<f64>,
    /// Seed of the grain sizes.
    #[arg(long)]
    pub seed: Option<u64>,
    /// cpu, gpu or auto.
    #[arg(long)]
    pub backend: Option<String>,
    /// Output directory (default: the configuration's output.dir).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Replace the files of an existing output directory.
    #[arg(long)]
    pub force: bool,
    /// Continue the run recorded in this directory from its last checkpoint (with the
    /// settings it was recorded with: no other setting, nor --force, applies).
    #[arg(
        long,
        conflicts_with_all = ["config", "disks", "mu", "sigma3", "strain", "seed", "out", "sample", "force"]
    )]
    pub resume: Option<PathBuf>,
    /// Start from a sample prepared by `cdlab prepare` (skips deposition and compaction).
    #[arg(long)]
    pub sample: Option<PathBuf>,
    /// No progress display.
    #[arg(long)]
    pub quiet: bool,
    /// Do not draw the stress-strain and contact-count figures beside the summary.
    #[arg(long)]
    pub no_figures: bool,
}

/// The configuration of a new run: file or default, then the flags.
pub fn configuration(args: &Args) -> Result<Config> {
    let sigma3 = args
        .sigma3
        .as_deref()
        .map(|s| run::sigma3(s, "--sigma3"))
        .transpose()?;
    run::configure(
        args.config.as_deref(),
        &Overrides {
            disks: args.disks,
            mu: args.mu,
            sigma3,
            strain: args.strain,
            seed: args.seed,
            backend: backend(args.backend.as_deref())?,
            out: args.out.clone(),
        },
    )
}

/// The backend named by `--backend`, parsed (a wrong name is an error naming
/// `solver.backend`, as in a file).
pub fn backend(name: Option<&str>) -> Result<Option<crate::config::Backend>> {
    name.map(str::parse).transpose()
}

/// Runs `cdlab biaxial`.
pub fn run(args: &Args) -> Result<()> {
    let cancel = crate::interrupt::install();
    let mut display = if args.quiet {
        Progress::Quiet
    } else {
        Progress::Own
    }
    .display();
    let (dir, outcome) = match &args.resume {
        Some(dir) => (
            dir.clone(),
            backend(args.backend.as_deref()).and_then(|b| run::resume(dir, b, &mut display, &cancel)),
        ),
        None => {
            let mut config = configuration(args)?;
            let sample = match &args.sample {
                Some(path) => {
                    let sample = run::read_sample(path)?;
                    let asked = [("--disks", args.disks.map(|n| n as u64)), ("--seed", args.seed)];
                    run::adopt_sample(&mut config, &sample.params, asked, path)?;
                    Some(sample.scene)
                }
                None => None,
            };
            let dir = config.output.dir.clone();
            (
                dir,
                run::start(
                    &config,
                    sample,
                    if args.force {
                        run::Existing::Replace
                    } else {
                        run::Existing::Refuse
                    },
                    &mut display,
                    &cancel,
                ),
            )
        }
    };
    let summary = hint_resume(outcome, &dir)?.summary;
    tell!("biaxial test finished: {}\n{}", dir.display(), summary.table());
    if !args.no_figures {
        // The record and summary are complete: a figure that cannot be drawn is reported,
        // not turned into a failed test.
        match run::write_curves(&dir, &dir) {
            Ok(files) => {
                let names: Vec<String> = files.iter().map(|p| p.display().to_string()).collect();
                tell!("figures: {}", names.join(", "));
            }
            Err(e) => note!("no figures drawn: {e}"),
        }
    }
    Ok(())
}

/// Says how to continue a run that a signal stopped at a checkpoint.
fn hint_resume<T>(outcome: Result<T>, dir: &Path) -> Result<T> {
    if let Err(Error::Interrupted { step, .. }) = &outcome
        && *step > 0
    {
        note!(
            "the run in {} ends at its checkpoint of step {step}: `cdlab biaxial --resume {}` \
             continues it",
            dir.display(),
            dir.display()
        );
    }
    outcome
}

/// [`run::run_fresh`] shown as `progress` says, stopped by a signal when the command
/// installed the handler.
pub fn run_fresh(
    config: &Config,
    dir: &Path,
    sample: Option<crate::model::Scene>,
    progress: &Progress,
) -> Result<Summary> {
    let outcome = run::run_fresh(
        config,
        dir,
        sample,
        &mut progress.display(),
        &Cancel::with_signals(),
    )?;
    Ok(outcome.summary)
}

/// [`run::run_resume`] shown as `progress` says, stopped by a signal when the command
/// installed the handler.
pub fn run_resume(
    dir: &Path,
    backend: Option<crate::config::Backend>,
    progress: &Progress,
) -> Result<Summary> {
    let outcome = run::run_resume(dir, backend, &mut progress.display(), &Cancel::with_signals())?;
    Ok(outcome.summary)
}
