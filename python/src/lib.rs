//! `cdlab._cdlab`: the compiled half of the `cdlab` Python package (python/cdlab/ is the
//! other half, which turns what this module hands out into dicts, NumPy arrays and pandas
//! DataFrames).
//!
//! Everything here goes through the cdlab library's own readers: a run or an archived test
//! with its checked summary ([`cdlab::run::open_test`], the record read with its chunk and
//! checkpoint CRCs), the series as typed columns ([`cdlab::record::series_column`]), the
//! micromechanical analysis of a snapshot ([`cdlab::measure::micro`]) and the campaign report
//! ([`cdlab::analysis::report`]). Nothing of the MCAP layout is parsed in Python.
//!
//! Arrays cross the boundary as little-endian bytes that the Python half wraps with
//! `numpy.frombuffer`: no copy per element through Python objects, and no dependency on a
//! NumPy crate whose version would have to follow PyO3's.

mod run;

use std::path::{Path, PathBuf};

use cdlab::Error;
use cdlab::error::Remedy;
use cdlab::record::{SERIES_FIELDS, SeriesColumn, Snapshot, series_column};
use cdlab::run::{OpenedTest, TestKind, open_test};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};

/// The library's allocator: large samples' steps walk tens of megabytes, and huge pages make
/// them faster where the kernel gives them only on request (src/hugepages.rs). It fixes the
/// C allocator's threshold for mapping large blocks at 4 MiB for the whole process.
#[global_allocator]
static ALLOCATOR: cdlab::hugepages::HugePages = cdlab::hugepages::HugePages;

create_exception!(
    cdlab,
    CdlabError,
    PyException,
    "Base class of every error cdlab raises; `str(e)` names the field or file at fault."
);
create_exception!(
    cdlab,
    InvalidParameterError,
    CdlabError,
    "A parameter outside its allowed range; attributes `field`, `value`, `allowed`."
);
create_exception!(
    cdlab,
    ParseError,
    CdlabError,
    "A file that cannot be parsed; attributes `path` and `line` (1-based, 0 when unknown)."
);
create_exception!(
    cdlab,
    NumericalError,
    CdlabError,
    "A time step that produced a non-finite value or too large an overlap; attribute `step`."
);
create_exception!(cdlab, GpuError, CdlabError, "A GPU adapter or device failure.");
create_exception!(
    cdlab,
    NoAdapterError,
    GpuError,
    "No GPU adapter on this machine (a GpuError that a caller may treat as 'skip')."
);
create_exception!(
    cdlab,
    FileError,
    CdlabError,
    "A file or directory that cannot be read or is not what it should be; attribute `path`."
);
create_exception!(
    cdlab,
    DamagedRecordError,
    FileError,
    "A run record (run.mcap) whose content failed a check; attribute `path`, and `reason`."
);
create_exception!(
    cdlab,
    StoppedError,
    CdlabError,
    "A run stopped by a signal; attributes `signal` and `step` (0 when nothing to resume)."
);

create_exception!(
    cdlab,
    RunError,
    CdlabError,
    "A run directory or file that cannot be used as asked; attributes `path` and `fault` \
     (NoRun, Occupied, NoCheckpoint, Complete, Unfinished, OtherSettings, Damaged)."
);
create_exception!(
    cdlab,
    CampaignError,
    CdlabError,
    "A campaign that cannot run as asked (sweep file, grid, failed tests); attribute `path`."
);

/// What to do about an error ([`Error::remedy`]) in a Python user's terms: the package's
/// calls and arguments where the command line names its flags.
pub fn python_hint(remedy: &Remedy) -> String {
    match remedy {
        Remedy::Resume(dir) => format!("cdlab.resume({:?})", dir.display().to_string()),
        Remedy::StartAgain => "start the run again with force=True".into(),
        Remedy::ReplaceResumeOrElsewhere(dir) => format!(
            "pass force=True to replace them, call cdlab.resume({:?}) to continue that run, or \
             give another out directory",
            dir.display().to_string()
        ),
        Remedy::PrepareAgain(file) => format!(
            "cdlab.prepare(config, out={:?}) with its settings",
            file.display().to_string()
        ),
        Remedy::Summarize(dir) => format!(
            "`cdlab summarize {}` on the command line writes it again",
            dir.display()
        ),
        Remedy::UseCpu => "run again with backend=\"cpu\", or continue a stopped run with \
             cdlab.resume(path, backend=\"cpu\")"
            .into(),
        Remedy::UseThinnedSeries(_) => "cdlab.open reads its thinned series and summary".into(),
        // The remedies are non-exhaustive: one added later is said by the message alone.
        _ => String::new(),
    }
}

/// An error's message with its remedy in the package's terms ([`python_hint`]).
pub fn in_python_terms(e: &Error) -> String {
    match e.remedy().map(|r| python_hint(&r)) {
        Some(hint) if !hint.is_empty() => format!("{e} ({hint})"),
        _ => e.to_string(),
    }
}

/// A cdlab error as the matching Python exception, its fields set as attributes; its
/// message with its remedy in the package's terms ([`in_python_terms`]).
fn py_err(py: Python<'_>, e: Error) -> PyErr {
    let msg = in_python_terms(&e);
    let (err, attrs): (PyErr, Vec<(&str, Py<PyAny>)>) = match e {
        Error::Invalid {
            field,
            value,
            allowed,
        } => (
            InvalidParameterError::new_err(msg),
            vec![
                ("field", field.into_pyobject(py).unwrap().into_any().unbind()),
                ("value", value.into_pyobject(py).unwrap().into_any().unbind()),
                ("allowed", allowed.into_pyobject(py).unwrap().into_any().unbind()),
            ],
        ),
        Error::Parse { path, line, .. } => (
            ParseError::new_err(msg),
            vec![
                ("path", path_obj(py, &path)),
                ("line", line.into_pyobject(py).unwrap().into_any().unbind()),
            ],
        ),
        Error::Numerical { step, .. } => (
            NumericalError::new_err(msg),
            vec![("step", step.into_pyobject(py).unwrap().into_any().unbind())],
        ),
        Error::Gpu(cdlab::error::GpuError::NoAdapter(_)) => (NoAdapterError::new_err(msg), vec![]),
        Error::Gpu(_) => (GpuError::new_err(msg), vec![]),
        Error::Io { path, .. } => (FileError::new_err(msg), vec![("path", path_obj(py, &path))]),
        Error::Interrupted { signal, step } => (
            StoppedError::new_err(msg),
            vec![
                ("signal", signal.into_pyobject(py).unwrap().into_any().unbind()),
                ("step", step.into_pyobject(py).unwrap().into_any().unbind()),
            ],
        ),
        Error::NotAFile { path } | Error::BadSample { path, .. } => {
            (FileError::new_err(msg), vec![("path", path_obj(py, &path))])
        }
        Error::InUse { dir, .. } | Error::Archived { dir, .. } => {
            (FileError::new_err(msg), vec![("path", path_obj(py, &dir))])
        }
        Error::DamagedRecord { file, reason } => (
            DamagedRecordError::new_err(format!(
                "{msg} (open(..., allow_damaged=True) reads what precedes the damage)"
            )),
            vec![("path", path_obj(py, &file)), ("reason", text_obj(py, reason))],
        ),
        Error::BadRecord { path, .. } => {
            let path = match path {
                Some(p) => path_obj(py, &p),
                None => py.None(),
            };
            (DamagedRecordError::new_err(msg), vec![("path", path)])
        }
        Error::Run { path, fault, .. } => (
            RunError::new_err(msg),
            vec![
                ("path", path_obj(py, &path)),
                ("fault", text_obj(py, format!("{fault:?}"))),
            ],
        ),
        Error::Campaign { path, .. } => (CampaignError::new_err(msg), vec![("path", path_obj(py, &path))]),
        // A snapshot that cannot be analysed: the base class, with the attributes a caller
        // needs to pick another snapshot (`fault`: NoSnapshot, NoSeriesRow, NoArea, NoForce,
        // NoEarlier).
        Error::Snapshot { path, fault, .. } => (
            CdlabError::new_err(msg),
            vec![
                ("path", path_obj(py, &path)),
                ("fault", text_obj(py, format!("{fault:?}"))),
            ],
        ),
        Error::BadCheckpoint { .. }
        | Error::NothingToDraw(_)
        | Error::Drawing(_)
        | Error::BandAnalysis(_)
        | Error::Other(_) => (CdlabError::new_err(msg), vec![]),
        // The library's errors are non-exhaustive: a kind added later is still a CdlabError.
        _ => (CdlabError::new_err(msg), vec![]),
    };
    set_attrs(py, err, attrs)
}

/// Sets `attrs` on the exception instance of `err` (exceptions have a `__dict__`).
fn set_attrs(py: Python<'_>, err: PyErr, attrs: Vec<(&str, Py<PyAny>)>) -> PyErr {
    let value = err.value(py);
    for (k, v) in attrs {
        if let Err(e) = value.setattr(k, v) {
            return e;
        }
    }
    err
}

/// A path as a Python `str` (what `os.fspath` gives; the Python half may wrap it).
fn path_obj(py: Python<'_>, p: &Path) -> Py<PyAny> {
    text_obj(py, p.display().to_string())
}

/// A Python `str` (converting a Rust string cannot fail).
fn text_obj(py: Python<'_>, s: String) -> Py<PyAny> {
    s.into_pyobject(py).unwrap().into_any().unbind()
}

/// A [`FileError`] naming `path`.
fn file_error(py: Python<'_>, path: &Path, msg: String) -> PyErr {
    set_attrs(py, FileError::new_err(msg), vec![("path", path_obj(py, path))])
}

/// A run or an archived test, read whole by the library ([`cdlab::run::open_test`]: the
/// snapshots are decoded; arrays and the micromechanical analysis of a snapshot are built
/// when asked for).
#[pyclass(frozen, module = "cdlab._cdlab")]
struct Record {
    test: OpenedTest,
    /// The configuration as JSON, written once at opening (`Test.config` parses it once).
    config_json: String,
}

/// Opens the run directory (or its `run.mcap`) or the archived test at `path`
/// ([`cdlab::run::open_test`], without the GIL). A record that failed a check raises
/// [`DamagedRecordError`] naming the file, with the `reason` apart, unless
/// `allow_damaged`, when what precedes the damage is kept and `damaged` says why. A record
/// cut short (a run killed mid-write, not a failed check) opens, `truncated` saying where it
/// ends. Every other error is the library's, as [`py_err`] raises it.
#[pyfunction]
#[pyo3(signature = (path, allow_damaged = false))]
fn open_record(py: Python<'_>, path: PathBuf, allow_damaged: bool) -> PyResult<Record> {
    let opened = py.detach(|| {
        let test = open_test(&path, allow_damaged)?;
        let config_json =
            serde_json::to_string(&test.config).map_err(|e| Error::Other(format!("configuration: {e}")))?;
        Ok(Record { test, config_json })
    });
    opened.map_err(|e| py_err(py, e))
}

/// One field of a snapshot's disk.
type DiskField = fn(&cdlab::record::DiskRecord) -> f64;

/// Little-endian bytes of `values`.
fn le_f64(values: impl Iterator<Item = f64>) -> Vec<u8> {
    values.flat_map(f64::to_le_bytes).collect()
}

/// Little-endian bytes of `values`.
fn le_u64(values: impl Iterator<Item = u64>) -> Vec<u8> {
    values.flat_map(u64::to_le_bytes).collect()
}

/// Little-endian bytes of `values`.
fn le_u32(values: impl Iterator<Item = u32>) -> Vec<u8> {
    values.flat_map(u32::to_le_bytes).collect()
}

impl Record {
    fn snapshot(&self, index: usize) -> PyResult<&Snapshot> {
        self.test.snapshots.get(index).ok_or_else(|| {
            pyo3::exceptions::PyIndexError::new_err(format!(
                "snapshot {index} of {} in {}",
                self.test.snapshots.len(),
                self.test.path.display()
            ))
        })
    }
}

#[pymethods]
impl Record {
    /// The run directory or archived test read.
    #[getter]
    fn path(&self) -> String {
        self.test.path.display().to_string()
    }

    /// "run" (a record) or "archived" (a directory of `cdlab archive`).
    #[getter]
    fn kind(&self) -> &'static str {
        match self.test.kind {
            TestKind::Run => "run",
            TestKind::Archived => "archived",
        }
    }

    /// The configuration as JSON (SI units, the keys of the TOML file).
    #[getter]
    fn config_json(&self) -> &str {
        &self.config_json
    }

    /// `summary.json`'s text, checked; None when the test has none (not finished).
    #[getter]
    fn summary_json(&self) -> Option<&str> {
        self.test.summary_text.as_deref()
    }

    /// Why the record ends early (None for a complete file).
    #[getter]
    fn truncated(&self) -> Option<&str> {
        self.test.truncated.as_deref()
    }

    /// Why the record failed a check (None unless opened with `allow_damaged`).
    #[getter]
    fn damaged(&self) -> Option<&str> {
        self.test.damaged.as_deref()
    }

    /// The record's identity (`summary.json`'s `record_id`).
    #[getter]
    fn run_id(&self) -> Option<&str> {
        self.test.run_id.as_deref()
    }

    /// The cdlab version that wrote the record.
    #[getter]
    fn version(&self) -> Option<&str> {
        self.test.version.as_deref()
    }

    /// The backend that wrote the record's last part, when it says.
    #[getter]
    fn backend(&self) -> Option<&str> {
        self.test.backend.as_deref()
    }

    /// The series as columns in the order of `series.csv`: name -> little-endian bytes of
    /// float64 (type "number") or uint64 (type "integer"), or a list of str ("string"),
    /// each built from the library's typed rows ([`series_column`]).
    fn series_columns<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for (name, _, _) in SERIES_FIELDS {
            match series_column(&self.test.series, name) {
                Some(SeriesColumn::Number(v)) => {
                    out.set_item(*name, PyBytes::new(py, &le_f64(v.into_iter())))?
                }
                Some(SeriesColumn::Integer(v)) => {
                    out.set_item(*name, PyBytes::new(py, &le_u64(v.into_iter())))?
                }
                Some(SeriesColumn::Text(v)) => out.set_item(*name, PyList::new(py, v)?)?,
                // The library's test holds every field to a column: a name without one would
                // be a cdlab bug, said as such rather than a column silently missing.
                None => return Err(CdlabError::new_err(format!("series field {name} has no column"))),
            }
        }
        Ok(out)
    }

    /// (time_s, strain) of every snapshot, in record order.
    fn snapshot_times(&self) -> Vec<(f64, f64)> {
        self.test.snapshots.iter().map(|s| (s.time_s, s.strain)).collect()
    }

    /// The disks of snapshot `index`: name -> little-endian float64 bytes, one value per
    /// disk (x_m, y_m, theta_rad, vx_m_s, vy_m_s, w_rad_s, r_m, dx_m, dy_m).
    fn snapshot_disks<'py>(&self, py: Python<'py>, index: usize) -> PyResult<Bound<'py, PyDict>> {
        let s = self.snapshot(index)?;
        let out = PyDict::new(py);
        let cols: [(&str, DiskField); 9] = [
            ("x_m", |d| d.x),
            ("y_m", |d| d.y),
            ("theta_rad", |d| d.theta),
            ("vx_m_s", |d| d.vx),
            ("vy_m_s", |d| d.vy),
            ("w_rad_s", |d| d.w),
            ("r_m", |d| d.r),
            ("dx_m", |d| d.dx),
            ("dy_m", |d| d.dy),
        ];
        for (name, f) in cols {
            out.set_item(name, PyBytes::new(py, &le_f64(s.disks.iter().map(f))))?;
        }
        Ok(out)
    }

    /// The contacts of snapshot `index`: "i", "j" (little-endian uint32 bytes), "nx", "ny",
    /// "f_n_n_m", "f_t_n_m" (float64 bytes; forces in N/m) and "class" (uint8 bytes).
    fn snapshot_contacts<'py>(&self, py: Python<'py>, index: usize) -> PyResult<Bound<'py, PyDict>> {
        let s = self.snapshot(index)?;
        let c = &s.contacts;
        let out = PyDict::new(py);
        out.set_item("i", PyBytes::new(py, &le_u32(c.iter().map(|c| c.i))))?;
        out.set_item("j", PyBytes::new(py, &le_u32(c.iter().map(|c| c.j))))?;
        out.set_item("nx", PyBytes::new(py, &le_f64(c.iter().map(|c| c.nx))))?;
        out.set_item("ny", PyBytes::new(py, &le_f64(c.iter().map(|c| c.ny))))?;
        out.set_item("f_n_n_m", PyBytes::new(py, &le_f64(c.iter().map(|c| c.f_n))))?;
        out.set_item("f_t_n_m", PyBytes::new(py, &le_f64(c.iter().map(|c| c.f_t))))?;
        let class: Vec<u8> = c.iter().map(|c| c.class).collect();
        out.set_item("class", PyBytes::new(py, &class))?;
        Ok(out)
    }

    /// The micromechanical analysis of snapshot `index` as JSON (what `cdlab fabric`
    /// prints: [`cdlab::measure::micro::Analysis`], from the same library call,
    /// [`Snapshot::fabric`]), the stress divided by the sample area of the series row
    /// nearest the snapshot's time. An error (`CdlabError` with attributes `path` and `fault`) names the
    /// test when no row gives an area or no contact carries force.
    fn snapshot_fabric_json(&self, py: Python<'_>, index: usize) -> PyResult<String> {
        let s = self.snapshot(index)?;
        let json = py.detach(|| {
            let fabric = s.fabric(&self.test.series, &self.test.path)?;
            serde_json::to_string(&fabric.analysis).map_err(|e| Error::Other(e.to_string()))
        });
        json.map_err(|e| py_err(py, e))
    }
}

/// The campaign report of the finished tests below `paths` (each a run directory, an
/// archived test or a directory holding them): `(report_json, report_csv, tests_csv)`,
/// the texts `cdlab report` writes as report.json, report.csv and tests.csv. An error
/// names a path that is not a directory, or says that none holds a finished test.
#[pyfunction]
fn campaign_report(py: Python<'_>, paths: Vec<PathBuf>) -> PyResult<(String, String, String)> {
    use cdlab::analysis::report::analyse;
    use cdlab::campaign::collect;
    for p in &paths {
        if !p.is_dir() {
            return Err(file_error(py, p, format!("{}: not a directory", p.display())));
        }
    }
    let (points, missing) = py.detach(|| collect(&paths));
    if points.is_empty() {
        return Err(CdlabError::new_err(format!(
            "no finished test (summary.json) below {}",
            paths
                .iter()
                .map(|p| p.display().to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let report = analyse(&points, missing);
    let json = serde_json::to_string(&report).map_err(|e| CdlabError::new_err(e.to_string()))?;
    Ok((json, report.csv(), report.tests_csv()))
}

/// The series columns: (name, JSON type, description with unit), in `series.csv` order.
#[pyfunction]
fn series_fields() -> Vec<(&'static str, &'static str, &'static str)> {
    SERIES_FIELDS.to_vec()
}

/// The cdlab library version this module was built with.
#[pyfunction]
fn library_version() -> &'static str {
    env!("CARGO_PKG_VERSION")
}

/// The module `cdlab._cdlab`.
#[pymodule]
fn _cdlab(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_class::<Record>()?;
    m.add_function(wrap_pyfunction!(open_record, m)?)?;
    m.add_function(wrap_pyfunction!(campaign_report, m)?)?;
    m.add_function(wrap_pyfunction!(series_fields, m)?)?;
    m.add_function(wrap_pyfunction!(library_version, m)?)?;
    m.add_function(wrap_pyfunction!(run::run_test, m)?)?;
    m.add_function(wrap_pyfunction!(run::resume_run, m)?)?;
    m.add_function(wrap_pyfunction!(run::prepare_sample, m)?)?;
    m.add_function(wrap_pyfunction!(run::run_campaign, m)?)?;
    m.add("CdlabError", py.get_type::<CdlabError>())?;
    m.add("InvalidParameterError", py.get_type::<InvalidParameterError>())?;
    m.add("ParseError", py.get_type::<ParseError>())?;
    m.add("NumericalError", py.get_type::<NumericalError>())?;
    m.add("GpuError", py.get_type::<GpuError>())?;
    m.add("NoAdapterError", py.get_type::<NoAdapterError>())?;
    m.add("FileError", py.get_type::<FileError>())?;
    m.add("DamagedRecordError", py.get_type::<DamagedRecordError>())?;
    m.add("StoppedError", py.get_type::<StoppedError>())?;
    m.add("RunError", py.get_type::<RunError>())?;
    m.add("CampaignError", py.get_type::<CampaignError>())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::in_python_terms;
    use cdlab::Error;
    use cdlab::error::{Remedy, RunFault, SampleProblem};

    /// The library's messages name no command-line flag (issue 36, item 17: RunError told a
    /// Python user to pass --force); the package adds each error's remedy as its own calls:
    /// the occupied directory's refusal as the library makes it, and the other remedies.
    #[test]
    fn messages_name_the_package_calls_not_the_flags() {
        let dir = std::env::temp_dir().join(format!("cdlab-py-terms-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("x"), b"").unwrap();
        let occupied = cdlab::run::check_out_dir(&dir, cdlab::run::Existing::Refuse).unwrap_err();
        let _ = std::fs::remove_dir_all(&dir);
        let d = dir.display().to_string();
        assert_eq!(
            in_python_terms(&occupied),
            format!(
                "output directory {d} already holds files: replace them, resume that run, or \
                 write elsewhere (pass force=True to replace them, call cdlab.resume({d:?}) to \
                 continue that run, or give another out directory)"
            )
        );
        let run = |remedy| Error::Run {
            path: "/r/a b/run.mcap".into(),
            fault: RunFault::NoCheckpoint,
            message: "no checkpoint".into(),
            remedy: Some(remedy),
        };
        for (e, call) in [
            (
                Error::DamagedRecord {
                    file: "/r/a b/run.mcap".into(),
                    reason: "chunk CRC".into(),
                },
                "cdlab.resume(\"/r/a b\")",
            ),
            (run(Remedy::StartAgain), "force=True"),
            (run(Remedy::Resume("/r/a b".into())), "cdlab.resume(\"/r/a b\")"),
            (
                Error::BadSample {
                    path: "s.bin".into(),
                    problem: SampleProblem::OldFormat { version: 1 },
                },
                "cdlab.prepare(config, out=\"s.bin\")",
            ),
            (cdlab::error::gpu_failure("device lost"), "backend=\"cpu\""),
        ] {
            let m = in_python_terms(&e);
            assert!(m.contains(call) && !m.contains("--"), "{m}");
        }
        let plain = Error::Other("nothing to change here".into());
        assert_eq!(in_python_terms(&plain), "nothing to change here");
    }
}
