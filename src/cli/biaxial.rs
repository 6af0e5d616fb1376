//! `cdlab biaxial`: one biaxial test, from deposition (or a prepared sample, or a resumed
//! record) to the summary.

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::config::units::{Dimension, parse_with_unit};
use crate::config::{Config, Density, Length, Overrides, Pressure};
use crate::error::{Error, Result};
use crate::measure::summary::Summary;
use crate::protocol::biaxial::Lab;
use crate::protocol::checkpoint::decode;
use crate::protocol::{Phase, ProtocolParams, prepare};
use crate::record::{Recorder, RunLock, read_run};

use super::run::{Progress, Recording, open_backend};

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
    /// Continue the run recorded in this directory from its last checkpoint.
    #[arg(long, conflicts_with_all = ["config", "disks", "mu", "sigma3", "strain", "seed", "out", "sample"])]
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
    let mut config = match &args.config {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    };
    let sigma3 = match &args.sigma3 {
        Some(s) => Some(Pressure(
            parse_with_unit(s, Dimension::Pressure).map_err(|e| Error::invalid("--sigma3", s, &e.0))?,
        )),
        None => None,
    };
    config.apply(&Overrides {
        disks: args.disks,
        mu: args.mu,
        sigma3,
        strain: args.strain,
        seed: args.seed,
        backend: args.backend.clone(),
        out: args.out.clone(),
    })?;
    config.validate()?;
    Ok(config)
}

/// Refuses an output directory that already holds files, unless `force`.
pub fn check_out_dir(dir: &Path, force: bool) -> Result<()> {
    if dir.exists() && !force {
        // The lock file of this process (or of an ended run) is not a result.
        let busy = std::fs::read_dir(dir)
            .map_err(|e| Error::io(dir, e))?
            .flatten()
            .any(|e| e.file_name() != crate::record::LOCK_FILE);
        if busy {
            return Err(Error::Other(format!(
                "output directory {} already holds files: pass --force to replace them, \
                 --resume {} to continue that run, or --out DIR",
                dir.display(),
                dir.display()
            )));
        }
    }
    Ok(())
}

/// A single test's progress display: its own, unless `--quiet`.
fn progress_of(args: &Args) -> Progress {
    if args.quiet {
        Progress::Quiet
    } else {
        Progress::Own
    }
}

/// Runs `cdlab biaxial`.
pub fn run(args: &Args) -> Result<()> {
    crate::interrupt::install();
    let (dir, summary) = if let Some(dir) = &args.resume {
        if !dir.is_dir() {
            return Err(Error::Other(format!("{}: no such run directory", dir.display())));
        }
        let _lock = RunLock::acquire(dir)?;
        let summary = run_resume(dir, args.backend.as_deref(), &progress_of(args));
        (dir.clone(), hint_resume(summary, dir)?)
    } else {
        let mut config = configuration(args)?;
        let sample = match &args.sample {
            Some(path) => {
                let sample = read_sample(path)?;
                adopt_sample(&mut config, &sample.params, args, path)?;
                Some(sample.scene)
            }
            None => None,
        };
        let dir = config.output.dir.clone();
        let _lock = RunLock::acquire(&dir)?;
        check_out_dir(&dir, args.force)?;
        let summary = run_fresh(&config, &dir, sample, &progress_of(args));
        (dir.clone(), hint_resume(summary, &dir)?)
    };
    println!("biaxial test finished: {}\n{}", dir.display(), summary.table());
    if !args.no_figures {
        // The record and summary are complete: a figure that cannot be drawn is reported,
        // not turned into a failed test.
        match super::render::write_curves(&dir, &dir) {
            Ok(files) => {
                let names: Vec<String> = files.iter().map(|p| p.display().to_string()).collect();
                println!("figures: {}", names.join(", "));
            }
            Err(e) => eprintln!("no figures drawn: {e}"),
        }
    }
    Ok(())
}

/// Says how to continue a run that a signal stopped at a checkpoint.
fn hint_resume<T>(outcome: Result<T>, dir: &Path) -> Result<T> {
    if let Err(Error::Interrupted { step, .. }) = &outcome
        && *step > 0
    {
        eprintln!(
            "the run in {} ends at its checkpoint of step {step}: `cdlab biaxial --resume {}` \
             continues it",
            dir.display(),
            dir.display()
        );
    }
    outcome
}

/// A sample written by `cdlab prepare`.
pub struct PreparedSample {
    /// The compacted scene.
    pub scene: crate::model::Scene,
    /// The parameters it was deposited and compacted with.
    pub params: ProtocolParams,
}

/// Reads a sample written by `cdlab prepare`, checking that its scene holds the disks its
/// parameters announce.
pub fn read_sample(path: &Path) -> Result<PreparedSample> {
    let s = crate::sample::file::read_sample(path)?;
    Ok(PreparedSample {
        scene: s.scene,
        params: s.params,
    })
}

/// The `[sample]` and `[compaction]` settings of `config` that differ from those a sample
/// was prepared with, as `key: configuration value, sample value` descriptions.
pub fn sample_differences(config: &Config, sample: &ProtocolParams) -> Vec<String> {
    let c = config.protocol();
    let counts = [
        ("sample.disks", c.disks as u64, sample.disks as u64),
        ("sample.seed", c.seed, sample.seed),
    ];
    let values = [
        ("sample.r_min", c.r_min, sample.r_min, " m"),
        ("sample.r_max", c.r_max, sample.r_max, " m"),
        ("sample.density", c.density, sample.density, " kg/m3"),
        ("sample.aspect_ratio", c.aspect, sample.aspect, ""),
        ("compaction.sigma_c", c.sigma_c, sample.sigma_c, " Pa"),
        ("compaction.friction", c.mu_compaction, sample.mu_compaction, ""),
    ];
    differences(&counts, &values, "the sample")
}

/// `key: ours here, theirs in WHERE` for each setting that differs: `counts` as
/// `(key, ours, theirs)`, then `values` as `(key, ours, theirs, unit)`.
pub fn differences(
    counts: &[(&str, u64, u64)],
    values: &[(&str, f64, f64, &str)],
    theirs_in: &str,
) -> Vec<String> {
    let counts = counts
        .iter()
        .filter(|(_, ours, theirs)| ours != theirs)
        .map(|(key, ours, theirs)| format!("{key}: {ours} here, {theirs} in {theirs_in}"));
    let values = values
        .iter()
        .filter(|(_, ours, theirs, _)| ours != theirs)
        .map(|(key, ours, theirs, unit)| format!("{key}: {ours}{unit} here, {theirs}{unit} in {theirs_in}"));
    counts.chain(values).collect()
}

/// Makes `config` describe the prepared sample a test starts from: its `[sample]` and
/// `[compaction]` settings become the sample's, so that the record, the summary and the
/// quantities scaled by `r_min` (overlaps, the velocity test) are those of the disks
/// actually simulated. A `--disks` or `--seed` flag that asks for another sample is an
/// error rather than silently ignored.
fn adopt_sample(config: &mut Config, sample: &ProtocolParams, args: &Args, path: &Path) -> Result<()> {
    let asked = [
        ("--disks", args.disks.map(|n| n as u64), sample.disks as u64),
        ("--seed", args.seed, sample.seed),
    ];
    for (flag, want, have) in asked {
        if let Some(want) = want.filter(|w| *w != have) {
            return Err(Error::Other(format!(
                "{flag} {want} contradicts the sample {} ({have}); leave {flag} out to use the \
                 sample as prepared",
                path.display()
            )));
        }
    }
    let s = &mut config.sample;
    s.disks = sample.disks;
    s.seed = sample.seed;
    s.r_min = Length(sample.r_min);
    s.r_max = Length(sample.r_max);
    s.density = Density(sample.density);
    s.aspect_ratio = sample.aspect;
    config.compaction.sigma_c = Pressure(sample.sigma_c);
    config.compaction.friction = sample.mu_compaction;
    config.validate()
}

/// Runs a new test into `dir` (which the caller has checked), from a deposition or from a
/// compacted `sample`, and writes its summary.
pub fn run_fresh(
    config: &Config,
    dir: &Path,
    sample: Option<crate::model::Scene>,
    progress: &Progress,
) -> Result<Summary> {
    let quiet = progress.quiet();
    let started = Instant::now();
    let params = config.protocol();
    params.validate()?;
    let (scene, compacted) = match sample {
        Some(scene) => (scene, true),
        None => {
            let (scene, rep) = prepare::deposit_scene(&params)?;
            if !quiet {
                eprintln!(
                    "deposited {} disks in {:.2} s: packing fraction {:.3}, coordination {:.2}, \
                     D10 {:.2} m, D60 {:.2} m, height/width {:.2}",
                    params.disks,
                    rep.seconds,
                    rep.packing_fraction,
                    rep.coordination,
                    rep.d10_m,
                    rep.d60_m,
                    rep.aspect
                );
            }
            (scene, false)
        }
    };
    let backend = open_backend(config, scene.clone(), params.step)?;
    let lab = Lab::new(backend, params.clone(), &scene, compacted)?;
    let obs = Recording::new(
        Recorder::create(dir, config)?,
        params.strain_end,
        progress,
        started,
    );
    finish(config, dir, lab, obs, quiet)
}

/// Continues the run recorded in `dir` from its last checkpoint and writes its summary.
pub fn run_resume(dir: &Path, backend: Option<&str>, progress: &Progress) -> Result<Summary> {
    let (config, lab, obs) = resume(dir, backend, progress)?;
    finish(&config, dir, lab, obs, progress.quiet())
}

fn finish(
    config: &Config,
    dir: &Path,
    mut lab: Lab<Box<dyn crate::backend::Backend>>,
    mut obs: Recording,
    quiet: bool,
) -> Result<Summary> {
    if !quiet {
        eprintln!(
            "running on {} -> {}",
            crate::backend::Backend::name(&lab.backend),
            dir.display()
        );
    }
    let outcome = lab.run(&mut obs);
    obs.finish();
    if let Err(e @ Error::Interrupted { .. }) = outcome {
        // The record ends at the checkpoint just written: close it properly for the resume.
        obs.recorder.finish()?;
        return Err(e);
    }
    outcome?;
    let wall_s = obs.wall_s();
    obs.recorder.finish()?;
    // From the record just closed: the snapshots are not kept in memory during the run.
    let summary = summary_of(
        config,
        &obs.rows,
        &obs.ends,
        crate::backend::Backend::name(&lab.backend),
        wall_s,
        &read_run(dir),
        quiet,
    );
    write_summary(dir, &summary)?;
    Ok(summary)
}

/// The summary of a finished test from its rows and phase ends, with the shear bands of
/// its record's snapshots: the same at the end of a run and in `cdlab summarize`.
pub(super) fn summary_of(
    config: &Config,
    rows: &[crate::measure::SeriesRow],
    ends: &[crate::protocol::PhaseEnd],
    backend: String,
    wall_s: f64,
    record: &Result<crate::record::RunRecord>,
    quiet: bool,
) -> Summary {
    let mut summary = Summary::new(
        rows,
        ends,
        config.test.sigma3.si(),
        config.test.mu,
        config.sample.disks,
        backend,
        wall_s,
    );
    summary.dt_s = Some(config.solver.dt.si());
    summary.deep_contacts = crate::measure::summary::DeepContacts::of_run(
        config.solver.deep_overlap,
        config.solver.deep_sweeps,
        rows,
    );
    let bands = match record {
        Ok(rec) => crate::analysis::bands::analyse_run(rec, None, None, &Default::default()),
        Err(e) => Err(Error::Other(e.to_string())),
    };
    summary.shear_bands = match bands {
        Ok(b) => Some(b),
        Err(e) => {
            if !quiet {
                eprintln!("no shear-band analysis: {e}");
            }
            None
        }
    };
    summary
}

/// Writes `summary.json` and `summary.txt` into `dir`.
pub fn write_summary(dir: &Path, summary: &Summary) -> Result<()> {
    let json = serde_json::to_string_pretty(summary).map_err(|e| Error::Other(e.to_string()))?;
    let p = dir.join("summary.json");
    std::fs::write(&p, json).map_err(|e| Error::io(&p, e))?;
    let p = dir.join("summary.txt");
    std::fs::write(&p, summary.table()).map_err(|e| Error::io(&p, e))
}

type Resumed = (Config, Lab<Box<dyn crate::backend::Backend>>, Recording);

/// Reopens a run directory: reads its record, rewrites it up to the last checkpoint (rows
/// and snapshots after it are dropped: the resumed run recomputes them exactly), and
/// restores the lab from the checkpoint.
fn resume(dir: &Path, backend: Option<&str>, progress: &Progress) -> Result<Resumed> {
    let started = Instant::now();
    let rec = read_run(dir)?;
    let mut config = rec.config()?;
    if let Some(b) = backend {
        config.solver.backend = b.parse()?;
    }
    let Some((step, bytes)) = rec.last_checkpoint.clone() else {
        return Err(Error::Other(format!(
            "{}: the record holds no checkpoint to resume from",
            dir.display()
        )));
    };
    let ck = decode(&bytes).map_err(|e| Error::Other(format!("{}: checkpoint: {e}", dir.display())))?;
    if ck.state.phase == Phase::Done {
        return Err(Error::Other(format!(
            "{}: this run is already complete",
            dir.display()
        )));
    }
    let params = ck.state.params.clone();
    let backend = open_backend(&config, ck.scene.clone(), params.step)?;
    let time = ck.scene.time;
    let lab = Lab::resume(backend, ck)?;
    // Only now, with everything read and checked, replace the files.
    let mut obs = Recording::new(
        Recorder::create(dir, &config)?,
        params.strain_end,
        progress,
        started,
    );
    for row in rec.series.iter().filter(|r| r.step <= step) {
        obs.replay(row)?;
    }
    for snap in rec.snapshots.iter().filter(|s| s.time_s <= time) {
        obs.recorder.snapshot(snap)?;
    }
    obs.ends = lab.state.ends.clone();
    obs.recorder.checkpoint(step, time, &bytes)?;
    if !progress.quiet() {
        eprintln!(
            "resuming {} from step {step} (t = {time:.3} s, phase {})",
            dir.display(),
            lab.state.phase.name()
        );
    }
    Ok((config, lab, obs))
}
