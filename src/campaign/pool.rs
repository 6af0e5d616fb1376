//! The worker pool that runs a campaign's tests, and what one worker does with one test.

use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

use super::{Point, State, Sweep, check_point, point_config};
use crate::config::Config;
use crate::error::{Error, Result, RunFault};
use crate::interrupt::Cancel;
use crate::measure::summary::Summary;
use crate::model::Scene;
use crate::record::RunLock;
use crate::run::{self, Progress, Silent};

/// How a campaign runs.
#[derive(Clone, Debug)]
pub struct Options {
    /// Tests run at once (at least 1).
    pub jobs: usize,
    /// Run only the `shard.0`-th of `shard.1` disjoint parts of the grid (0 <= I < N):
    /// the tests whose index in the grid is I modulo N.
    pub shard: (usize, usize),
    /// Run nothing: find each test's state (and check a test found in its directory against
    /// the sweep's settings), one at a time, in the order a run would start them.
    pub dry_run: bool,
}

impl Default for Options {
    /// One test at a time per core, the whole grid, for real.
    fn default() -> Self {
        Options {
            jobs: std::thread::available_parallelism().map_or(1, |n| n.get()),
            shard: (0, 1),
            dry_run: false,
        }
    }
}

/// What became of one test.
#[derive(Clone, Debug)]
pub enum TestOutcome {
    /// Found finished: skipped.
    Skipped,
    /// Ran (or resumed) to its end.
    Finished(Box<Summary>),
    /// Dry run: what would be done, and whether another process runs the test now.
    Checked {
        /// The test's state.
        state: State,
        /// Whether another process holds the test's lock.
        busy: bool,
    },
    /// Another process runs the test (its lock is held): left to it, not failed.
    Elsewhere,
    /// Stopped by the cancellation at its checkpoint of `step` (0: before it began).
    Stopped {
        /// The checkpoint's step.
        step: u64,
    },
    /// Failed, with the error's message.
    Failed(String),
}

/// What a campaign reports while it goes. Lines are reported from the worker threads, in
/// the order things happen.
#[derive(Debug)]
#[non_exhaustive]
pub enum Event<'a> {
    /// The campaign begins.
    Planned {
        /// Tests in the whole grid.
        grid: usize,
        /// Tests in this shard.
        tests: usize,
        /// Tests run at once.
        jobs: usize,
        /// The campaign directory.
        out: &'a Path,
    },
    /// The campaign's list of tests could not be updated: a report will not name the tests
    /// that were never run.
    GridNotWritten(&'a Error),
    /// A worker starts, restarts or resumes a test.
    Starting {
        /// The test.
        point: &'a Point,
        /// Its state (new, to restart, to resume).
        state: State,
    },
    /// Another process prepares the sample `path`: this one waits for it.
    WaitingForSample(&'a Path),
    /// A test is done with, whatever became of it.
    Ended {
        /// The test.
        point: &'a Point,
        /// What became of it.
        outcome: &'a TestOutcome,
        /// Tests ended or found finished so far (this one included when it counts: not one
        /// stopped or left to another process).
        ended: usize,
        /// Tests in this shard.
        total: usize,
        /// Wall-clock hours since the campaign began.
        hours: f64,
    },
}

/// Watches a campaign: its events, and each test's progress. Called from several worker
/// threads at once.
pub trait Watch: Sync {
    /// Called for each campaign event.
    fn event(&self, event: &Event<'_>) {
        let _ = event;
    }

    /// The progress receiver of one test's run, on the worker that runs it.
    fn test(&self, point: &Point) -> Box<dyn Progress + '_> {
        let _ = point;
        Box::new(Silent)
    }
}

/// A [`Watch`] that ignores everything.
#[derive(Clone, Copy, Debug, Default)]
pub struct Quiet;

impl Watch for Quiet {}

/// What a campaign did in this shard.
#[derive(Clone, Debug, Default)]
pub struct CampaignOutcome {
    /// Tests in the whole grid.
    pub grid: usize,
    /// Tests in this shard.
    pub total: usize,
    /// Tests ended or found finished (failures included).
    pub ended: usize,
    /// Tests that failed, with why.
    pub failed: Vec<(PathBuf, String)>,
    /// Tests the cancellation stopped at a checkpoint or before they began.
    pub stopped: Vec<PathBuf>,
    /// Tests another process runs.
    pub elsewhere: Vec<PathBuf>,
    /// What stopped the campaign, if something did ([`Cancel::requested`]).
    pub cancelled: Option<i32>,
}

/// Runs the tests of `sweep` in this shard with `options.jobs` workers. Finished tests are
/// checked and skipped first, then the others start, those with the smallest time step
/// (the most steps) first. `cancel` stops the running tests at a checkpoint and starts no
/// more. The grid's list of tests is written into the campaign directory (except in a dry
/// run), whatever the shard, so that a report on any shard names the tests no shard ran.
///
/// A test that fails does not stop the others: the outcome lists it.
pub fn run(sweep: &Sweep, options: &Options, watch: &dyn Watch, cancel: &Cancel) -> Result<CampaignOutcome> {
    let (shard, of) = options.shard;
    if of == 0 || shard >= of {
        return Err(Error::invalid(
            "shard",
            format!("{shard}/{of}"),
            "I/N with 0 <= I < N",
        ));
    }
    // An `out` that is a file, a FIFO or a looping link is no campaign directory: said
    // once, up front, in a dry run too (each test failed with "Too many levels of symbolic
    // links", after a warning that said "File exists").
    crate::fsio::check_directory(&sweep.out)?;
    if !options.dry_run {
        let written = crate::fsio::create_dir_all(&sweep.out)
            .and_then(|()| super::grid::add_to_grid(&sweep.out, &sweep.names()));
        if let Err(e) = written {
            watch.event(&Event::GridNotWritten(&e));
        }
    }
    // Finished tests first: they are only checked and skipped, so the counts of the
    // progress lines (and of a stop) include them from the start. Then the tests with the
    // smallest time step, which take the most steps: started first, they leave the shorter
    // tests for the end, when fewer jobs remain to share the cores (longest first; the
    // sort is stable, so the grid's order holds at equal steps).
    let (mut mine, mut to_run): (Vec<Point>, Vec<Point>) = sweep
        .grid
        .iter()
        .enumerate()
        .filter(|(k, _)| k % of == shard)
        .map(|(_, p)| p.clone())
        .partition(|p| p.dir.join("summary.json").exists());
    to_run.sort_by(|a, b| a.dt.total_cmp(&b.dt));
    mine.append(&mut to_run);
    let jobs = options.jobs.max(1);
    watch.event(&Event::Planned {
        grid: sweep.grid.len(),
        tests: mine.len(),
        jobs,
        out: &sweep.out,
    });
    // The cores are shared between the tests running at once: each solver gets its share
    // (its sweeps wait for each other at barriers, which must not compete for one core),
    // unless the base configuration sets its team size.
    let mut base = sweep.base.clone();
    base.solver.backend = crate::config::Backend::Cpu;
    if base.solver.threads == 0 {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        base.solver.threads = (cores / jobs).max(1);
    }
    let started = Instant::now();
    let total = mine.len();
    let queue = Mutex::new(mine.into_iter().collect::<VecDeque<Point>>());
    let samples: Mutex<Vec<(u64, Scene)>> = Mutex::new(Vec::new());
    let done = Mutex::new(CampaignOutcome {
        grid: sweep.grid.len(),
        total,
        ..Default::default()
    });
    // A dry run checks the tests one by one, so that it lists them in the order a run
    // would start them (with several workers, a slow check, such as reading a long record,
    // would move its line after quicker ones).
    let workers = if options.dry_run { 1 } else { jobs };
    std::thread::scope(|s| {
        for _ in 0..workers {
            s.spawn(|| {
                loop {
                    // Taken in a statement of its own: the guard of a `while let`
                    // scrutinee lives through the loop body, which ran the tests one at a
                    // time whatever the jobs said.
                    if cancel.requested().is_some() {
                        break;
                    }
                    let next = queue.lock().expect("queue").pop_front();
                    let Some(p) = next else { break };
                    let mut progress = watch.test(&p);
                    let outcome = if options.dry_run {
                        check_point(&point_config(&base, &p), &p).map(|state| TestOutcome::Checked {
                            state,
                            busy: RunLock::held_elsewhere(&p.dir),
                        })
                    } else {
                        run_point(&base, &sweep.out, &p, &samples, &mut *progress, watch, cancel)
                    };
                    drop(progress);
                    let outcome = match outcome {
                        Ok(o) => o,
                        Err(Error::Interrupted { step, .. }) => TestOutcome::Stopped { step },
                        Err(e) => TestOutcome::Failed(e.to_string()),
                    };
                    let mut d = done.lock().expect("progress");
                    match &outcome {
                        TestOutcome::Elsewhere => d.elsewhere.push(p.dir.clone()),
                        TestOutcome::Stopped { .. } => d.stopped.push(p.dir.clone()),
                        TestOutcome::Failed(e) => {
                            d.ended += 1;
                            d.failed.push((p.dir.clone(), e.clone()));
                        }
                        _ => d.ended += 1,
                    }
                    watch.event(&Event::Ended {
                        point: &p,
                        outcome: &outcome,
                        ended: d.ended,
                        total,
                        hours: started.elapsed().as_secs_f64() / 3600.0,
                    });
                }
            });
        }
    });
    let mut outcome = done.into_inner().expect("progress");
    outcome.cancelled = cancel.requested();
    Ok(outcome)
}

/// Runs, resumes or skips one test.
fn run_point(
    base: &Config,
    out: &Path,
    p: &Point,
    samples: &Mutex<Vec<(u64, Scene)>>,
    progress: &mut dyn Progress,
    watch: &dyn Watch,
    cancel: &Cancel,
) -> Result<TestOutcome> {
    let config = point_config(base, p);
    // Held until the test ends, so that a second sweep on this directory leaves it alone.
    // A test whose lock another process holds is that process's to run (two sweeps on one
    // directory, or a biaxial --resume beside the sweep): skipped, not failed.
    // A refusal is tried once more: the other process may have ended in between (its test
    // is then found finished, or resumed here).
    let acquire = || RunLock::acquire(&p.dir);
    let _lock = match acquire().or_else(|_| acquire()) {
        Ok(lock) => lock,
        Err(_) if RunLock::held_elsewhere(&p.dir) => return Ok(TestOutcome::Elsewhere),
        Err(e) => return Err(e),
    };
    let state = check_point(&config, p)?;
    if state == State::Finished {
        return Ok(TestOutcome::Skipped);
    }
    watch.event(&Event::Starting { point: p, state });
    let outcome = if state == State::Resumable {
        run::run_resume(&p.dir, Some(crate::config::Backend::Cpu), progress, cancel)?
    } else {
        config.validate()?;
        // The sample is prepared with the base configuration's settings, whichever test
        // asks for it first (its time step may be one of `dt_by_friction`).
        let mut prepare = base.clone();
        prepare.sample.seed = p.seed;
        let scene = sample(&prepare, out, p.seed, samples, watch, cancel)?;
        // A record without a checkpoint may have a summary beside it that is not its own
        // (check_point found it did not stand): gone before the new record takes its place.
        run::clear_results(&p.dir)?;
        run::run_fresh(&config, &p.dir, Some(scene), progress, cancel)?
    };
    Ok(TestOutcome::Finished(Box::new(outcome.summary)))
}

/// The compacted sample of `seed`: from memory, from `out/samples/seedS.bin`, or prepared
/// now (once: a second thread asking for the same seed waits on the mutex, a second process,
/// another shard, waits on the sample's file lock and then reads the finished file).
fn sample(
    config: &Config,
    out: &Path,
    seed: u64,
    samples: &Mutex<Vec<(u64, Scene)>>,
    watch: &dyn Watch,
    cancel: &Cancel,
) -> Result<Scene> {
    let mut cache = samples.lock().expect("samples");
    if let Some((_, s)) = cache.iter().find(|(k, _)| *k == seed) {
        return Ok(s.clone());
    }
    let path = out.join("samples").join(format!("seed{seed}.bin"));
    let dir = path.parent().expect("has a parent");
    crate::fsio::create_dir_all(dir)?;
    // Held while the sample is looked for and, when absent, prepared and written: the file
    // appears whole (temporary name, fsync, rename) and only once.
    let _lock = crate::protocol::sample_file::SampleLock::acquire(&path, || {
        watch.event(&Event::WaitingForSample(&path))
    })?;
    let scene = if path.exists() {
        let sample = run::read_sample(&path)?;
        // A samples directory left by a campaign with other sample settings must not
        // stand in for this one's.
        let differ = run::sample_differences(config, &sample.params);
        if !differ.is_empty() {
            return Err(Error::Run {
                path: path.clone(),
                fault: RunFault::OtherSettings,
                message: format!(
                    "{} was prepared with other settings than this campaign's ({}): move it \
                     away or use another output directory",
                    path.display(),
                    differ.join("; ")
                ),
                remedy: None,
            });
        }
        sample.scene
    } else {
        run::prepare(config, &path, &mut Silent, cancel)?.scene
    };
    cache.push((seed, scene.clone()));
    Ok(scene)
}
