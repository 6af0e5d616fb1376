//! How the commands that run tests show their progress: one implementation of
//! [`crate::run::Progress`], a bar on a terminal and plain lines otherwise (CI, logs).

use std::io::IsTerminal;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

use crate::analysis::report::OVERLAP_BOUND_REL;
use crate::measure::SeriesRow;
use crate::run::Event;

pub use crate::run::{open_backend, snapshot};

/// How a test shows its progress.
#[derive(Clone, Debug)]
pub enum Progress {
    /// Nothing but the warnings that a resume could not use its whole record.
    Quiet,
    /// A test on its own: a bar on a terminal, a line every 5 s otherwise (CI, logs), and
    /// its other messages (backend, deposition, phase ends).
    Own,
    /// One test of a campaign, whose other messages the sweep replaces with its own: on a
    /// terminal, `bar` (the test's line in the campaign's display); otherwise a line every
    /// `every_s` seconds starting with `label`, so that a log shows where an hour-long
    /// test stands.
    Campaign {
        /// Names the test in log lines.
        label: String,
        /// The test's bar in the campaign's display.
        bar: Option<ProgressBar>,
        /// Seconds between two log lines.
        every_s: f64,
    },
}

impl Progress {
    /// Whether the messages around the progress display (backend, deposition, phase ends,
    /// resume) are left out.
    pub fn quiet(&self) -> bool {
        !matches!(self, Progress::Own)
    }

    /// The display of a test's events in this mode.
    pub fn display(&self) -> Display {
        Display {
            mode: self.clone(),
            bar: None,
            last_line: Instant::now(),
            compression_start: None,
            started: false,
        }
    }
}

/// Shows a test's [`Event`]s as its [`Progress`] mode says.
pub struct Display {
    mode: Progress,
    bar: Option<ProgressBar>,
    last_line: Instant,
    /// Wall-clock seconds and axial strain at this part's first compression row: the rate
    /// behind the plain lines' estimate of the time left.
    compression_start: Option<(f64, f64)>,
    /// Whether the steps (or the replay of a resumed record) have begun.
    started: bool,
}

impl Display {
    /// Opens the bar, and starts the clock of the plain lines, as the steps begin.
    fn start(&mut self) {
        if std::mem::replace(&mut self.started, true) {
            return;
        }
        self.last_line = Instant::now();
        self.bar = match &self.mode {
            Progress::Own if std::io::stderr().is_terminal() => {
                let b = ProgressBar::new(1000);
                b.set_style(
                    ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {msg} (ETA {eta})")
                        .expect("valid template"),
                );
                Some(b)
            }
            Progress::Campaign { bar, .. } => bar.clone(),
            _ => None,
        };
    }

    /// Prefix and interval of the plain progress lines; none when they are off.
    fn lines(&self) -> Option<(String, f64)> {
        match &self.mode {
            _ if self.bar.is_some() => None,
            Progress::Own => Some((String::new(), 5.0)),
            Progress::Campaign { label, every_s, .. } => Some((format!("{label}: "), *every_s)),
            Progress::Quiet => None,
        }
    }

    /// Prints a line above the bar, or on stderr.
    fn say(&self, line: String) {
        match &self.bar {
            Some(b) => b.println(line),
            None => eprintln!("{line}"),
        }
    }

    fn row(&mut self, row: &SeriesRow, strain_end: f64) {
        let msg = format!(
            "{:<11} t {:8.3} s  strain {:.4}  sigma1 {:7.3} MPa  dV/V0 {:+.4}  iterations/step {:6.1}",
            row.phase,
            row.time_s,
            row.strain_axial,
            row.sigma1_pa / 1e6,
            row.volumetric_strain,
            row.iterations
        );
        if let Some(b) = &self.bar {
            if row.phase == "compression" {
                b.set_position((1000.0 * row.strain_axial / strain_end).min(1000.0) as u64);
            }
            b.set_message(msg);
        } else if let Some((label, every)) = self.lines() {
            if row.phase == "compression" && self.compression_start.is_none() {
                self.compression_start = Some((row.wall_s, row.strain_axial));
            }
            if self.last_line.elapsed().as_secs_f64() >= every {
                let left = self
                    .compression_start
                    .and_then(|(w0, e0)| time_left(w0, e0, row.wall_s, row.strain_axial, strain_end))
                    .map_or(String::new(), |s| format!("  about {} left", duration(s)));
                eprintln!("{label}[{:7.1} s] {msg}{left}", row.wall_s);
                self.last_line = Instant::now();
            }
        }
    }
}

impl crate::run::Progress for Display {
    fn event(&mut self, event: &Event<'_>) {
        let quiet = self.mode.quiet();
        match event {
            Event::Deposited { disks, report: r } if !quiet => eprintln!(
                "deposited {disks} disks in {:.2} s: packing fraction {:.3}, coordination {:.2}, \
                 D10 {:.2} m, D60 {:.2} m, height/width {:.2}",
                r.seconds, r.packing_fraction, r.coordination, r.d10_m, r.d60_m, r.aspect
            ),
            Event::FellBack {
                file,
                why,
                step,
                phase,
                strain,
            } => eprintln!(
                "warning: {}: {why}; falling back to the last intact checkpoint before the damage: \
                 step {step} (phase {}{}); the run is recomputed from there",
                file.display(),
                phase.name(),
                strain.map_or(String::new(), |e| format!(", axial strain {e:.5}"))
            ),
            Event::SummaryRewritten { dir, fault } => eprintln!(
                "{}: the record is complete but its summary.json {fault}: written again from the \
                 record",
                dir.display()
            ),
            Event::Resuming {
                dir,
                step,
                time_s,
                phase,
            } => {
                self.start();
                if !quiet {
                    eprintln!(
                        "resuming {} from step {step} (t = {time_s:.3} s, phase {})",
                        dir.display(),
                        phase.name()
                    );
                }
            }
            Event::Running { backend, dir } => {
                if !quiet {
                    eprintln!("running on {backend} -> {}", dir.display());
                }
                self.start();
            }
            Event::Row { row, strain_end } => self.row(row, *strain_end),
            Event::OverlapBound { row, within_half } if !matches!(self.mode, Progress::Quiet) => {
                let label = self.lines().map_or(String::new(), |(l, _)| l);
                self.say(overlap_warning(&label, row, *within_half));
            }
            Event::PhaseEnd(end) if !quiet => self.say(format!(
                "{} ended at t = {:.3} s (step {}): {}, kinetic ratio {:.2e}, force imbalance {:.2e}",
                end.phase.name(),
                end.time_s,
                end.step,
                match (end.phase, end.settled) {
                    (crate::protocol::Phase::Compression, _) => "target strain reached",
                    (_, true) => "settled",
                    (_, false) => "NOT settled (time cap reached)",
                },
                end.kinetic_ratio,
                end.force_imbalance
            )),
            Event::StepsEnded => {
                if let Some(b) = &self.bar {
                    b.finish_and_clear();
                }
            }
            Event::NoShearBands(e) if !quiet => eprintln!("no shear-band analysis: {e}"),
            _ => {}
        }
    }
}

/// The warning given once when the largest overlap passes docs/method.md's bound, with the
/// remedies its growth points to.
fn overlap_warning(label: &str, row: &SeriesRow, within_half: Option<(u64, f64)>) -> String {
    let half = 0.5 * OVERLAP_BOUND_REL;
    let since = match within_half {
        Some((step, strain)) => format!(
            "it was within {:.1}% {} steps earlier (axial strain {strain:.4})",
            100.0 * half,
            row.step.saturating_sub(step)
        ),
        None => format!(
            "no row since this run (or its resume) started was within {:.1}%",
            100.0 * half
        ),
    };
    format!(
        "{label}warning: the largest overlap passed {:.0}% of r_min (docs/method.md's bound): \
         {:.2}% at step {} ({}, axial strain {:.4}); {since}. A contact that closes fast \
         within a step needs a smaller solver.dt; one that sinks slowly under load over \
         many steps (the solver's residual) needs further convergence, which a smaller \
         step gives only in part and solver.deep_overlap (say 0.005) gives to the deep \
         contacts alone (`cdlab overlaps RUN` names the pair from the snapshots; docs/results.md, \
         \"Overlaps at high friction\")",
        OVERLAP_BOUND_REL * 100.0,
        row.overlap_max_rel * 100.0,
        row.step,
        row.phase,
        row.strain_axial
    )
}

/// Seconds left to axial strain `end` at the mean rate since (`w0` s, strain `e0`), once
/// the compression has gone a measurable way (none before).
fn time_left(w0: f64, e0: f64, wall: f64, strain: f64, end: f64) -> Option<f64> {
    let (done, spent) = (strain - e0, wall - w0);
    (done > 1e-4 && spent > 0.0).then(|| (end - strain).max(0.0) * spent / done)
}

/// A duration in the unit that reads best: seconds, minutes or hours.
fn duration(s: f64) -> String {
    if s < 120.0 {
        format!("{s:.0} s")
    } else if s < 7200.0 {
        format!("{:.0} min", s / 60.0)
    } else {
        format!("{:.1} h", s / 3600.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The estimate extrapolates the mean rate of this part: 0.01 of strain in 100 s leaves
    /// 800 s for the remaining 0.08; none before the strain has moved, none past the end.
    #[test]
    fn time_left_follows_the_mean_rate_of_the_compression() {
        assert_eq!(time_left(100.0, 0.01, 200.0, 0.02, 0.1), Some(800.0));
        assert_eq!(time_left(100.0, 0.01, 100.5, 0.01, 0.1), None);
        assert_eq!(time_left(100.0, 0.01, 300.0, 0.11, 0.1), Some(0.0));
        assert_eq!(duration(45.0), "45 s");
        assert_eq!(duration(1800.0), "30 min");
        assert_eq!(duration(9000.0), "2.5 h");
    }
}
