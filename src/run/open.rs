//! A finished (or stopped) run or an archived test read back, and its figures.

use std::path::{Path, PathBuf};

use crate::config::Config;
use crate::error::{Error, Result};
use crate::figures::{self, ContactsFigure, StressStrainFigure};
use crate::measure::SeriesRow;
use crate::measure::summary::Summary;
use crate::record::{LAST_SNAPSHOT_FILE, MCAP_FILE, RunRecord, Snapshot, is_archived, read_run, read_series};

use super::summary::SUMMARY_FILE;

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

/// Which of the two kinds of test directory an [`OpenedTest`] was read from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TestKind {
    /// A run directory (or its `run.mcap`): everything comes from the record.
    Run,
    /// A directory written by `cdlab archive`: configuration, summary, thinned series and,
    /// when it was kept, the last snapshot.
    Archived,
}

/// A run or an archived test read whole by [`open_test`]: what the Python package's
/// `cdlab.open` shows.
#[derive(Clone, Debug)]
pub struct OpenedTest {
    /// Run or archived test.
    pub kind: TestKind,
    /// The run directory (also when the record file itself was given) or archived test.
    pub path: PathBuf,
    /// The configuration: the record's, or the archived `config.toml` (checksum checked).
    pub config: Config,
    /// `summary.json`, checked to be a cdlab summary (with its checksum) and, for a run, the
    /// summary of this record; `None` while the test is not finished.
    pub summary: Option<Summary>,
    /// The text of `summary.json` that [`OpenedTest::summary`] was read from, as written: a
    /// caller that hands the summary on (the Python package, as a dict) keeps its keys and
    /// their order, those of other cdlab versions included.
    pub summary_text: Option<String>,
    /// The series rows: the whole record's, or an archived test's thinned series.
    pub series: Vec<SeriesRow>,
    /// The snapshots in record order (an archived test: its kept last one, if any).
    pub snapshots: Vec<Snapshot>,
    /// Why the record ends early (a run killed while it wrote); `None` when complete, and
    /// for an archived test.
    pub truncated: Option<String>,
    /// Why the record failed a check; only ever set when opened with `allow_damaged`.
    pub damaged: Option<String>,
    /// The record's identity (the summary's `record_id`); `None` for an archived test.
    pub run_id: Option<String>,
    /// The cdlab version that wrote the record; `None` for an archived test.
    pub version: Option<String>,
    /// The backend that wrote the record's last part, when the record says.
    pub backend: Option<String>,
}

/// A run's record with what [`open`] and [`open_test`] check beside it.
struct CheckedRun {
    dir: PathBuf,
    config: Config,
    summary: Option<(Summary, String)>,
    record: RunRecord,
}

/// An error of the file `path` itself (unreadable content): a caller shows
/// "PATH: WHY", and the Python package raises `FileError` with the path.
fn file_fault(path: &Path, why: impl std::fmt::Display) -> Error {
    Error::io(
        path,
        std::io::Error::new(std::io::ErrorKind::InvalidData, why.to_string()),
    )
}

/// The summary of the test in `dir` with its text, checked: it parses as a [`Summary`]
/// (whose checksum is checked as it is read) and, when both carry an identity, it is the
/// summary of the record `run_id` (one left from a record since replaced is stale).
/// `None` when there is none yet (a run not finished).
fn checked_summary(dir: &Path, run_id: Option<&str>) -> Result<Option<(Summary, String)>> {
    let file = dir.join(SUMMARY_FILE);
    if !file.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&file).map_err(|e| Error::io(&file, e))?;
    let summary: Summary = serde_json::from_str(&text).map_err(|e| file_fault(&file, e))?;
    if let (Some(ours), Some(theirs)) = (run_id, summary.record_id.as_deref())
        && ours != theirs
    {
        return Err(file_fault(
            &file,
            format!(
                "the summary of record {theirs}, not of this directory's {MCAP_FILE} \
                 (record {ours}): stale; `cdlab summarize {}` writes it again",
                dir.display()
            ),
        ));
    }
    Ok(Some((summary, text)))
}

/// Reads the run at `path` (a run directory or its record file) with its configuration
/// and checked summary: the one implementation behind [`open`] and [`open_test`].
fn open_run(path: &Path, allow_damaged: bool) -> Result<CheckedRun> {
    let record = read_run(path)?;
    let file = if path.is_dir() {
        path.join(MCAP_FILE)
    } else {
        path.to_path_buf()
    };
    let dir = file.parent().unwrap_or(Path::new(".")).to_path_buf();
    if let (Some(why), false) = (&record.damaged, allow_damaged) {
        return Err(Error::DamagedRecord {
            file,
            reason: why.clone(),
        });
    }
    let config = record.config().map_err(|e| file_fault(&file, e))?;
    let summary = checked_summary(&dir, record.run_id.as_deref())?;
    Ok(CheckedRun {
        dir: if path.is_dir() { path.to_path_buf() } else { dir },
        config,
        summary,
        record,
    })
}

/// Reads the run in `dir`: its record (checked as [`read_run`] checks it; one damaged is
/// read up to the damage, [`RunRecord::damaged`] saying why), the configuration in it,
/// and its `summary.json` when there is one, checked as [`open_test`] checks it: a
/// summary that is damaged, not a cdlab summary, or another record's is an error naming
/// the file, never returned as this run's.
pub fn open(dir: &Path) -> Result<FinishedRun> {
    let run = open_run(dir, true)?;
    Ok(FinishedRun {
        dir: run.dir,
        config: run.config,
        summary: run.summary.map(|(s, _)| s),
        record: run.record,
    })
}

/// Opens the run directory (or its `run.mcap`) or the archived test (`cdlab archive`) at
/// `path`, whole: configuration, checked summary, series and snapshots (what the Python
/// package's `cdlab.open` reads a test with). A run is read as [`open`] reads it.
///
/// A record is read with its checks (chunk and checkpoint CRCs). One that failed a check
/// is refused ([`Error::DamagedRecord`], with its file and reason) unless `allow_damaged`, when what precedes the damage is kept and
/// [`OpenedTest::damaged`] says why. A record cut short (a run killed mid-write, not a
/// failed check) opens, [`OpenedTest::truncated`] saying where it ends.
///
/// Errors name the file at fault: a missing path, a summary that does not parse, fails its
/// checksum or belongs to another record, a record configuration that does not parse and
/// an archived snapshot that does not decode are [`Error::Io`] of that file; a record that
/// is no cdlab record is [`Error::BadRecord`]; an archived configuration out of range or
/// not parsing is [`Error::Invalid`] or [`Error::Parse`] naming it.
pub fn open_test(path: &Path, allow_damaged: bool) -> Result<OpenedTest> {
    if !path.exists() {
        return Err(Error::io(
            path,
            std::io::Error::new(std::io::ErrorKind::NotFound, "no such file or directory"),
        ));
    }
    if is_archived(path) {
        let (series, config) = read_series(path)?;
        let config = config?;
        let kept = path.join(LAST_SNAPSHOT_FILE);
        let snapshots = if kept.exists() {
            let bytes = std::fs::read(&kept).map_err(|e| Error::io(&kept, e))?;
            vec![Snapshot::decode(&bytes).map_err(|e| file_fault(&kept, e))?]
        } else {
            Vec::new()
        };
        let summary = checked_summary(path, None)?;
        let (summary, summary_text) = summary.unzip();
        return Ok(OpenedTest {
            kind: TestKind::Archived,
            path: path.to_path_buf(),
            config,
            summary,
            summary_text,
            series,
            snapshots,
            truncated: None,
            damaged: None,
            run_id: None,
            version: None,
            backend: None,
        });
    }
    let CheckedRun {
        dir,
        config,
        summary,
        record,
    } = open_run(path, allow_damaged)?;
    let (summary, summary_text) = summary.unzip();
    Ok(OpenedTest {
        kind: TestKind::Run,
        path: dir,
        config,
        summary,
        summary_text,
        series: record.series,
        snapshots: record.snapshots,
        truncated: record.truncated,
        damaged: record.damaged,
        run_id: record.run_id,
        version: Some(record.version),
        backend: record.backend,
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The test directory shipped in `assets/results` (5000 disks, archived).
    fn shipped() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/results/campaign5000/seed1_mu0.3_s8MPa")
    }

    /// The shipped archived test opens as one: its configuration, its summary with the
    /// file's text, its thinned series, and nothing of a record.
    #[test]
    fn an_archived_test_opens_with_its_summary_and_series() {
        let t = open_test(&shipped(), false).unwrap();
        assert_eq!(t.kind, TestKind::Archived);
        assert_eq!(t.config.test.mu, 0.3);
        let summary = t.summary.expect("the archive's summary");
        assert_eq!(summary.mu, 0.3);
        let text = std::fs::read_to_string(shipped().join(SUMMARY_FILE)).unwrap();
        assert_eq!(t.summary_text.as_deref(), Some(text.as_str()));
        assert!(t.series.len() > 100, "{} rows", t.series.len());
        assert!(t.run_id.is_none() && t.version.is_none() && t.damaged.is_none());
        // The run reader refuses it: it holds no record.
        assert!(matches!(open(&shipped()), Err(Error::Archived { .. })));
    }

    /// A missing path and a summary that does not parse are errors of that file (the
    /// Python package's `FileError` with its path).
    #[test]
    fn errors_name_the_file_at_fault() {
        let missing = shipped().join("nothing here");
        match open_test(&missing, false) {
            Err(Error::Io { path, .. }) => assert_eq!(path, missing),
            other => panic!("{other:?}"),
        }
        let dir = std::env::temp_dir().join(format!("cdlab-open-test-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        for f in ["config.toml", "series_thinned.csv"] {
            std::fs::copy(shipped().join(f), dir.join(f)).unwrap();
        }
        std::fs::write(dir.join(SUMMARY_FILE), "{\"version\": ").unwrap();
        let e = open_test(&dir, false).unwrap_err();
        let _ = std::fs::remove_dir_all(&dir);
        let file = dir.join(SUMMARY_FILE);
        assert!(matches!(&e, Error::Io { path, .. } if *path == file), "{e:?}");
        assert!(e.to_string().starts_with(&file.display().to_string()), "{e}");
    }

    /// The refusal of a damaged record names its file and reason apart, and the way out
    /// as a remedy: resume the run in the record's directory.
    #[test]
    fn a_refused_damaged_record_names_its_file_reason_and_remedy() {
        let file = PathBuf::from("/runs/a: b/run.mcap");
        let why = "damaged after 3 intact messages: chunk CRC: `x`: y";
        let e = Error::DamagedRecord {
            file: file.clone(),
            reason: why.into(),
        };
        assert_eq!(
            e.to_string(),
            format!(
                "{}: {why}: resuming the run recomputes it from its last intact checkpoint",
                file.display()
            )
        );
        assert_eq!(
            e.remedy(),
            Some(crate::error::Remedy::Resume("/runs/a: b".into()))
        );
    }
}
