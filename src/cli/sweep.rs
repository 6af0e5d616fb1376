//! `cdlab sweep FILE.toml`: the friction x pressure campaign, one compacted sample per seed
//! reused by every test of that seed (compaction is frictionless, so the sample does not
//! depend on the test's friction), tests run in parallel, finished ones skipped and
//! half-finished ones resumed. `--shard I/N` runs the I-th of N disjoint parts (0 <= I < N).

use std::collections::VecDeque;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

use serde::Deserialize;

use crate::analysis::report::tests;
use crate::config::units::{Dimension, parse_with_unit};
use crate::config::{Config, Duration, Pressure};
use crate::error::{Error, Result};

use super::biaxial::{differences, read_sample, run_fresh, run_resume, sample_differences};
use super::run::Progress;

/// Options of `cdlab sweep`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The sweep file (TOML), or `collect` followed by directories to merge into a report.
    pub file: PathBuf,
    /// With `collect`: the campaign directories to merge.
    pub dirs: Vec<PathBuf>,
    /// Run only the I-th of N disjoint parts, written `I/N` (0 <= I < N).
    #[arg(long)]
    pub shard: Option<String>,
    /// Tests run at once (default: the number of cores).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Seconds between two progress lines of each running test when stderr is not a
    /// terminal (a log); on a terminal the campaign's display updates continuously.
    #[arg(long, default_value_t = 120.0)]
    pub log_every: f64,
    /// Run nothing: say what the sweep would do with each test (skip, resume, start), in
    /// the order the tests would start, after checking the tests found in the output
    /// directory against the sweep's settings (a campaign copied from an archive, say).
    #[arg(long)]
    pub dry_run: bool,
}

/// The sweep file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SweepFile {
    /// Base configuration file, relative to the sweep file (default: the built-in one).
    base: Option<PathBuf>,
    /// Campaign directory.
    out: PathBuf,
    /// Contact frictions (default: the paper's 13).
    #[serde(default = "paper_mu")]
    mu: Vec<f64>,
    /// Confining stresses with units (default: the paper's 0.5, 1, 2, 4, 8 MPa).
    #[serde(default = "paper_sigma3")]
    sigma3: Vec<toml::Value>,
    /// Sample seeds (one compacted sample each; default [1]).
    #[serde(default = "one_seed")]
    seeds: Vec<u64>,
    /// Time steps by contact friction: a test runs at the `dt` of the entry with the
    /// largest `mu_from` at or below its friction, else at the base configuration's.
    #[serde(default)]
    dt_by_friction: Vec<FrictionDt>,
}

/// One `[[dt_by_friction]]` entry of a sweep file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FrictionDt {
    /// Lowest contact friction that runs at `dt`.
    mu_from: f64,
    /// The time step.
    dt: Duration,
}

impl SweepFile {
    /// The time step of a test at contact friction `mu` (s), `base` where no entry applies.
    fn dt(&self, mu: f64, base: f64) -> f64 {
        self.dt_by_friction
            .iter()
            .filter(|e| e.mu_from <= mu)
            .max_by(|a, b| a.mu_from.total_cmp(&b.mu_from))
            .map_or(base, |e| e.dt.si())
    }

    /// Refuses entries that cannot mean anything (the time step itself is checked with the
    /// rest of each test's configuration).
    fn check_dt_entries(&self, file: &Path) -> Result<()> {
        for (k, e) in self.dt_by_friction.iter().enumerate() {
            if !(e.mu_from.is_finite() && e.mu_from >= 0.0) {
                return Err(Error::invalid(
                    "dt_by_friction.mu_from",
                    e.mu_from,
                    "a friction >= 0",
                ));
            }
            if self.dt_by_friction[..k].iter().any(|o| o.mu_from == e.mu_from) {
                return Err(Error::Other(format!(
                    "{}: two dt_by_friction entries start at friction {}",
                    file.display(),
                    e.mu_from
                )));
            }
        }
        Ok(())
    }
}

fn paper_mu() -> Vec<f64> {
    vec![0.01, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.2, 3.0, 6.0, 12.0]
}
fn paper_sigma3() -> Vec<toml::Value> {
    ["0.5 MPa", "1 MPa", "2 MPa", "4 MPa", "8 MPa"]
        .iter()
        .map(|s| toml::Value::String(s.to_string()))
        .collect()
}
fn one_seed() -> Vec<u64> {
    vec![1]
}

/// One test of the grid.
#[derive(Clone, Debug)]
struct Point {
    mu: f64,
    sigma3: f64,
    seed: u64,
    /// Time step (s).
    dt: f64,
    dir: PathBuf,
}

fn parse_shard(s: &str) -> Result<(usize, usize)> {
    let bad = || Error::invalid("--shard", s, "I/N with 0 <= I < N");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n) = (
        i.parse::<usize>().map_err(|_| bad())?,
        n.parse::<usize>().map_err(|_| bad())?,
    );
    if n == 0 || i >= n {
        return Err(bad());
    }
    Ok((i, n))
}

/// Runs `cdlab sweep`.
pub fn run(args: &Args) -> Result<()> {
    if args.file.as_os_str() == "collect" {
        return super::report::run(&super::report::Args {
            dirs: args.dirs.clone(),
            out: None,
        });
    }
    crate::interrupt::install();
    if !(args.log_every.is_finite() && args.log_every >= 0.0) {
        return Err(Error::invalid("--log-every", args.log_every, "seconds >= 0"));
    }
    let (shard, of) = args
        .shard
        .as_deref()
        .map(parse_shard)
        .transpose()?
        .unwrap_or((0, 1));
    let text = crate::config::read_capped(&args.file, crate::config::MAX_CONFIG_BYTES, "a sweep file")?;
    let sweep: SweepFile = toml::from_str(&text).map_err(|e| Error::Parse {
        path: args.file.clone(),
        line: 0,
        message: e.to_string(),
    })?;
    let here = args.file.parent().unwrap_or(Path::new("."));
    let mut base = match &sweep.base {
        Some(p) => Config::load(here.join(p))?,
        None => Config::default(),
    };
    let sigma3: Vec<f64> = sweep
        .sigma3
        .iter()
        .map(|v| match v {
            // A unit is required: `sigma3 = [8]` would be 8 Pa.
            toml::Value::String(s) => {
                let pa = parse_with_unit(s, Dimension::Pressure)
                    .map_err(|e| Error::invalid("sigma3", format!("\"{s}\""), &e.0))?;
                crate::config::validate::check_pressure("sigma3", pa)?;
                Ok(pa)
            }
            other => Err(Error::invalid(
                "sigma3",
                other,
                "a pressure with its unit, as a string such as \"8 MPa\"",
            )),
        })
        .collect::<Result<_>>()
        .map_err(|e| Error::Other(format!("{}: {e}", args.file.display())))?;
    // Every friction a test can run at, before anything is run or a dry run says it would.
    if let Some(mu) = sweep.mu.iter().find(|m| !(m.is_finite() && **m >= 0.0)) {
        return Err(Error::Other(format!(
            "{}: {}",
            args.file.display(),
            Error::invalid("mu", mu, "every friction must be a finite number >= 0")
        )));
    }
    if sweep.mu.is_empty() || sigma3.is_empty() || sweep.seeds.is_empty() {
        return Err(Error::Other(format!(
            "{}: the grid is empty (mu, sigma3 and seeds need values)",
            args.file.display()
        )));
    }
    sweep.check_dt_entries(&args.file)?;
    let mut grid = Vec::new();
    for &seed in &sweep.seeds {
        for &mu in &sweep.mu {
            for &s3 in &sigma3 {
                let dir = sweep.out.join(format!("seed{seed}_mu{mu}_s{}MPa", s3 / 1e6));
                if grid.iter().any(|p: &Point| p.dir == dir) {
                    return Err(Error::Other(format!(
                        "duplicate point mu {mu}, sigma3 {s3} Pa, seed {seed}"
                    )));
                }
                grid.push(Point {
                    mu,
                    sigma3: s3,
                    seed,
                    dt: sweep.dt(mu, base.solver.dt.si()),
                    dir,
                });
            }
        }
    }
    // Each test's configuration (its friction, pressure and time step in the base one) is
    // checked before anything is written or a dry run says it would start.
    for p in &grid {
        point_config(&base, p).validate().map_err(|e| {
            Error::Other(format!(
                "{}: the test {}: {e}",
                args.file.display(),
                p.dir.display()
            ))
        })?;
    }
    // The whole grid, whatever the shard, so that a report on any shard's directory (or on
    // several, merged) names the tests no shard has run yet.
    if !args.dry_run {
        let names: Vec<String> = grid
            .iter()
            .filter_map(|p| p.dir.file_name().map(|n| n.to_string_lossy().into_owned()))
            .collect();
        let written = std::fs::create_dir_all(&sweep.out)
            .map_err(|e| Error::io(&sweep.out, e))
            .and_then(|()| crate::analysis::report::add_to_grid(&sweep.out, &names));
        if let Err(e) = written {
            eprintln!(
                "warning: the campaign's list of tests ({}) was not updated: {e}; the report \
                 will not name the tests that were never run",
                crate::analysis::report::GRID_FILE
            );
        }
    }
    // Finished tests first: they are only checked and skipped, so the counts of the
    // progress lines (and of a stop) include them from the start. Then the tests with the
    // smallest time step, which take the most steps: started first, they leave the shorter
    // tests for the end, when fewer jobs remain to share the cores (longest first; the
    // sort is stable, so the grid's order holds at equal steps).
    let (mut mine, mut to_run): (Vec<Point>, Vec<Point>) = grid
        .iter()
        .enumerate()
        .filter(|(k, _)| k % of == shard)
        .map(|(_, p)| p.clone())
        .partition(|p| p.dir.join("summary.json").exists());
    to_run.sort_by(|a, b| a.dt.total_cmp(&b.dt));
    mine.append(&mut to_run);
    let jobs = args
        .jobs
        .unwrap_or_else(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
        .max(1);
    eprintln!(
        "sweep: {} in the grid, {} in this shard, {} at a time -> {}",
        tests(grid.len()),
        mine.len(),
        jobs,
        sweep.out.display()
    );
    // The cores are shared between the tests running at once: each solver gets its share
    // (its sweeps wait for each other at barriers, which must not compete for one core),
    // unless the base configuration sets its team size.
    base.solver.backend = crate::config::Backend::Cpu;
    if base.solver.threads == 0 {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        base.solver.threads = (cores / jobs).max(1);
    }
    // On a terminal, one display for the campaign: a bar of finished tests and one line per
    // running test. In a log, each test's start and end, and a line per running test every
    // `--log-every` seconds.
    let display = std::io::stderr().is_terminal().then(MultiProgress::new);
    let overall = display.as_ref().map(|m| {
        let b = m.add(ProgressBar::new(mine.len() as u64));
        b.set_style(
            ProgressStyle::with_template("campaign [{elapsed_precise}] {bar:30} {pos}/{len} tests")
                .expect("valid template"),
        );
        b
    });
    let say = |line: &str| match &display {
        Some(m) => {
            let _ = m.println(line);
        }
        None => eprintln!("{line}"),
    };
    let started = Instant::now();
    let queue = Mutex::new(mine.iter().cloned().collect::<VecDeque<Point>>());
    let samples: Mutex<Vec<(u64, crate::model::Scene)>> = Mutex::new(Vec::new());
    // Tests ended, failures, tests a signal stopped, tests another process runs.
    let done = Mutex::new((
        0usize,
        Vec::<(PathBuf, String)>::new(),
        Vec::<PathBuf>::new(),
        Vec::<PathBuf>::new(),
    ));
    let total = mine.len();
    // A dry run checks the tests one by one, so that it lists them in the order a run
    // would start them (with several workers, a slow check, such as reading a long record,
    // would move its line after quicker ones).
    let workers = if args.dry_run { 1 } else { jobs };
    std::thread::scope(|s| {
        for _ in 0..workers {
            s.spawn(|| {
                loop {
                    // Taken in a statement of its own: the guard of a `while let`
                    // scrutinee lives through the loop body, which ran the tests one at a
                    // time whatever --jobs said.
                    if crate::interrupt::requested().is_some() {
                        break;
                    }
                    let next = queue.lock().expect("queue").pop_front();
                    let Some(p) = next else { break };
                    let label = p
                        .dir
                        .file_name()
                        .map_or(String::new(), |n| n.to_string_lossy().into());
                    let bar = display.as_ref().map(|m| {
                        let b = m.add(ProgressBar::new(1000));
                        b.set_style(
                            ProgressStyle::with_template("  {prefix:<22} {bar:20} {msg}")
                                .expect("valid template"),
                        );
                        b.set_prefix(label.clone());
                        b
                    });
                    let progress = Progress::Campaign {
                        label,
                        bar: bar.clone(),
                        every_s: args.log_every,
                    };
                    let outcome = if args.dry_run {
                        check_point(&point_config(&base, &p), &p).map(|what| {
                            let busy = crate::record::RunLock::held_elsewhere(&p.dir);
                            let note = if busy {
                                " (running now in another process)"
                            } else {
                                ""
                            };
                            Some(format!("{}{note}", what.dry_run()))
                        })
                    } else {
                        run_point(&base, &sweep.out, &p, &samples, &progress, &say)
                    };
                    if let (Some(m), Some(b)) = (&display, &bar) {
                        m.remove(b);
                    }
                    let mut d = done.lock().expect("progress");
                    if matches!(outcome, Ok(None)) {
                        say(&format!(
                            "{}: running in another process, skipped (its results appear \
                             when that process ends it)",
                            p.dir.display()
                        ));
                        d.3.push(p.dir.clone());
                        continue;
                    }
                    if let Err(Error::Interrupted { step, .. }) = &outcome {
                        let at = if *step > 0 {
                            format!("stopped at its checkpoint of step {step}")
                        } else {
                            "stopped before its test began".to_string()
                        };
                        say(&format!("{}: {at}", p.dir.display()));
                        d.2.push(p.dir.clone());
                        continue;
                    }
                    d.0 += 1;
                    if let Some(b) = &overall {
                        b.inc(1);
                    }
                    let hours = started.elapsed().as_secs_f64() / 3600.0;
                    match outcome {
                        Ok(line) => say(&format!(
                            "[{}/{total}, campaign {hours:.2} h] {}: {}",
                            d.0,
                            p.dir.display(),
                            line.unwrap_or_default()
                        )),
                        Err(e) => {
                            say(&format!(
                                "[{}/{total}, campaign {hours:.2} h] {}: FAILED: {e}",
                                d.0,
                                p.dir.display()
                            ));
                            d.1.push((p.dir.clone(), e.to_string()));
                        }
                    }
                }
            });
        }
    });
    if let Some(b) = &overall {
        b.finish_and_clear();
    }
    let (ended, failed, stopped, elsewhere) = done.into_inner().expect("progress");
    if let Some(signal) = crate::interrupt::requested() {
        eprintln!(
            "sweep: stopped by {}: {ended} of {total} tests ended or were found finished ({} \
             failed), {} stopped at a checkpoint or before starting, {} running in another \
             process, {} not started; the same command resumes the campaign",
            crate::interrupt::signal_name(signal),
            failed.len(),
            stopped.len(),
            elsewhere.len(),
            total - ended - stopped.len() - elsewhere.len()
        );
        return Err(Error::Interrupted { signal, step: 0 });
    }
    if failed.is_empty() && args.dry_run {
        eprintln!("sweep: dry run, nothing was run; {} checked", tests(total));
        Ok(())
    } else if failed.is_empty() && !elsewhere.is_empty() {
        eprintln!(
            "sweep: {ended} of this shard's {} finished, {} running in another process \
             (not failed: that process ends them); `cdlab report {}` analyses the campaign \
             once it has",
            tests(total),
            elsewhere.len(),
            sweep.out.display()
        );
        Ok(())
    } else if failed.is_empty() {
        eprintln!(
            "sweep: {} of this shard finished; `cdlab report {}` analyses the campaign",
            if total == 1 {
                "the 1 test".to_string()
            } else {
                format!("all {total} tests")
            },
            sweep.out.display()
        );
        Ok(())
    } else {
        Err(Error::Other(format!(
            "{} of {total} tests failed (the others finished): {failed:?}",
            failed.len()
        )))
    }
}

/// What the sweep does with one test, found from its directory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Finished (a summary): skipped.
    Finished,
    /// A record with a checkpoint: resumed.
    Resumable,
    /// A record without a checkpoint (killed in its first minutes): started again.
    Restart,
    /// Nothing yet: started.
    New,
}

impl State {
    /// The line `--dry-run` prints.
    fn dry_run(self) -> &'static str {
        match self {
            State::Finished => "already finished, would be skipped",
            State::Resumable => "would resume from its last checkpoint",
            State::Restart => "would restart (its record holds no checkpoint yet)",
            State::New => "would start",
        }
    }
}

/// The test's configuration in this sweep.
fn point_config(base: &Config, p: &Point) -> Config {
    let mut config = base.clone();
    config.sample.seed = p.seed;
    config.test.mu = p.mu;
    config.test.sigma3 = Pressure(p.sigma3);
    config.solver.dt = Duration(p.dt);
    config.output.dir = p.dir.clone();
    config
}

/// Finds what state test `p` is in and checks that a test found in its directory (finished
/// or to resume) has this sweep's settings (`config`, from [`point_config`]).
fn check_point(config: &Config, p: &Point) -> Result<State> {
    // A finished test is skipped and a half-finished one resumes with its own settings, so
    // both must be this sweep's tests. A record without a checkpoint (a test killed in its
    // first minutes) has nothing to resume: the test starts again. An unreadable record is
    // an error, never overwritten.
    let started = p.dir.join(crate::record::MCAP_FILE).exists();
    let finished = p.dir.join("summary.json").exists();
    let (recorded, resume) = if finished {
        (Some(crate::record::read_config(&p.dir)?), false)
    } else if started {
        let record = crate::record::read_run(&p.dir)?;
        match record.last_checkpoint {
            Some(_) => (Some(record.config()?), true),
            None => (None, false),
        }
    } else {
        (None, false)
    };
    if let Some(recorded) = recorded {
        let differ = point_differences(config, &recorded);
        if !differ.is_empty() {
            return Err(Error::Other(format!(
                "{} holds a test of other settings than this sweep's ({}): move it away or \
                 use another output directory",
                p.dir.display(),
                differ.join("; ")
            )));
        }
    }
    Ok(match (finished, started, resume) {
        (true, _, _) => State::Finished,
        (_, _, true) => State::Resumable,
        (_, true, false) => State::Restart,
        _ => State::New,
    })
}

/// Runs, resumes or skips one test; returns a one-line outcome, or None when another
/// process runs the test.
fn run_point(
    base: &Config,
    out: &Path,
    p: &Point,
    samples: &Mutex<Vec<(u64, crate::model::Scene)>>,
    progress: &Progress,
    say: &dyn Fn(&str),
) -> Result<Option<String>> {
    let config = point_config(base, p);
    // Held until the test ends, so that a second sweep on this directory leaves it alone.
    // A test whose lock another process holds is that process's to run (two sweeps on one
    // directory, or a biaxial --resume beside the sweep): skipped, not failed.
    // A refusal is tried once more: the other process may have ended in between (its test
    // is then found finished, or resumed here).
    let acquire = || crate::record::RunLock::acquire(&p.dir);
    let _lock = match acquire().or_else(|_| acquire()) {
        Ok(lock) => lock,
        Err(_) if crate::record::RunLock::held_elsewhere(&p.dir) => return Ok(None),
        Err(e) => return Err(e),
    };
    let state = check_point(&config, p)?;
    let resume = state == State::Resumable;
    let how = match state {
        State::Finished => return Ok(Some("already finished, skipped".into())),
        State::Resumable => "resuming",
        State::Restart => "restarting (its record holds no checkpoint yet)",
        State::New => "starting",
    };
    say(&format!("sweep: {how} {}", p.dir.display()));
    let summary = if resume {
        run_resume(&p.dir, Some("cpu"), progress)?
    } else {
        config.validate()?;
        // The sample is prepared with the base configuration's settings, whichever test
        // asks for it first (its time step may be one of `dt_by_friction`).
        let mut prepare = base.clone();
        prepare.sample.seed = p.seed;
        let scene = sample(&prepare, out, p.seed, samples)?;
        run_fresh(&config, &p.dir, Some(scene), progress)?
    };
    Ok(Some(format!(
        "peak sigma1 {:.3} MPa, residual {}, {:.0} s",
        summary.sigma1_peak_mpa,
        summary.sigma1_residual_mpa.map_or(
            format!(
                "n/a (ended before strain {:.3})",
                crate::measure::derived::RESIDUAL_MIN_END
            ),
            |v| format!("{v:.3} MPa")
        ),
        summary.wall_time_s
    )))
}

/// The settings the sweep gives each test on which `recorded` (a test found in its
/// directory) differs from `ours`, one phrase each. A finished test of other settings would
/// enter the report as one of this campaign's, and a half-finished one would resume with its
/// own.
fn point_differences(ours: &Config, recorded: &Config) -> Vec<String> {
    differences(
        &[("sample.seed", ours.sample.seed, recorded.sample.seed)],
        &[
            ("test.mu", ours.test.mu, recorded.test.mu, ""),
            (
                "test.sigma3",
                ours.test.sigma3.si(),
                recorded.test.sigma3.si(),
                " Pa",
            ),
            (
                "test.strain_end",
                ours.test.strain_end,
                recorded.test.strain_end,
                "",
            ),
            ("solver.dt", ours.solver.dt.si(), recorded.solver.dt.si(), " s"),
        ],
        "the test",
    )
}

/// The compacted sample of `seed`: from memory, from `out/samples/seedS.bin`, or prepared
/// now (once: a second thread asking for the same seed waits on the mutex, a second process,
/// another shard, waits on the sample's file lock and then reads the finished file).
fn sample(
    config: &Config,
    out: &Path,
    seed: u64,
    samples: &Mutex<Vec<(u64, crate::model::Scene)>>,
) -> Result<crate::model::Scene> {
    let mut cache = samples.lock().expect("samples");
    if let Some((_, s)) = cache.iter().find(|(k, _)| *k == seed) {
        return Ok(s.clone());
    }
    let path = out.join("samples").join(format!("seed{seed}.bin"));
    let dir = path.parent().expect("has a parent");
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    // Held while the sample is looked for and, when absent, prepared and written: the file
    // appears whole (temporary name, fsync, rename) and only once.
    let _lock = crate::sample::file::SampleLock::acquire(&path, || {
        eprintln!(
            "sweep: another process is preparing {}; waiting for it",
            path.display()
        )
    })?;
    let scene = if path.exists() {
        let sample = read_sample(&path)?;
        // A samples directory left by a campaign with other sample settings must not
        // stand in for this one's.
        let differ = sample_differences(config, &sample.params);
        if !differ.is_empty() {
            return Err(Error::Other(format!(
                "{} was prepared with other settings than this campaign's ({}): move it away \
                 or use another output directory",
                path.display(),
                differ.join("; ")
            )));
        }
        sample.scene
    } else {
        super::prepare::prepare_to(config, &path, true)?
    };
    cache.push((seed, scene.clone()));
    Ok(scene)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A test runs at the entry with the largest `mu_from` at or below its friction; an
    /// entry repeated or below zero is refused.
    #[test]
    fn time_step_follows_the_friction_entries() {
        let sweep: SweepFile = toml::from_str(
            "out = \"x\"\n[[dt_by_friction]]\nmu_from = 6\ndt = \"0.1 ms\"\n\
             [[dt_by_friction]]\nmu_from = 3\ndt = \"0.25 ms\"\n",
        )
        .unwrap();
        sweep.check_dt_entries(Path::new("x.toml")).unwrap();
        let base = 5e-4;
        // Expected: below 3 the base step, from 3 up to 6 the 3 entry, from 6 the 6 entry.
        let got: Vec<f64> = [0.01, 2.99, 3.0, 5.0, 6.0, 12.0]
            .iter()
            .map(|&mu| sweep.dt(mu, base))
            .collect();
        assert_eq!(got, [5e-4, 5e-4, 2.5e-4, 2.5e-4, 1e-4, 1e-4]);
        for bad in [
            "out = \"x\"\n[[dt_by_friction]]\nmu_from = 3\ndt = \"0.25 ms\"\n[[dt_by_friction]]\nmu_from = 3\ndt = \"0.1 ms\"\n",
            "out = \"x\"\n[[dt_by_friction]]\nmu_from = -1\ndt = \"0.25 ms\"\n",
        ] {
            let sweep: SweepFile = toml::from_str(bad).unwrap();
            let e = sweep
                .check_dt_entries(Path::new("x.toml"))
                .unwrap_err()
                .to_string();
            assert!(e.contains("dt_by_friction"), "{e}");
        }
        // A duration without a time unit is a parse error, not a silent number.
        assert!(
            toml::from_str::<SweepFile>("out = \"x\"\n[[dt_by_friction]]\nmu_from = 3\ndt = \"0.25 MPa\"\n")
                .is_err()
        );
    }

    /// The campaign files shipped in `assets/` parse, cover the paper's 13 x 5 grid, and
    /// their base configurations load with the sample size their names promise.
    #[test]
    fn shipped_campaign_files_parse() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
        // (file, disks, iteration after which relaxation and the velocity test apply, time
        // step at friction 12)
        for (file, disks, after, dt12) in [
            ("campaign1000.toml", 1000, 100, 1.25e-4),
            ("campaign5000.toml", 5000, 100, 6.25e-5),
            ("campaign5000_fast.toml", 5000, 30, 1.25e-4),
        ] {
            let text = std::fs::read_to_string(dir.join(file)).unwrap();
            let sweep: SweepFile = toml::from_str(&text).unwrap();
            assert_eq!((sweep.mu.len(), sweep.sigma3.len()), (13, 5), "{file}");
            let base = Config::load(dir.join(sweep.base.as_ref().expect("a base file"))).unwrap();
            assert_eq!(base.sample.disks, disks, "{file}");
            assert_eq!(base.solver.threads, 1, "{file}: one thread per test");
            assert_eq!(base.solver.gs_relax_after, after, "{file}");
            // All run friction 1.2 at the base's 0.5 ms and 3 at 0.25 ms; 12 at 0.125 ms,
            // or 0.0625 ms in the 5000-disk reference campaign (docs/results.md, "Overlaps at
            // high friction").
            let base_dt = base.solver.dt.si();
            assert_eq!(base_dt, 5e-4, "{file}");
            let steps = [1.2, 3.0, 12.0].map(|mu| sweep.dt(mu, base_dt));
            assert_eq!(steps, [5e-4, 2.5e-4, dt12], "{file}");
        }
    }
}
