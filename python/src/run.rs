//! Running tests from Python: `cdlab.run`, `cdlab.resume`, `cdlab.prepare` and
//! `cdlab.campaign` (python/cdlab/__init__.py wraps these in their documented signatures).
//!
//! Each call releases the GIL while the library computes. Ctrl-C stays Python's: cdlab
//! installs no signal handler. Instead, at every progress event of the run (each series row,
//! each phase end) the GIL is taken back for a moment and Python's pending signals are run
//! (`py.check_signals()`); the KeyboardInterrupt that Python's own SIGINT handler raises there,
//! or any exception the progress callback raises, sets the run's [`Cancel`] token, the
//! library stops at its next checkpoint, and the exception is raised to the caller with the
//! checkpoint's `step` and the run's `path` as attributes: `cdlab.resume(path)` continues it.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use cdlab::Error;
use cdlab::campaign::{self, Options, Sweep};
use cdlab::config::{Config, Overrides};
use cdlab::interrupt::Cancel;
use cdlab::run::{self, Event, Progress};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::{path_obj, py_err};

/// A configuration given as JSON text (what `json.dumps` makes of a Python dict with the
/// TOML file's keys and unit strings), deserialised straight into the library's
/// configuration ([`Config::from_json_value`]): units and ranges are checked as for a file,
/// and a value of the wrong type or an unknown key is an InvalidParameterError naming its
/// key, not a line of a text the user never wrote.
fn config_from_json(json: &str) -> cdlab::Result<Config> {
    let bad = |why: String| Error::Parse {
        path: PathBuf::from(CONFIG_DICT),
        line: 0,
        message: why,
    };
    let value: serde_json::Value = serde_json::from_str(json).map_err(|e| bad(e.to_string()))?;
    if !value.is_object() {
        return Err(bad("the configuration must be a dict of sections".into()));
    }
    Config::from_json_value(value, CONFIG_DICT)
}

/// How errors of a configuration given as a dict name their source.
const CONFIG_DICT: &str = "<config dict>";

/// The configuration of a call: a dict (as JSON), a TOML file, or the built-in default;
/// then the output directory and backend, validated (what `cdlab biaxial --config FILE
/// --out DIR --backend B` builds).
fn configure(
    json: Option<&str>,
    file: Option<&Path>,
    out: Option<PathBuf>,
    backend: Option<String>,
) -> cdlab::Result<Config> {
    let overrides = Overrides {
        backend: backend.as_deref().map(str::parse).transpose()?,
        out,
        ..Default::default()
    };
    match json {
        Some(j) => {
            let mut c = config_from_json(j)?;
            c.apply(&overrides);
            c.validate()?;
            Ok(c)
        }
        None => run::configure(file, &overrides),
    }
}

/// The progress receiver of a run: passes each series row to the Python callback (if any)
/// and runs Python's pending signal handlers. The first exception either raises is kept and
/// cancels the run.
struct Bridge {
    callback: Option<Py<PyAny>>,
    error: Option<PyErr>,
    cancel: Cancel,
}

impl Bridge {
    fn new(callback: Option<Py<PyAny>>) -> Self {
        Bridge {
            callback,
            error: None,
            cancel: Cancel::new(),
        }
    }

    /// The dict the callback receives for `event`, None for events it is not told about.
    fn event_dict<'py>(py: Python<'py>, event: &Event<'_>) -> PyResult<Option<Bound<'py, PyDict>>> {
        let d = PyDict::new(py);
        match event {
            Event::Row { row, strain_end } => {
                d.set_item("event", "row")?;
                d.set_item("phase", &row.phase)?;
                d.set_item("step", row.step)?;
                d.set_item("time_s", row.time_s)?;
                d.set_item("strain", row.strain_axial)?;
                d.set_item("strain_end", *strain_end)?;
                d.set_item("sigma1_pa", row.sigma1_pa)?;
                d.set_item("sigma3_pa", row.sigma3_pa)?;
                d.set_item("volumetric_strain", row.volumetric_strain)?;
                d.set_item("coordination", row.coordination)?;
                d.set_item("wall_s", row.wall_s)?;
            }
            Event::PhaseEnd(end) => {
                d.set_item("event", "phase_end")?;
                d.set_item("phase", end.phase.name())?;
            }
            Event::BackendNote(text) => {
                d.set_item("event", "note")?;
                d.set_item("text", *text)?;
            }
            _ => return Ok(None),
        }
        Ok(Some(d))
    }
}

impl Progress for Bridge {
    fn event(&mut self, event: &Event<'_>) {
        if self.error.is_some() {
            return;
        }
        let outcome = Python::attach(|py| -> PyResult<()> {
            if let Some(cb) = &self.callback
                && let Some(d) = Self::event_dict(py, event)?
            {
                cb.call1(py, (d,))?;
            }
            py.check_signals()
        });
        if let Err(e) = outcome {
            self.error = Some(e);
            self.cancel.cancel();
        }
    }
}

/// The end of a run as Python sees it: the run directory, or the exception that stopped it
/// (the callback's or KeyboardInterrupt, carrying `step` and `path`), or the library's error.
fn conclude(py: Python<'_>, bridge: Bridge, result: cdlab::Result<PathBuf>, dir: &Path) -> PyResult<String> {
    match (bridge.error, result) {
        (None, Ok(dir)) => Ok(dir.display().to_string()),
        (None, Err(e)) => Err(py_err(py, e)),
        (Some(raised), result) => {
            let step = match &result {
                Err(Error::Interrupted { step, .. }) => Some(*step),
                _ => None,
            };
            // Attributes help a caller resume; an exception type without a __dict__ keeps
            // its own meaning rather than being replaced.
            let value = raised.value(py);
            let _ = value.setattr("path", path_obj(py, dir));
            let _ = value.setattr("step", step);
            Err(raised)
        }
    }
}

/// Runs a new biaxial test into `out` (see `cdlab.run`); returns the run directory.
#[pyfunction]
#[pyo3(signature = (out, config_json = None, config_path = None, backend = None, force = false, progress = None, sample = None))]
#[allow(clippy::too_many_arguments)]
pub fn run_test(
    py: Python<'_>,
    out: PathBuf,
    config_json: Option<String>,
    config_path: Option<PathBuf>,
    backend: Option<String>,
    force: bool,
    progress: Option<Py<PyAny>>,
    sample: Option<PathBuf>,
) -> PyResult<String> {
    let mut config = configure(
        config_json.as_deref(),
        config_path.as_deref(),
        Some(out.clone()),
        backend,
    )
    .map_err(|e| py_err(py, e))?;
    let scene = match &sample {
        Some(path) => {
            let s = py.detach(|| run::read_sample(path)).map_err(|e| py_err(py, e))?;
            run::adopt_sample(&mut config, &s.params, [("disks", None), ("seed", None)], path)
                .map_err(|e| py_err(py, e))?;
            Some(s.scene)
        }
        None => None,
    };
    let mut bridge = Bridge::new(progress);
    let result = py.detach(|| {
        let cancel = bridge.cancel.clone();
        let existing = if force {
            run::Existing::Replace
        } else {
            run::Existing::Refuse
        };
        run::start(&config, scene, existing, &mut bridge, &cancel).map(|o| o.dir)
    });
    conclude(py, bridge, result, &out)
}

/// Continues the run in `path` from its last intact checkpoint (see `cdlab.resume`).
#[pyfunction]
#[pyo3(signature = (path, backend = None, progress = None))]
pub fn resume_run(
    py: Python<'_>,
    path: PathBuf,
    backend: Option<String>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let backend = backend
        .as_deref()
        .map(str::parse)
        .transpose()
        .map_err(|e| py_err(py, e))?;
    let mut bridge = Bridge::new(progress);
    let result = py.detach(|| {
        let cancel = bridge.cancel.clone();
        run::resume(&path, backend, &mut bridge, &cancel).map(|o| o.dir)
    });
    conclude(py, bridge, result, &path)
}

/// Deposits and compacts a sample and writes it to `out` (see `cdlab.prepare`); returns
/// (path, disks, width_m, height_m, wall_s).
#[pyfunction]
#[pyo3(signature = (out, config_json = None, config_path = None, progress = None))]
pub fn prepare_sample(
    py: Python<'_>,
    out: PathBuf,
    config_json: Option<String>,
    config_path: Option<PathBuf>,
    progress: Option<Py<PyAny>>,
) -> PyResult<(String, usize, f64, f64, f64)> {
    let config =
        configure(config_json.as_deref(), config_path.as_deref(), None, None).map_err(|e| py_err(py, e))?;
    let mut bridge = Bridge::new(progress);
    let result = py.detach(|| {
        let cancel = bridge.cancel.clone();
        run::prepare(&config, &out, &mut bridge, &cancel).map(|p| {
            (
                p.path.clone(),
                p.scene.disks.len(),
                p.width_m,
                p.height_m,
                p.wall_s,
            )
        })
    });
    match (bridge.error, result) {
        (None, Ok((p, n, w, h, t))) => Ok((p.display().to_string(), n, w, h, t)),
        (None, Err(e)) => Err(py_err(py, e)),
        (Some(raised), _) => Err(raised),
    }
}

/// Runs (this shard of) the campaign of the sweep file `sweep` with `jobs` workers (see
/// `cdlab.campaign`); returns (grid, total, ended, failed [(dir, why)], stopped, elsewhere).
///
/// The workers run on threads of their own; this thread, without the GIL, waits for them
/// and takes the GIL back every few tenths of a second to run Python's pending signal
/// handlers, so that Ctrl-C stops the campaign's tests at their checkpoints.
#[pyfunction]
#[pyo3(signature = (sweep, jobs = 1, shard = (0, 1), dry_run = false))]
#[allow(clippy::type_complexity)]
pub fn run_campaign(
    py: Python<'_>,
    sweep: PathBuf,
    jobs: usize,
    shard: (usize, usize),
    dry_run: bool,
) -> PyResult<(
    usize,
    usize,
    usize,
    Vec<(String, String)>,
    Vec<String>,
    Vec<String>,
)> {
    if shard.1 == 0 || shard.0 >= shard.1 {
        let e = Error::invalid(
            "shard",
            format!("({}, {})", shard.0, shard.1),
            "(I, N) with 0 <= I < N",
        );
        return Err(py_err(py, e));
    }
    let loaded = py.detach(|| Sweep::load(&sweep)).map_err(|e| py_err(py, e))?;
    let options = Options {
        jobs: jobs.max(1),
        shard,
        dry_run,
    };
    let cancel = Cancel::new();
    let done = AtomicBool::new(false);
    let mut raised: Option<PyErr> = None;
    let result = py.detach(|| {
        std::thread::scope(|s| {
            let worker = s.spawn(|| {
                let r = campaign::run(&loaded, &options, &campaign::Quiet, &cancel);
                done.store(true, Ordering::SeqCst);
                r
            });
            while !done.load(Ordering::SeqCst) {
                std::thread::sleep(std::time::Duration::from_millis(200));
                if raised.is_none()
                    && let Err(e) = Python::attach(|py| py.check_signals())
                {
                    raised = Some(e);
                    cancel.cancel();
                }
            }
            worker
                .join()
                .unwrap_or_else(|_| Err(Error::Other("the campaign's thread panicked".into())))
        })
    });
    if let Some(e) = raised {
        return Err(e);
    }
    let o = result.map_err(|e| py_err(py, e))?;
    let s = |p: &PathBuf| p.display().to_string();
    Ok((
        o.grid,
        o.total,
        o.ended,
        o.failed.iter().map(|(p, w)| (s(p), w.clone())).collect(),
        o.stopped.iter().map(s).collect(),
        o.elsewhere.iter().map(s).collect(),
    ))
}
