//! `cdlab sweep FILE.toml`: the friction x pressure campaign of [`crate::campaign`], with a
//! display: on a terminal a bar of finished tests and one line per running test, in a log
//! each test's start and end and a line per running test every `--log-every` seconds.
//! `--shard I/N` runs the I-th of N disjoint parts (0 <= I < N).

use std::io::IsTerminal;
use std::path::PathBuf;
use std::sync::OnceLock;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

use crate::analysis::report::tests;
use crate::campaign::{CampaignOutcome, Event, Options, Point, State, Sweep, TestOutcome, Watch};
use crate::error::{Error, Result};

use super::run::{Display, Progress};

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
    let cancel = crate::interrupt::install();
    if !(args.log_every.is_finite() && args.log_every >= 0.0) {
        return Err(Error::invalid("--log-every", args.log_every, "seconds >= 0"));
    }
    let shard = args
        .shard
        .as_deref()
        .map(parse_shard)
        .transpose()?
        .unwrap_or((0, 1));
    let sweep = Sweep::load(&args.file)?;
    let options = Options {
        jobs: args.jobs.unwrap_or(Options::default().jobs).max(1),
        shard,
        dry_run: args.dry_run,
    };
    let display = CampaignDisplay::new(args.log_every);
    let outcome = crate::campaign::run(&sweep, &options, &display, &cancel)?;
    if let Some(b) = display.overall.get() {
        b.finish_and_clear();
    }
    conclude(&outcome, &sweep, args.dry_run)
}

/// The end of a campaign: its closing line, and the error of a stopped or failed one.
fn conclude(o: &CampaignOutcome, sweep: &Sweep, dry_run: bool) -> Result<()> {
    let (ended, total) = (o.ended, o.total);
    if let Some(signal) = o.cancelled {
        eprintln!(
            "sweep: stopped by {}: {ended} of {total} tests ended or were found finished ({} \
             failed), {} stopped at a checkpoint or before starting, {} running in another \
             process, {} not started; the same command resumes the campaign",
            crate::interrupt::signal_name(signal),
            o.failed.len(),
            o.stopped.len(),
            o.elsewhere.len(),
            total - ended - o.stopped.len() - o.elsewhere.len()
        );
        return Err(Error::Interrupted { signal, step: 0 });
    }
    if o.failed.is_empty() && dry_run {
        eprintln!("sweep: dry run, nothing was run; {} checked", tests(total));
    } else if o.failed.is_empty() && !o.elsewhere.is_empty() {
        eprintln!(
            "sweep: {ended} of this shard's {} finished, {} running in another process \
             (not failed: that process ends them); `cdlab report {}` analyses the campaign \
             once it has",
            tests(total),
            o.elsewhere.len(),
            sweep.out.display()
        );
    } else if o.failed.is_empty() {
        let which = if total == 1 {
            "the 1 test".to_string()
        } else {
            format!("all {total} tests")
        };
        eprintln!(
            "sweep: {which} of this shard finished; `cdlab report {}` analyses the campaign",
            sweep.out.display()
        );
    } else {
        return Err(Error::Campaign {
            path: sweep.out.clone(),
            tests: o.failed.clone(),
            message: format!(
                "{} of {total} tests failed (the others finished): {:?}",
                o.failed.len(),
                o.failed
            ),
        });
    }
    Ok(())
}

/// The campaign's display: on a terminal, a bar of finished tests and one line per running
/// test; in a log, each test's start and end, and a line per running test every
/// `log_every` seconds.
struct CampaignDisplay {
    multi: Option<MultiProgress>,
    /// The bar of finished tests, set once the campaign knows its length.
    overall: OnceLock<ProgressBar>,
    log_every: f64,
}

impl CampaignDisplay {
    fn new(log_every: f64) -> Self {
        let multi = std::io::stderr().is_terminal().then(MultiProgress::new);
        CampaignDisplay {
            multi,
            overall: OnceLock::new(),
            log_every,
        }
    }

    fn say(&self, line: &str) {
        match &self.multi {
            Some(m) => {
                let _ = m.println(line);
            }
            None => eprintln!("{line}"),
        }
    }

    /// The one-line result of a test.
    fn result(&self, outcome: &TestOutcome) -> String {
        match outcome {
            TestOutcome::Skipped => "already finished, skipped".into(),
            TestOutcome::Checked { state, busy } => {
                let note = if *busy {
                    " (running now in another process)"
                } else {
                    ""
                };
                format!("{}{note}", state.dry_run())
            }
            TestOutcome::Finished(s) => format!(
                "peak sigma1 {:.3} MPa, residual {}, {:.0} s",
                s.sigma1_peak_mpa,
                s.sigma1_residual_mpa.map_or(
                    format!(
                        "n/a (ended before strain {:.3})",
                        crate::measure::derived::RESIDUAL_MIN_END
                    ),
                    |v| format!("{v:.3} MPa")
                ),
                s.wall_time_s
            ),
            TestOutcome::Failed(e) => format!("FAILED: {e}"),
            TestOutcome::Elsewhere | TestOutcome::Stopped { .. } => String::new(),
        }
    }
}

/// One running test's line in the campaign's display, removed when the test is done.
struct TestLine<'a> {
    display: Display,
    multi: Option<&'a MultiProgress>,
    bar: Option<ProgressBar>,
}

impl crate::run::Progress for TestLine<'_> {
    fn event(&mut self, event: &crate::run::Event<'_>) {
        self.display.event(event);
    }
}

impl Drop for TestLine<'_> {
    fn drop(&mut self) {
        if let (Some(m), Some(b)) = (self.multi, &self.bar) {
            m.remove(b);
        }
    }
}

impl Watch for CampaignDisplay {
    fn event(&self, event: &Event<'_>) {
        match event {
            Event::Planned {
                grid,
                tests: mine,
                jobs,
                out,
            } => {
                eprintln!(
                    "sweep: {} in the grid, {mine} in this shard, {jobs} at a time -> {}",
                    tests(*grid),
                    out.display()
                );
                // Only now does the campaign's bar know its length; `overall` is set once.
                if let Some(m) = &self.multi {
                    let b = m.add(ProgressBar::new(*mine as u64));
                    b.set_style(
                        ProgressStyle::with_template(
                            "campaign [{elapsed_precise}] {bar:30} {pos}/{len} tests",
                        )
                        .expect("valid template"),
                    );
                    let _ = self.overall.set(b);
                }
            }
            Event::GridNotWritten(e) => eprintln!(
                "warning: the campaign's list of tests ({}) was not updated: {e}; the report \
                 will not name the tests that were never run",
                crate::analysis::report::GRID_FILE
            ),
            Event::Starting { point, state } => {
                let how = match state {
                    State::Resumable => "resuming",
                    State::Restart => "restarting (its record holds no checkpoint yet)",
                    _ => "starting",
                };
                self.say(&format!("sweep: {how} {}", point.dir.display()));
            }
            Event::WaitingForSample(path) => eprintln!(
                "sweep: another process is preparing {}; waiting for it",
                path.display()
            ),
            Event::Ended {
                point,
                outcome,
                ended,
                total,
                hours,
            } => match outcome {
                TestOutcome::Elsewhere => self.say(&format!(
                    "{}: running in another process, skipped (its results appear when that \
                     process ends it)",
                    point.dir.display()
                )),
                TestOutcome::Stopped { step } => {
                    let at = if *step > 0 {
                        format!("stopped at its checkpoint of step {step}")
                    } else {
                        "stopped before its test began".to_string()
                    };
                    self.say(&format!("{}: {at}", point.dir.display()));
                }
                _ => {
                    if let Some(b) = self.overall.get() {
                        b.inc(1);
                    }
                    self.say(&format!(
                        "[{ended}/{total}, campaign {hours:.2} h] {}: {}",
                        point.dir.display(),
                        self.result(outcome)
                    ));
                }
            },
        }
    }

    fn test(&self, point: &Point) -> Box<dyn crate::run::Progress + '_> {
        let label = point
            .dir
            .file_name()
            .map_or(String::new(), |n| n.to_string_lossy().into());
        let bar = self.multi.as_ref().map(|m| {
            let b = m.add(ProgressBar::new(1000));
            b.set_style(
                ProgressStyle::with_template("  {prefix:<22} {bar:20} {msg}").expect("valid template"),
            );
            b.set_prefix(label.clone());
            b
        });
        let display = Progress::Campaign {
            label,
            bar: bar.clone(),
            every_s: self.log_every,
        }
        .display();
        Box::new(TestLine {
            display,
            multi: self.multi.as_ref(),
            bar,
        })
    }
}
