//! A finished test's summary: derived from its rows, phase ends and snapshots, written
//! beside its record, checked, and computed again from the record.

use std::path::Path;

use super::{Event, Progress};
use crate::config::Config;
use crate::error::{Error, Remedy, Result, RunFault};
use crate::measure::SeriesRow;
use crate::measure::derived::DerivedCurve;
use crate::measure::summary::{DerivedFrom, Summary};
use crate::protocol::biaxial::QUASI_STATIC_CHECK_EVERY;
use crate::protocol::checkpoint::decode;
use crate::protocol::{Phase, PhaseEnd};
use crate::record::{MCAP_FILE, RunLock, RunRecord, atomic, read_run};

/// The summary of a finished test from its rows and phase ends, with the shear bands of
/// its record's snapshots: the same at the end of a run and in [`summarize`]. A band
/// analysis that cannot be made is reported to `progress` ([`Event::NoShearBands`]).
#[allow(clippy::too_many_arguments)]
pub fn summary_of(
    config: &Config,
    rows: &[SeriesRow],
    ends: &[PhaseEnd],
    derived: Option<&DerivedCurve>,
    backend: String,
    wall_s: f64,
    record: &Result<RunRecord>,
    progress: &mut dyn Progress,
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
    summary = match derived {
        Some(curve) if curve.points > 0 => summary.with_derived(curve, QUASI_STATIC_CHECK_EVERY.into(), rows),
        _ => Summary {
            derived_from: Some(DerivedFrom {
                source: "rows".into(),
                every_steps: config.output.series_every,
            }),
            ..summary
        },
    };
    summary.dt_s = Some(config.solver.dt.si());
    summary.seed = Some(config.sample.seed);
    summary.strain_end = Some(config.test.strain_end);
    if let Ok(rec) = record
        && rec.backends.len() > 1
    {
        summary.backends = rec.backends.clone();
    }
    summary.deep_contacts = crate::measure::summary::DeepContacts::of_run(
        config.solver.deep_overlap_rel(),
        config.solver.deep_sweeps,
        rows,
    );
    summary.record_id = record.as_ref().ok().and_then(|r| r.run_id.clone());
    let bands = record
        .as_ref()
        .map(|rec| crate::analysis::bands::analyse_run(rec, None, None, &Default::default()));
    summary.shear_bands = match bands {
        Ok(Ok(b)) => Some(b),
        Ok(Err(e)) => {
            progress.event(&Event::NoShearBands(&e));
            None
        }
        Err(e) => {
            progress.event(&Event::NoShearBands(e));
            None
        }
    };
    summary
}

/// Writes `summary.txt` and then `summary.json` into `dir`, each to a temporary name,
/// synced and renamed into place ([`atomic::write_file`]): `summary.json` marks the test
/// finished, so it comes last and is never seen half-written.
/// `summary.json` carries the checksum of its content ([`Summary::to_json`]).
pub fn write_summary(dir: &Path, summary: &Summary) -> Result<()> {
    let json = summary.to_json().map_err(|e| unwritable(dir, e))?;
    atomic::write_file(&dir.join("summary.txt"), summary.table().as_bytes())?;
    atomic::write_file(&dir.join(SUMMARY_FILE), json.as_bytes())
}

/// The file that holds a finished test's summary, and marks it finished.
pub const SUMMARY_FILE: &str = "summary.json";

/// Why the summary JSON `value` cannot stand as the summary of the record `run_id` (when
/// known), if it cannot: its checksum does not match its content, or it names another
/// record (a stale summary of an earlier run of the directory).
fn value_fault(value: &serde_json::Value, run_id: Option<&str>) -> Option<String> {
    if let Err(why) = crate::measure::summary::verify_checksum(value) {
        return Some(format!("is damaged: {why}"));
    }
    match (value.get("record_id").and_then(|v| v.as_str()), run_id) {
        (Some(theirs), Some(ours)) if theirs != ours => Some(format!(
            "belongs to another record (record_id {theirs}) than the {MCAP_FILE} beside it \
             (run_id {ours}): a stale summary of an earlier run"
        )),
        _ => None,
    }
}

/// Reads the `summary.json` of the test in `dir` and checks that it stands: it parses, its
/// checksum matches its content, and it names the record beside it, if there is one (an
/// archived test has none, and its `config.toml` must pass its own checksum). The one check of a finished test that `cdlab report`, `cdlab
/// sweep` and `cdlab archive` share, so that none takes as finished a test another
/// refuses. The error ([`RunFault::Damaged`]) names the file and says how to repair it.
pub fn read_checked_summary(dir: &Path) -> Result<serde_json::Value> {
    let path = dir.join(SUMMARY_FILE);
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    let damaged = |why: String| {
        let (repair, remedy) = if dir.join(MCAP_FILE).is_file() {
            (
                "; it can be written again from the record once that run is complete",
                Some(Remedy::Summarize(dir.to_path_buf())),
            )
        } else {
            ("", None)
        };
        Error::Run {
            path: path.clone(),
            fault: RunFault::Damaged,
            message: format!("{} {why}{repair}", path.display()),
            remedy,
        }
    };
    let value: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| damaged(format!("is damaged ({e})")))?;
    // A record whose head cannot be read is judged where it is read whole.
    let run_id = if dir.join(MCAP_FILE).is_file() {
        crate::record::read_run_id(dir).ok().flatten()
    } else {
        None
    };
    if let Some(why) = value_fault(&value, run_id.as_deref()) {
        return Err(damaged(why));
    }
    // An archived test is its summary and its configuration: a damaged configuration
    // (checked by its checksum) is a damaged test, though its summary stands. Before, the
    // sweep compared its settings with a configuration changed on disk (150 disks read as
    // 250) and skipped it as finished, and the report counted it.
    if crate::record::is_archived(dir) {
        crate::record::read_config(dir)?;
    }
    Ok(value)
}

/// A summary that cannot be put into JSON: the error of writing `dir`'s `summary.json`.
fn unwritable(dir: &Path, e: serde_json::Error) -> Error {
    Error::io(dir.join("summary.json"), std::io::Error::other(e))
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
    if let Some(why) = value_fault(&value, rec.run_id.as_deref()) {
        return Some(why);
    }
    if serde_json::from_value::<Summary>(value).is_err() {
        return Some("is not a cdlab summary".into());
    }
    None
}

/// An [`Error::Run`] about the record file `file`.
fn record_fault(file: &Path, fault: RunFault, what: impl std::fmt::Display, remedy: Option<Remedy>) -> Error {
    Error::Run {
        path: file.to_path_buf(),
        fault,
        message: format!("{}: {what}", file.display()),
        remedy,
    }
}

/// The summary of the complete record `rec` of `dir`, computed again from it. What the
/// record does not hold is taken from `old` (a former summary) when given: the backend's
/// name and the wall time; otherwise the record's backend and its last row's wall time.
pub fn rebuild_summary(dir: &Path, rec: &RunRecord, old: Option<&serde_json::Value>) -> Result<Summary> {
    let name = dir.join(MCAP_FILE);
    let named = |e: Error| record_fault(&name, RunFault::Damaged, e, None);
    let config = rec.config().map_err(named)?;
    let Some((_, bytes)) = &rec.last_checkpoint else {
        return Err(record_fault(
            &name,
            RunFault::NoCheckpoint,
            "the record holds no intact checkpoint",
            Some(Remedy::StartAgain),
        ));
    };
    // The phase ends are in the checkpoint the run wrote as it finished.
    let state = decode(bytes).map_err(named)?.state;
    if state.phase != Phase::Done {
        return Err(record_fault(
            &name,
            RunFault::Unfinished,
            format!(
                "the record ends in phase {} (resume it first)",
                state.phase.name()
            ),
            Some(Remedy::Resume(dir.to_path_buf())),
        ));
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
        state.derived.as_ref(),
        backend,
        wall_s,
        &record,
        &mut super::Silent,
    ))
}

/// What [`summarize`] did with one test.
#[derive(Debug, PartialEq)]
pub enum Summarized {
    /// The summary was written again (or would be, in a dry run); the top-level keys
    /// whose values changed.
    Rewritten(Vec<String>),
    /// The recomputed summary equals the one there (nothing written).
    Unchanged,
}

/// Computes the summary of the finished test in `dir` from its record and writes it (unless
/// `dry_run`) when it differs from the one there. A missing, empty or damaged summary, or
/// one of another record, is rebuilt from the record. A test without its record (an
/// archived one) or not finished is an error naming why.
///
/// Unless `dry_run`, it holds the directory's lock ([`RunLock`]) from the read of the record
/// to the write: a run started meanwhile (`biaxial --force`, a sweep) replaces the record,
/// and a summary computed from the old one would then mark the new run finished. A
/// directory whose lock another process holds is an error ([`Error::InUse`]).
pub fn summarize(dir: &Path, dry_run: bool) -> Result<Summarized> {
    if !dir.join(MCAP_FILE).exists() {
        return Err(Error::Run {
            path: dir.to_path_buf(),
            fault: RunFault::NoRun,
            message: format!(
                "no record ({MCAP_FILE}): an archived test keeps the summary it was archived with"
            ),
            remedy: None,
        });
    }
    let _lock = if dry_run {
        None
    } else {
        Some(RunLock::acquire(dir)?)
    };
    let record = read_run(dir)?;
    if let Some(why) = &record.damaged {
        let file = dir.join(MCAP_FILE);
        return Err(record_fault(
            &file,
            RunFault::Damaged,
            format!("{why}: resuming the run recomputes it from its last intact checkpoint"),
            Some(Remedy::Resume(dir.to_path_buf())),
        ));
    }
    let fault = summary_fault(dir, &record);
    let old = match &fault {
        None => {
            let old_path = dir.join("summary.json");
            let text = std::fs::read_to_string(&old_path).map_err(|e| Error::io(&old_path, e))?;
            Some(
                serde_json::from_str::<serde_json::Value>(&text)
                    .map_err(|e| record_fault(&old_path, RunFault::Damaged, e, None))?,
            )
        }
        // The figures of another record's summary are not this one's.
        Some(_) => None,
    };
    let summary = rebuild_summary(dir, &record, old.as_ref())?;
    let new = serde_json::to_value(&summary).map_err(|e| unwritable(dir, e))?;
    let changed = match (&old, &fault) {
        // The checksum follows the content: no change of its own (and a summary written
        // before summaries had one gets it only when rewritten for another reason).
        (Some(old), None) => {
            let mut old = old.clone();
            if let Some(o) = old.as_object_mut() {
                o.remove(crate::measure::summary::CHECKSUM_KEY);
            }
            changed_keys(&old, &new)
        }
        _ => vec![format!("all (summary.json {})", fault.unwrap_or_default())],
    };
    // Which version wrote it is no change of the test's figures.
    if changed.iter().all(|k| k == "version") {
        return Ok(Summarized::Unchanged);
    }
    if !dry_run {
        write_summary(dir, &summary)?;
    }
    Ok(Summarized::Rewritten(changed))
}

/// The top-level keys of `new` whose values differ in `old` (or that `old` lacks), and the
/// keys `old` has that `new` lacks.
fn changed_keys(old: &serde_json::Value, new: &serde_json::Value) -> Vec<String> {
    let empty = serde_json::Map::new();
    let (o, n) = (
        old.as_object().unwrap_or(&empty),
        new.as_object().unwrap_or(&empty),
    );
    let mut keys: Vec<String> = n
        .iter()
        .filter(|(k, v)| o.get(*k) != Some(v))
        .map(|(k, _)| k.clone())
        .collect();
    keys.extend(o.keys().filter(|k| !n.contains_key(*k)).cloned());
    keys
}
