//! The messages a test's [`Display`] gives for the events around its rows: deposition,
//! resume, backend, phase ends, the overlap warning, the end of the steps.

use super::run::{Display, Progress};
use crate::analysis::report::OVERLAP_BOUND_REL;
use crate::measure::SeriesRow;
use crate::run::Event;

impl crate::run::Progress for Display {
    fn event(&mut self, event: &Event<'_>) {
        let quiet = self.mode.quiet();
        match event {
            Event::Deposited { disks, report: r } if !quiet => note!(
                "deposited {disks} disks in {:.2} s: packing fraction {:.3}, coordination {:.2}, \
                 D10 {:.2} m, D60 {:.2} m, height/width {:.2}",
                r.seconds,
                r.packing_fraction,
                r.coordination,
                r.d10_m,
                r.d60_m,
                r.aspect
            ),
            Event::FellBack {
                file,
                why,
                step,
                phase,
                strain,
            } => note!(
                "warning: {}: {why}; falling back to the last intact checkpoint before the damage: \
                 step {step} (phase {}{}); the run is recomputed from there",
                file.display(),
                phase.name(),
                strain.map_or(String::new(), |e| format!(", axial strain {e:.5}"))
            ),
            Event::SummaryRewritten { dir, fault } => note!(
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
                    note!(
                        "resuming {} from step {step} (t = {time_s:.3} s, phase {})",
                        dir.display(),
                        phase.name()
                    );
                }
            }
            Event::BackendNote(text) if !quiet => note!("note: {text}"),
            Event::Running { backend, dir } => {
                if !quiet {
                    note!("running on {backend} -> {}", dir.display());
                }
                self.start();
            }
            Event::Row { row, strain_end } => self.row(row, *strain_end),
            Event::Settling(check) => self.settling(check),
            Event::OverlapBound { row, within_half } if !matches!(self.mode, Progress::Quiet) => {
                let label = self.lines().map_or(String::new(), |(l, _)| l);
                self.say(overlap_warning(&label, row, *within_half));
            }
            Event::PhaseEnd(end) if !quiet => self.say(format!(
                "{} ended at t = {:.3} s (step {}): {}, kinetic ratio {:.2e}, force imbalance {:.2e}{}",
                end.phase.name(),
                end.time_s,
                end.step,
                match (end.phase, end.settled) {
                    (crate::protocol::Phase::Compression, _) => "target strain reached",
                    (_, true) => "settled",
                    (_, false) => "NOT settled (time cap reached)",
                },
                end.kinetic_ratio,
                end.force_imbalance,
                end.creep_rate
                    .map_or(String::new(), |r| format!(", creep {r:.2e}/s"))
            )),
            Event::Activity { phase, text } if !quiet => self.say(format!("{}: {text}", phase.name())),
            Event::StepsEnded => {
                if let Some(b) = &self.bar {
                    b.finish_and_clear();
                }
            }
            Event::NoShearBands(e) if !quiet => note!("no shear-band analysis: {e}"),
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
         step gives only in part and local updates of deep contacts give to the deep \
         contacts alone (solver.deep_overlap unset or 0.005 with a Gauss-Seidel method, \
         solver.deep_sweeps 50; `cdlab overlaps RUN` names the pair from the snapshots; \
         docs/results.md, \"Every friction at 0.5 ms\")",
        OVERLAP_BOUND_REL * 100.0,
        row.overlap_max_rel * 100.0,
        row.step,
        row.phase,
        row.strain_axial
    )
}
