//! The display of `cdlab sweep`: one implementation of [`crate::campaign::Watch`].

use std::io::IsTerminal;
use std::sync::OnceLock;

use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

use crate::analysis::report::tests;
use crate::campaign::{Event, Point, State, TestOutcome, Watch};

use super::run::{Display, Progress};

/// The campaign's display: on a terminal, a bar of finished tests and one line per running
/// test; in a log, each test's start and end, and a line per running test every
/// `log_every` seconds.
pub struct CampaignDisplay {
    multi: Option<MultiProgress>,
    /// The bar of finished tests, set once the campaign knows its length.
    pub overall: OnceLock<ProgressBar>,
    log_every: f64,
}

impl CampaignDisplay {
    /// The display of a campaign whose tests log a line every `log_every` seconds.
    pub fn new(log_every: f64) -> Self {
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
