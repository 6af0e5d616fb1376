//! Shared pieces of the commands that run tests: choosing the backend, the observer that
//! records and shows progress.

use std::io::IsTerminal;
use std::time::Instant;

use glam::DVec2;
use indicatif::{ProgressBar, ProgressStyle};

use crate::backend::{Backend, ContactRecord, CpuBackend};
use crate::config::{Backend as Choice, Config};
use crate::engine::StepParams;
use crate::error::Result;
use crate::measure::SeriesRow;
use crate::model::Scene;
use crate::protocol::{Observer, PhaseEnd};
use crate::record::{ContactRecord as SnapContact, DiskRecord, Recorder, Snapshot};

/// Opens the backend the configuration asks for. `auto` takes the GPU path only on a
/// hardware adapter (on the software one the CPU path is faster) and says which it took.
pub fn open_backend(config: &Config, scene: Scene, params: StepParams) -> Result<Box<dyn Backend>> {
    let gpu = match config.solver.backend {
        Choice::Cpu => false,
        Choice::Gpu => true,
        Choice::Auto => crate::gpu::device::list_adapters()
            .iter()
            .any(|a| a.device_type != "Cpu"),
    };
    if gpu {
        Ok(Box::new(crate::gpu::backend::GpuBackend::new(scene, params)?))
    } else {
        Ok(Box::new(CpuBackend::new(scene, params)?))
    }
}

/// How a test shows its progress.
#[derive(Clone, Debug)]
pub enum Progress {
    /// Nothing.
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
}

/// Records every row, snapshot and checkpoint, and shows progress: a bar on a terminal,
/// plain lines every few seconds otherwise (CI, logs).
pub struct Recording {
    /// The MCAP and CSV writer.
    pub recorder: Recorder,
    /// Rows received (the summary is derived from them).
    pub rows: Vec<SeriesRow>,
    /// Phase ends received.
    pub ends: Vec<PhaseEnd>,
    strain_end: f64,
    bar: Option<ProgressBar>,
    started: Instant,
    /// Wall-clock seconds of the run's earlier parts (a resumed run's replayed rows).
    wall_before: f64,
    last_line: Instant,
    /// Label and interval of the plain progress lines; none when they are off.
    lines: Option<(String, f64)>,
    /// Wall-clock seconds and axial strain at this part's first compression row: the rate
    /// behind the plain lines' estimate of the time left.
    compression_start: Option<(f64, f64)>,
    /// Whether warnings are shown (all but `Progress::Quiet`), and whether the overlap
    /// warning has been given.
    warn: bool,
    overlap_warned: bool,
    /// Step and axial strain of the last row whose largest overlap was within half the
    /// bound: how fast it then grew tells which remedy the warning's reader needs.
    overlap_low: Option<(u64, f64)>,
    quiet: bool,
}

impl Recording {
    /// A recording observer showing its progress as `progress` says; its wall clock runs
    /// from `started` (before the deposition or the reading of a record it follows).
    pub fn new(recorder: Recorder, strain_end: f64, progress: &Progress, started: Instant) -> Self {
        let terminal = std::io::stderr().is_terminal();
        let (bar, lines) = match progress {
            Progress::Quiet => (None, None),
            Progress::Own if terminal => {
                let b = ProgressBar::new(1000);
                b.set_style(
                    ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:30} {msg} (ETA {eta})")
                        .expect("valid template"),
                );
                (Some(b), None)
            }
            Progress::Own => (None, Some((String::new(), 5.0))),
            Progress::Campaign { bar: Some(b), .. } => (Some(b.clone()), None),
            Progress::Campaign {
                label,
                bar: None,
                every_s,
            } => (None, Some((format!("{label}: "), *every_s))),
        };
        Recording {
            recorder,
            rows: Vec::new(),
            ends: Vec::new(),
            strain_end,
            bar,
            started,
            wall_before: 0.0,
            last_line: Instant::now(),
            lines,
            compression_start: None,
            warn: !matches!(progress, Progress::Quiet),
            overlap_warned: false,
            overlap_low: None,
            quiet: progress.quiet(),
        }
    }

    /// Wall-clock seconds of the run so far, its earlier parts included.
    pub fn wall_s(&self) -> f64 {
        self.wall_before + self.started.elapsed().as_secs_f64()
    }

    /// Records a row of an earlier part of the run (a resumed run's rows up to its
    /// checkpoint) as it was, and counts that part's wall-clock time into this one's. A row
    /// from a record written before rows held the wall time adds nothing, so such a run's
    /// total is that of its last part only.
    pub fn replay(&mut self, row: &SeriesRow) -> Result<()> {
        self.recorder.series(row)?;
        if row.wall_s.is_finite() {
            self.wall_before = row.wall_s;
        }
        self.rows.push(row.clone());
        Ok(())
    }

    /// Says once, when the largest overlap first passes docs/method.md's bound, that the run
    /// has left it: the summary and the campaign report say so at the end, which for a
    /// 5000-disk test at high friction can be hours later.
    fn warn_overlap(&mut self, row: &SeriesRow) {
        use crate::analysis::report::OVERLAP_BOUND_REL;
        let half = 0.5 * OVERLAP_BOUND_REL;
        if row.overlap_max_rel <= half {
            self.overlap_low = Some((row.step, row.strain_axial));
        }
        if self.overlap_warned || row.overlap_max_rel.is_nan() || row.overlap_max_rel <= OVERLAP_BOUND_REL {
            return;
        }
        self.overlap_warned = true;
        if !self.warn {
            return;
        }
        let label = self.lines.as_ref().map_or("", |(l, _)| l.as_str());
        let since = match self.overlap_low {
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
        let line = format!(
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
        );
        match &self.bar {
            Some(b) => b.println(line),
            None => eprintln!("{line}"),
        }
    }

    /// Ends the progress display.
    pub fn finish(&self) {
        if let Some(b) = &self.bar {
            b.finish_and_clear();
        }
    }
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

impl Observer for Recording {
    fn series(&mut self, row: &SeriesRow) -> Result<()> {
        let row = SeriesRow {
            wall_s: self.wall_s(),
            ..row.clone()
        };
        self.recorder.series(&row)?;
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
                b.set_position((1000.0 * row.strain_axial / self.strain_end).min(1000.0) as u64);
            }
            b.set_message(msg);
        } else if let Some((label, every)) = &self.lines {
            if row.phase == "compression" && self.compression_start.is_none() {
                self.compression_start = Some((row.wall_s, row.strain_axial));
            }
            if self.last_line.elapsed().as_secs_f64() >= *every {
                let left = self
                    .compression_start
                    .and_then(|(w0, e0)| time_left(w0, e0, row.wall_s, row.strain_axial, self.strain_end))
                    .map_or(String::new(), |s| format!("  about {} left", duration(s)));
                eprintln!("{label}[{:7.1} s] {msg}{left}", row.wall_s);
                self.last_line = Instant::now();
            }
        }
        self.warn_overlap(&row);
        self.rows.push(row);
        Ok(())
    }

    fn phase_end(&mut self, end: &PhaseEnd) -> Result<()> {
        let line = format!(
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
        );
        if !self.quiet {
            match &self.bar {
                Some(b) => b.println(line),
                None => eprintln!("{line}"),
            }
        }
        self.ends.push(end.clone());
        Ok(())
    }

    fn snapshot(
        &mut self,
        strain: f64,
        scene: &Scene,
        contacts: &[ContactRecord],
        reference: &[DVec2],
    ) -> Result<()> {
        self.recorder
            .snapshot(&snapshot(strain, scene, contacts, reference))
    }

    fn checkpoint(&mut self, step: u64, bytes: &[u8]) -> Result<()> {
        let time = self.rows.last().map_or(0.0, |r| r.time_s);
        self.recorder.checkpoint(step, time, bytes)
    }
}

/// The snapshot record of a state: disks with their displacement since `reference`
/// (the start of compression; zero before), and every candidate contact.
pub fn snapshot(strain: f64, scene: &Scene, contacts: &[ContactRecord], reference: &[DVec2]) -> Snapshot {
    let d = &scene.disks;
    Snapshot {
        time_s: scene.time,
        strain,
        disks: (0..d.len())
            .map(|k| {
                let u = reference.get(k).map_or(DVec2::ZERO, |r| d.pos[k] - *r);
                DiskRecord {
                    x: d.pos[k].x,
                    y: d.pos[k].y,
                    theta: d.theta[k],
                    vx: d.vel[k].x,
                    vy: d.vel[k].y,
                    w: d.spin[k],
                    r: d.radius[k],
                    dx: u.x,
                    dy: u.y,
                }
            })
            .collect(),
        contacts: contacts
            .iter()
            .map(|c| SnapContact {
                i: c.i,
                j: c.j,
                nx: c.n.x,
                ny: c.n.y,
                f_n: c.f_n,
                f_t: c.f_t,
                class: c.class as u8,
            })
            .collect(),
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
