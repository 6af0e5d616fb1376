//! Running a test: a new one into its output directory, or a resumed one from its record's
//! last intact checkpoint.

use std::path::Path;
use std::time::Instant;

use super::summary::{rebuild_summary, summary_fault};
use super::{Cancel, Event, Progress, Recording, RunOutcome, open_backend_told, summary_of, write_summary};
use crate::backend::Backend;
use crate::config::{self, Config};
use crate::error::{Error, Remedy, Result, RunFault};
use crate::model::Scene;
use crate::protocol::biaxial::Lab;
use crate::protocol::checkpoint::decode;
use crate::protocol::{Phase, prepare};
use crate::record::{
    ARCHIVED_CONFIG_FILE, MCAP_FILE, RecordHead, Recorder, RunLock, RunRecord, atomic, new_run_id, read_run,
};

/// The files in a run directory that hold a finished test's results.
pub const RESULT_FILES: [&str; 2] = ["summary.json", "summary.txt"];

/// What [`start`] does with an output directory that already holds files.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Existing {
    /// Refuses it ([`RunFault::Occupied`]): a finished test is never lost by mistake.
    #[default]
    Refuse,
    /// Removes the run's files there first (the old results before the old record).
    Replace,
}

/// Runs a new test into `config.output.dir`: takes the directory's lock, refuses a
/// directory that already holds files unless `existing` is [`Existing::Replace`]
/// ([`RunFault::Occupied`]), removes
/// the old results, then runs from a deposition or from a compacted `sample`
/// ([`run_fresh`]). A test stopped by `cancel` returns [`Error::Interrupted`] with the step
/// of the checkpoint its record ends at ([`resume`] continues it).
pub fn start(
    config: &Config,
    sample: Option<Scene>,
    existing: Existing,
    progress: &mut dyn Progress,
    cancel: &Cancel,
) -> Result<RunOutcome> {
    let dir = config.output.dir.clone();
    let _lock = RunLock::acquire(&dir)?;
    check_out_dir(&dir, existing)?;
    // Gone before the new record replaces the old one: a replaced run killed at any point
    // never leaves the old test's results looking like its own.
    clear_results(&dir)?;
    run_fresh(config, &dir, sample, progress, cancel)
}

/// Continues the run recorded in `dir` from its last intact checkpoint, holding the
/// directory's lock, on the backend the record names or on `backend` ([`run_resume`]).
pub fn resume(
    dir: &Path,
    backend: Option<config::Backend>,
    progress: &mut dyn Progress,
    cancel: &Cancel,
) -> Result<RunOutcome> {
    if !dir.is_dir() {
        return Err(Error::Run {
            path: dir.to_path_buf(),
            fault: RunFault::NoRun,
            message: format!("{}: no such run directory", dir.display()),
            remedy: None,
        });
    }
    let _lock = RunLock::acquire(dir)?;
    run_resume(dir, backend, progress, cancel)
}

/// The files a run writes into its directory besides [`RESULT_FILES`]: the record, its CSV
/// copy and the figures.
const OUTPUT_FILES: [&str; 7] = [
    MCAP_FILE,
    crate::record::CSV_FILE,
    ARCHIVED_CONFIG_FILE,
    "stress_strain.png",
    "stress_strain.svg",
    "contacts.png",
    "contacts.svg",
];

/// Refuses an output directory that already holds files, unless `replace`, and one where
/// a file the run would replace exists as something else than a regular file (a link, a
/// FIFO, a device: [`atomic::check_replaceable`]), before anything there is removed.
pub fn check_out_dir(dir: &Path, existing: Existing) -> Result<()> {
    for name in RESULT_FILES.iter().chain(&OUTPUT_FILES) {
        atomic::check_replaceable(&dir.join(name))?;
    }
    if dir.exists() && existing == Existing::Refuse {
        // The lock file of this process (or of an ended run) is not a result.
        let busy = std::fs::read_dir(dir)
            .map_err(|e| Error::io(dir, e))?
            .flatten()
            .any(|e| e.file_name() != crate::record::LOCK_FILE);
        if busy {
            return Err(Error::Run {
                path: dir.to_path_buf(),
                fault: RunFault::Occupied,
                message: format!(
                    "output directory {} already holds files: replace them, resume that run, \
                     or write elsewhere",
                    dir.display()
                ),
                remedy: Some(Remedy::ReplaceResumeOrElsewhere(dir.to_path_buf())),
            });
        }
    }
    Ok(())
}

/// Removes the results of a test from `dir`: `summary.json` first (it is what marks a test
/// finished to `cdlab report` and `cdlab sweep`), then `summary.txt`, the configuration
/// written beside the record and the figures drawn there (`*.png`, `*.svg`), each removal
/// synced. Called before a new record replaces an
/// old one, and before a resume continues an unfinished record (results beside it cannot
/// be its own). The temporary files of killed writes whose process has ended go too
/// ([`atomic::remove_stale_tmps`]).
pub fn clear_results(dir: &Path) -> Result<()> {
    // Left by writes killed before their rename, by any process; never results.
    atomic::remove_stale_tmps(dir, None);
    for name in RESULT_FILES {
        atomic::remove_file(&dir.join(name))?;
    }
    // The run that follows writes its own once its record is in place.
    atomic::remove_file(&dir.join(ARCHIVED_CONFIG_FILE))?;
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

/// Runs a new test into `dir`, from a deposition or from a compacted `sample`, and writes
/// its summary. The caller holds `dir`'s lock and has checked it ([`start`] does both).
pub fn run_fresh(
    config: &Config,
    dir: &Path,
    sample: Option<Scene>,
    progress: &mut dyn Progress,
    cancel: &Cancel,
) -> Result<RunOutcome> {
    let started = Instant::now();
    let params = config.protocol();
    params.validate()?;
    let (scene, compacted) = match sample {
        Some(scene) => (scene, true),
        None => {
            let (scene, report) = prepare::deposit_scene(&params)?;
            progress.event(&Event::Deposited {
                disks: params.disks,
                report: &report,
            });
            (scene, false)
        }
    };
    let backend = open_backend_told(config, scene.clone(), params.step, progress)?;
    let lab = Lab::new(backend, params.clone(), &scene, compacted)?;
    let head = RecordHead {
        run_id: new_run_id(),
        backend: Some(lab.backend.name()),
        earlier_backends: Vec::new(),
    };
    let mut recorder = Recorder::stage(dir, config, &head)?;
    recorder.commit()?;
    write_config(dir, config)?;
    let obs = Recording::new(recorder, params.strain_end, progress, started);
    let summary = finish(config, dir, lab, obs, cancel)?;
    Ok(RunOutcome {
        dir: dir.to_path_buf(),
        summary,
        resumed_from: None,
        summary_only: false,
    })
}

/// Continues the run recorded in `dir` from its last intact checkpoint and writes its
/// summary; the caller holds `dir`'s lock ([`resume`] takes it). A record that is already
/// complete gets its summary written again when the one beside it is missing, empty,
/// damaged or another record's ([`RunOutcome::summary_only`]); with a sound summary it is
/// an error saying the run is complete ([`RunFault::Complete`]).
pub fn run_resume(
    dir: &Path,
    backend: Option<config::Backend>,
    progress: &mut dyn Progress,
    cancel: &Cancel,
) -> Result<RunOutcome> {
    let started = Instant::now();
    let file = dir.join(MCAP_FILE);
    let rec = read_run(dir)?;
    let mut config = rec.config().map_err(|e| Error::Run {
        path: file.clone(),
        fault: RunFault::Damaged,
        message: format!("{}: {e}", file.display()),
        remedy: None,
    })?;
    if let Some(b) = backend {
        config.solver.backend = b;
    }
    let Some((step, bytes)) = rec.last_checkpoint.clone() else {
        let why = rec
            .truncated
            .as_deref()
            .map_or(String::new(), |t| format!(" (the record {t})"));
        return Err(Error::Run {
            path: file.clone(),
            fault: RunFault::NoCheckpoint,
            message: format!(
                "{}: the record holds no intact checkpoint to resume from{why}: the run can \
                 only start again",
                file.display()
            ),
            remedy: Some(Remedy::StartAgain),
        });
    };
    let ck = decode(&bytes).map_err(|e| Error::Run {
        path: file.clone(),
        fault: RunFault::Damaged,
        message: format!("{}: checkpoint: {e}", file.display()),
        remedy: None,
    })?;
    if let Some(why) = &rec.damaged {
        progress.event(&Event::FellBack {
            file: &file,
            why,
            step,
            phase: ck.state.phase,
            strain: strain_at(&rec, step),
        });
    }
    // A complete record read whole needs at most its summary; one cut short or damaged
    // after its final checkpoint is written again whole from it (the lab has no step left
    // to run) with its summary.
    if ck.state.phase == Phase::Done && rec.truncated.is_none() {
        let Some(fault) = summary_fault(dir, &rec) else {
            return Err(Error::Run {
                path: dir.to_path_buf(),
                fault: RunFault::Complete,
                message: format!("{}: this run is already complete", dir.display()),
                remedy: None,
            });
        };
        let old = std::fs::read_to_string(dir.join("summary.json"))
            .ok()
            .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok());
        let summary = rebuild_summary(dir, &rec, old.as_ref())?;
        write_summary(dir, &summary)?;
        progress.event(&Event::SummaryRewritten { dir, fault: &fault });
        return Ok(RunOutcome {
            dir: dir.to_path_buf(),
            summary,
            resumed_from: Some(step),
            summary_only: true,
        });
    }
    let params = ck.state.params.clone();
    let backend = open_backend_told(&config, ck.scene.clone(), params.step, progress)?;
    let time = ck.scene.time;
    let lab = Lab::resume(backend, ck)?;
    let head = RecordHead::resumed(&rec, lab.backend.name());
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
    write_config(dir, &config)?;
    obs.event(&Event::Resuming {
        dir,
        step,
        time_s: time,
        phase: lab.state.phase,
    });
    let summary = finish(&config, dir, lab, obs, cancel)?;
    Ok(RunOutcome {
        dir: dir.to_path_buf(),
        summary,
        resumed_from: Some(step),
        summary_only: false,
    })
}

/// Writes the run's configuration beside its record ([`ARCHIVED_CONFIG_FILE`], TOML),
/// whole ([`atomic::write_file`]): what was run, readable without cdlab. The record holds
/// the same configuration, and that copy is the one cdlab reads.
fn write_config(dir: &Path, config: &Config) -> Result<()> {
    let text = format!(
        "# The configuration of the run recorded in {MCAP_FILE} beside this file (cdlab {}).\n\
         # `cdlab config --of {}` prints it from the record.\n{}",
        env!("CARGO_PKG_VERSION"),
        dir.display(),
        config.to_toml_string()?
    );
    atomic::write_file(&dir.join(ARCHIVED_CONFIG_FILE), text.as_bytes())
}

/// The axial strain of the last row at or before `step`, when that row is in the
/// compression.
fn strain_at(rec: &RunRecord, step: u64) -> Option<f64> {
    rec.series
        .iter()
        .rfind(|r| r.step <= step)
        .filter(|r| r.phase == "compression")
        .map(|r| r.strain_axial)
}

/// Runs the lab to its end, closes the record and writes the summary.
fn finish(
    config: &Config,
    dir: &Path,
    mut lab: Lab<Box<dyn Backend>>,
    mut obs: Recording<'_>,
    cancel: &Cancel,
) -> Result<crate::measure::summary::Summary> {
    let backend = lab.backend.name();
    obs.event(&Event::Running {
        backend: &backend,
        dir,
    });
    let outcome = lab.run_until(&mut obs, cancel);
    obs.event(&Event::StepsEnded);
    if let Err(e @ Error::Interrupted { .. }) = outcome {
        // The record ends at the checkpoint just written: close it properly for the resume.
        obs.recorder.finish()?;
        return Err(e);
    }
    outcome?;
    let wall_s = obs.wall_s();
    obs.recorder.finish()?;
    // From the record just closed: the snapshots are not kept in memory during the run. A
    // summary made without it would lack its record_id and shear bands yet mark the test
    // finished, so a failed read fails the run, leaving the summary to the resume.
    let record = read_run(dir).map_err(|e| unreadable_at_end(dir, &e))?;
    let summary = summary_of(
        config,
        &obs.rows,
        &obs.ends,
        lab.state.derived.as_ref(),
        backend,
        wall_s,
        &Ok(record),
        &mut *obs.progress,
    );
    write_summary(dir, &summary)?;
    Ok(summary)
}

/// The error of a run whose steps are all recorded but whose record cannot be read back
/// for its summary: it names the record and says how to write the summary.
fn unreadable_at_end(dir: &Path, e: &Error) -> Error {
    let file = dir.join(MCAP_FILE);
    Error::Run {
        message: format!(
            "{}: the run is complete but its record could not be read back for the summary \
             ({e}); no summary was written: resuming the run writes it",
            file.display()
        ),
        path: file,
        fault: RunFault::Unfinished,
        remedy: Some(Remedy::Resume(dir.to_path_buf())),
    }
}
