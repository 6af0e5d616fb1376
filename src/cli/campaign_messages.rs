//! The messages of `cdlab sweep`'s display: the plan, each test's start and end with its
//! result, the warnings of the campaign.

use indicatif::{ProgressBar, ProgressStyle};

use super::campaign_display::CampaignDisplay;
use crate::campaign::tests;
use crate::campaign::{Event, State, TestOutcome};

impl CampaignDisplay {
    /// Shows a campaign event: its plan, each test's start and end with its result.
    pub(super) fn show(&self, event: &Event<'_>) {
        match event {
            Event::Planned {
                grid,
                tests: mine,
                jobs,
                out,
            } => {
                note!(
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
            Event::GridNotWritten(e) => note!(
                "warning: the campaign's list of tests ({}) was not updated: {e}; the report \
                 will not name the tests that were never run",
                crate::campaign::GRID_FILE
            ),
            Event::Starting { point, state } => {
                let how = match state {
                    State::Resumable => "resuming",
                    State::Restart => "restarting (its record holds no checkpoint yet)",
                    _ => "starting",
                };
                self.say(&format!("sweep: {how} {}", point.dir.display()));
            }
            Event::WaitingForSample(path) => note!(
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
