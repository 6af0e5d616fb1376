//! How the commands that run tests show their progress: one implementation of
//! [`crate::run::Progress`], a bar on a terminal and plain lines otherwise (CI, logs). This
//! file holds the modes and the bar; the messages of the other events are in
//! `cli/run_events.rs`.

use std::io::IsTerminal;
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};

use crate::measure::SeriesRow;
use crate::run::time_left;

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
            settle: SettleTrack::default(),
        }
    }
}

/// Shows a test's [`crate::run::Event`]s as its [`Progress`] mode says.
pub struct Display {
    pub(super) mode: Progress,
    pub(super) bar: Option<ProgressBar>,
    last_line: Instant,
    /// Wall-clock seconds and axial strain at this part's first compression row: the rate
    /// behind the plain lines' estimate of the time left.
    compression_start: Option<(f64, f64)>,
    /// Whether the steps (or the replay of a resumed record) have begun.
    started: bool,
    /// The equilibrium checks of the current preparation phase.
    settle: SettleTrack,
}

/// What a display keeps of a preparation phase to estimate its time left.
#[derive(Debug, Default)]
struct SettleTrack {
    phase: Option<crate::protocol::Phase>,
    /// `(phase time s, kinetic ratio)` of each check.
    checks: Vec<(f64, f64)>,
    /// `(wall-clock s, phase time s)` of each check: the rate that turns simulated time
    /// left into wall time.
    clock: Vec<(f64, f64)>,
    /// Iterations per step and wall-clock seconds of the last row (each check follows its
    /// window's row).
    iterations: f64,
    /// See `iterations`.
    wall_s: f64,
}

impl SettleTrack {
    /// Wall seconds per simulated second over the last [`crate::run::SETTLE_FIT_CHECKS`]
    /// checks; none before two.
    fn wall_per_sim(&self) -> Option<f64> {
        let recent = &self.clock[self.clock.len().saturating_sub(crate::run::SETTLE_FIT_CHECKS + 1)..];
        let (a, b) = (recent.first()?, recent.last()?);
        (b.1 > a.1).then(|| (b.0 - a.0) / (b.1 - a.1))
    }
}

impl Display {
    /// Opens the bar, and starts the clock of the plain lines, as the steps begin.
    pub(super) fn start(&mut self) {
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
    pub(super) fn lines(&self) -> Option<(String, f64)> {
        match &self.mode {
            _ if self.bar.is_some() => None,
            Progress::Own => Some((String::new(), own_line_interval())),
            Progress::Campaign { label, every_s, .. } => Some((format!("{label}: "), *every_s)),
            Progress::Quiet => None,
        }
    }

    /// Prints a line above the bar, or on stderr.
    pub(super) fn say(&self, line: String) {
        match &self.bar {
            Some(b) => b.println(line),
            None => note!("{line}"),
        }
    }

    /// Shows a series row: on the bar, or as a plain line every so often with the time
    /// left.
    pub(super) fn row(&mut self, row: &SeriesRow, strain_end: f64) {
        let msg = format!(
            "{:<11} t {:8.3} s  strain {:.4}  sigma1 {:7.3} MPa  dV/V0 {:+.4}  iterations/step {:6.1}",
            row.phase,
            row.time_s,
            row.strain_axial,
            row.sigma1_pa / 1e6,
            row.volumetric_strain,
            row.iterations
        );
        self.settle.iterations = row.iterations;
        self.settle.wall_s = row.wall_s;
        if let Some(b) = &self.bar {
            if row.phase == "compression" {
                b.set_position((1000.0 * row.strain_axial / strain_end).min(1000.0) as u64);
            }
            b.set_message(msg);
        } else if let Some((label, every)) = self.lines() {
            if row.phase == "compression" && self.compression_start.is_none() {
                self.compression_start = Some((row.wall_s, row.strain_axial));
            }
            // A preparation phase's lines come with its equilibrium checks (`settling`).
            if row.phase != "compression" {
                return;
            }
            if self.last_line.elapsed().as_secs_f64() >= every {
                let left = self
                    .compression_start
                    .and_then(|(w0, e0)| time_left(w0, e0, row.wall_s, row.strain_axial, strain_end))
                    .map_or(String::new(), |s| format!("  about {} left", duration(s)));
                note!("{label}[{:7.1} s] {msg}{left}", row.wall_s);
                self.last_line = Instant::now();
            }
        }
    }
}

impl Display {
    /// Shows a preparation phase's equilibrium check: where its criteria stand, and the
    /// time left as [`crate::run::settle_time_left`] estimates it, bounded by the phase's
    /// time cap.
    pub(super) fn settling(&mut self, c: &crate::protocol::Settling) {
        if self.settle.phase != Some(c.phase) {
            self.settle = SettleTrack {
                phase: Some(c.phase),
                iterations: self.settle.iterations,
                wall_s: self.settle.wall_s,
                ..Default::default()
            };
        }
        let now = self.settle.wall_s;
        self.settle.checks.push((c.phase_time_s, c.kinetic_ratio));
        self.settle.clock.push((now, c.phase_time_s));
        let (estimate, cap) =
            crate::run::settle_time_left(&self.settle.checks, c.kinetic_threshold, c.max_time_s);
        let left = match (self.settle.wall_per_sim(), estimate) {
            (Some(rate), Some(e)) => format!(
                "  about {} left (at most {}: the {:.0} s cap)",
                duration(e * rate),
                duration(cap * rate),
                c.max_time_s
            ),
            (Some(rate), None) => format!(
                "  at most {} left (the {:.0} s cap)",
                duration(cap * rate),
                c.max_time_s
            ),
            (None, _) => String::new(),
        };
        // The creep is the other way to settle, once enough checks have come to measure it.
        let creep = match c.creep {
            Some(r) if c.creep_limit > 0.0 => format!("  creep {r:.1e}/s (or below {:.0e}/s)", c.creep_limit),
            _ => String::new(),
        };
        let msg = format!(
            "{:<11} t {:8.3} s  kinetic ratio {:.1e} (ends below {:.0e}){creep}  wall force off by {:.2}% (below {:.2}%)  iterations/step {:6.1}",
            c.phase.name(),
            c.time_s,
            c.kinetic_ratio,
            c.kinetic_threshold,
            100.0 * c.imbalance,
            100.0 * c.imbalance_limit,
            self.settle.iterations
        );
        if let Some(b) = &self.bar {
            b.set_message(format!("{msg}{left}"));
        } else if let Some((label, every)) = self.lines()
            && self.last_line.elapsed().as_secs_f64() >= every
        {
            note!("{label}[{now:7.1} s] {msg}{left}");
            self.last_line = Instant::now();
        }
    }
}

/// Seconds between two plain progress lines of a command run on its own:
/// `CDLAB_PROGRESS_EVERY` when it holds a number >= 0, else 5 (docs/outputs.md, "Progress").
fn own_line_interval() -> f64 {
    std::env::var("CDLAB_PROGRESS_EVERY")
        .ok()
        .and_then(|v| v.trim().parse::<f64>().ok())
        .filter(|s| *s >= 0.0 && s.is_finite())
        .unwrap_or(5.0)
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

    /// Durations read in the unit that suits them.
    #[test]
    fn durations_read_in_seconds_minutes_or_hours() {
        assert_eq!(duration(45.0), "45 s");
        assert_eq!(duration(1800.0), "30 min");
        assert_eq!(duration(9000.0), "2.5 h");
    }
}
