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
use crate::record::atomic;
use crate::record::{MCAP_FILE, RecordHead, Recorder, RunLock, RunRecord, new_run_id, read_run};

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
        // Gone before the new record replaces the old one: a forced run killed at any
        // point never leaves the old test's results looking like its own.
        clear_results(&dir)?;
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
    let head = RecordHead {
        run_id: new_run_id(),
        backend: Some(crate::backend::Backend::name(&lab.backend)),
    };
    let mut recorder = Recorder::stage(dir, config, &head)?;
    recorder.commit()?;
    let obs = Recording::new(recorder, params.strain_end, progress, started);
    finish(config, dir, lab, obs, quiet)
}

/// The files in a run directory that hold a finished test's results.
pub const RESULT_FILES: [&str; 2] = ["summary.json", "summary.txt"];

/// Removes the results of a test from `dir`: `summary.json` first (it is what marks a test
/// finished to `cdlab report` and `cdlab sweep`), then `summary.txt` and the figures drawn
/// there (`*.png`, `*.svg`), each removal synced. Called before a new record replaces an
/// old one, and before a resume continues an unfinished record (results beside it cannot
/// be its own).
pub fn clear_results(dir: &Path) -> Result<()> {
    for name in RESULT_FILES {
        atomic::remove_file(&dir.join(name))?;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Ok(());
    };
    for e in entries.flatten() {
        let p = e.path();
        let figure = matches!(p.extension().and_then(|x| x.to_str()), Some("png" | "svg"));
        if figure && p.is_file() {
            atomic::remove_file(&p)?;
        }
    }
    Ok(())
}

/// Continues the run recorded in `dir` from its last intact checkpoint and writes its
/// summary. A record that is already complete gets its summary written again when the one
/// beside it is missing, empty, damaged or another record's; with a sound summary it is an
/// error saying the run is complete.
pub fn run_resume(dir: &Path, backend: Option<&str>, progress: &Progress) -> Result<Summary> {
    match resume(dir, backend, progress)? {
        Resumed::Run(run) => {
            let (config, lab, obs) = *run;
            finish(&config, dir, lab, obs, progress.quiet())
        }
        Resumed::Complete(summary) => Ok(*summary),
    }
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
    summary.record_id = record.as_ref().ok().and_then(|r| r.run_id.clone());
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

/// Writes `summary.txt` and then `summary.json` into `dir`, each to a temporary name,
/// synced and renamed into place ([`atomic::write_file`]): `summary.json` marks the test
/// finished, so it comes last and is never seen half-written.
pub fn write_summary(dir: &Path, summary: &Summary) -> Result<()> {
    let json = serde_json::to_string_pretty(summary).map_err(|e| Error::Other(e.to_string()))?;
    atomic::write_file(&dir.join("summary.txt"), summary.table().as_bytes())?;
    atomic::write_file(&dir.join("summary.json"), json.as_bytes())
}

/// An unfinished run reopened: its configuration, the lab at its checkpoint, and the
/// recording that goes on from there.
type Reopened = (Config, Lab<Box<dyn crate::backend::Backend>>, Recording);

/// What reopening a run directory gives.
enum Resumed {
    /// An unfinished run, ready to go on.
    Run(Box<Reopened>),
    /// A complete record whose summary was written again.
    Complete(Box<Summary>),
}

/// Why the `summary.json` beside a complete record cannot stand, if it cannot: missing,
/// empty or unreadable, or computed from another record (its `record_id`).
pub fn summary_fault(dir: &Path, rec: &RunRecord) -> Option<String> {
    let path = dir.join("summary.json");
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Some("is missing".into()),
        Err(e) => return Some(format!("cannot be read ({e})")),
    };
    if text.trim().is_empty() {
        return Some("is empty".into());
    }
    let value: serde_json::Value = match serde_json::from_str(&text) {
        Ok(v) => v,
        Err(e) => return Some(format!("is damaged ({e})")),
    };
    if serde_json::from_value::<Summary>(value.clone()).is_err() {
        return Some("is not a cdlab summary".into());
    }
    match (value.get("record_id").and_then(|v| v.as_str()), &rec.run_id) {
        (Some(theirs), Some(ours)) if theirs != ours => Some(format!(
            "belongs to another record (record_id {theirs}, the record's run_id is {ours})"
        )),
        _ => None,
    }
}

/// The summary of the complete record `rec` of `dir`, computed again from it. What the
/// record does not hold is taken from `old` (a former summary) when given: the backend's
/// name and the wall time; otherwise the record's backend and its last row's wall time.
pub fn rebuild_summary(dir: &Path, rec: &RunRecord, old: Option<&serde_json::Value>) -> Result<Summary> {
    let name = dir.join(MCAP_FILE);
    let named = |e: Error| Error::Other(format!("{}: {e}", name.display()));
    let config = rec.config().map_err(named)?;
    let Some((_, bytes)) = &rec.last_checkpoint else {
        return Err(Error::Other(format!(
            "{}: the record holds no intact checkpoint",
            name.display()
        )));
    };
    // The phase ends are in the checkpoint the run wrote as it finished.
    let state = decode(bytes).map_err(named)?.state;
    if state.phase != Phase::Done {
        return Err(Error::Other(format!(
            "{}: the record ends in phase {} (resume it with cdlab biaxial --resume)",
            name.display(),
            state.phase.name()
        )));
    }
    let old_text = |k: &str| {
        old.and_then(|o| o.get(k))
            .and_then(|v| v.as_str())
            .map(str::to_string)
    };
    let backend = old_text("backend")
        .or_else(|| rec.backend.clone())
        .unwrap_or_else(|| "unknown (not in the record)".into());
    let last_wall = rec.series.last().map(|r| r.wall_s).filter(|w| w.is_finite());
    let wall_s = old
        .and_then(|o| o.get("wall_time_s"))
        .and_then(|v| v.as_f64())
        .or(last_wall)
        .unwrap_or(0.0);
    let record = Ok(rec.clone());
    Ok(summary_of(
        &config,
        &rec.series,
        &state.ends,
        backend,
        wall_s,
        &record,
        true,
    ))
}

/// The stderr note of a resume that could not use the whole record: the file, why, and
/// the checkpoint it continues from (step, and axial strain in the compression).
fn fallback_note(file: &Path, rec: &RunRecord, step: u64, phase: Phase) -> Option<String> {
    let why = rec.damaged.as_ref()?;
    let strain = rec
        .series
        .iter()
        .rfind(|r| r.step <= step)
        .filter(|r| r.phase == "compression")
        .map_or(String::new(), |r| format!(", axial strain {:.5}", r.strain_axial));
    Some(format!(
        "warning: {}: {why}; falling back to the last intact checkpoint before the damage: \
         step {step} (phase {}{strain}); the run is recomputed from there",
        file.display(),
        phase.name()
    ))
}

/// Reopens a run directory: reads its record, rewrites it up to the last intact checkpoint
/// (rows and snapshots after it are dropped: the resumed run recomputes them exactly), and
/// restores the lab from the checkpoint. The new record is written under a temporary name
/// and replaces the old one only once it holds that checkpoint, synced
/// ([`Recorder::commit`]): at every instant a complete record with the checkpoint is on
/// disk. A complete record gets its summary rewritten when the one beside it cannot stand.
fn resume(dir: &Path, backend: Option<&str>, progress: &Progress) -> Result<Resumed> {
    let started = Instant::now();
    let file = dir.join(MCAP_FILE);
    let rec = read_run(dir)?;
    let mut config = rec
        .config()
        .map_err(|e| Error::Other(format!("{}: {e}", file.display())))?;
    if let Some(b) = backend {
        config.solver.backend = b.parse()?;
    }
    let Some((step, bytes)) = rec.last_checkpoint.clone() else {
        let why = rec
            .truncated
            .as_deref()
            .map_or(String::new(), |t| format!(" (the record {t})"));
        return Err(Error::Other(format!(
            "{}: the record holds no intact checkpoint to resume from{why}: start the run \
             again with --force",
            file.display()
        )));
    };
    let ck = decode(&bytes).map_err(|e| Error::Other(format!("{}: checkpoint: {e}", file.display())))?;
    if let Some(note) = fallback_note(&file, &rec, step, ck.state.phase) {
        eprintln!("{note}");
    }
    // A complete record read whole needs at most its summary; one cut short or damaged
    // after its final checkpoint is written again whole from it (the lab has no step left
    // to run) with its summary.
    if ck.state.phase == Phase::Done && rec.truncated.is_none() {
        let Some(fault) = summary_fault(dir, &rec) else {
            return Err(Error::Other(format!(
                "{}: this run is already complete",
                dir.display()
            )));
        };
        let old = std::fs::read_to_string(dir.join("summary.json"))
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok());
        let summary = rebuild_summary(dir, &rec, old.as_ref())?;
        write_summary(dir, &summary)?;
        eprintln!(
            "{}: the record is complete but its summary.json {fault}: written again from the \
             record",
            dir.display()
        );
        return Ok(Resumed::Complete(Box::new(summary)));
    }
    let params = ck.state.params.clone();
    let backend = open_backend(&config, ck.scene.clone(), params.step)?;
    let time = ck.scene.time;
    let lab = Lab::resume(backend, ck)?;
    let head = RecordHead {
        run_id: rec.run_id.clone().unwrap_or_else(new_run_id),
        backend: Some(crate::backend::Backend::name(&lab.backend)),
    };
    // Only now, with everything read and checked, write the new record beside the old.
    let mut obs = Recording::new(
        Recorder::stage(dir, &config, &head)?,
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
    // Results beside an unfinished record are not its own.
    clear_results(dir)?;
    obs.recorder.commit()?;
    if !progress.quiet() {
        eprintln!(
            "resuming {} from step {step} (t = {time:.3} s, phase {})",
            dir.display(),
            lab.state.phase.name()
        );
    }
    Ok(Resumed::Run(Box::new((config, lab, obs))))
}
