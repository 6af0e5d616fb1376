//! The observer of a recorded test: every row, snapshot and checkpoint into the record,
//! every event to the caller's [`Progress`].

use std::time::Instant;

use glam::DVec2;

use super::{Event, Progress};
use crate::backend::ContactRecord;
use crate::error::Result;
use crate::measure::SeriesRow;
use crate::model::Scene;
use crate::protocol::{Observer, PhaseEnd};
use crate::record::{ContactRecord as SnapContact, DiskRecord, Recorder, Snapshot};

/// Records every row, snapshot and checkpoint, keeps the rows and phase ends the summary
/// is derived from, and reports each to a [`Progress`].
pub struct Recording<'p> {
    /// The MCAP and CSV writer.
    pub recorder: Recorder,
    /// Rows received (the summary is derived from them).
    pub rows: Vec<SeriesRow>,
    /// Phase ends received.
    pub ends: Vec<PhaseEnd>,
    strain_end: f64,
    started: Instant,
    /// Wall-clock seconds of the run's earlier parts (a resumed run's replayed rows).
    wall_before: f64,
    /// Whether the overlap bound has been reported.
    overlap_reported: bool,
    /// Step and axial strain of the last row whose largest overlap was within half the
    /// bound: how fast it then grew tells which remedy the warning's reader needs.
    overlap_low: Option<(u64, f64)>,
    pub(super) progress: &'p mut dyn Progress,
}

impl<'p> Recording<'p> {
    /// A recording observer reporting to `progress`; its wall clock runs from `started`
    /// (before the deposition or the reading of a record it follows).
    pub fn new(
        recorder: Recorder,
        strain_end: f64,
        progress: &'p mut dyn Progress,
        started: Instant,
    ) -> Self {
        Recording {
            recorder,
            rows: Vec::new(),
            ends: Vec::new(),
            strain_end,
            started,
            wall_before: 0.0,
            overlap_reported: false,
            overlap_low: None,
            progress,
        }
    }

    /// Wall-clock seconds of the run so far, its earlier parts included.
    pub fn wall_s(&self) -> f64 {
        self.wall_before + self.started.elapsed().as_secs_f64()
    }

    /// Reports an event to the caller's [`Progress`].
    pub fn event(&mut self, event: &Event<'_>) {
        self.progress.event(event);
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

    /// Reports once when the largest overlap first passes docs/method.md's bound: the
    /// summary and the campaign report say so at the end, which for a 5000-disk test at
    /// high friction can be hours later.
    fn watch_overlap(&mut self, row: &SeriesRow) {
        use crate::analysis::report::OVERLAP_BOUND_REL;
        if row.overlap_max_rel <= 0.5 * OVERLAP_BOUND_REL {
            self.overlap_low = Some((row.step, row.strain_axial));
        }
        if self.overlap_reported || row.overlap_max_rel.is_nan() || row.overlap_max_rel <= OVERLAP_BOUND_REL {
            return;
        }
        self.overlap_reported = true;
        let within_half = self.overlap_low;
        self.progress.event(&Event::OverlapBound { row, within_half });
    }
}

impl Observer for Recording<'_> {
    fn series(&mut self, row: &SeriesRow) -> Result<()> {
        let row = SeriesRow {
            wall_s: self.wall_s(),
            ..row.clone()
        };
        self.recorder.series(&row)?;
        self.progress.event(&Event::Row {
            row: &row,
            strain_end: self.strain_end,
        });
        self.watch_overlap(&row);
        self.rows.push(row);
        Ok(())
    }

    fn phase_end(&mut self, end: &PhaseEnd) -> Result<()> {
        self.progress.event(&Event::PhaseEnd(end));
        self.ends.push(end.clone());
        Ok(())
    }

    fn activity(&mut self, phase: crate::protocol::Phase, text: &str) -> Result<()> {
        self.progress.event(&Event::Activity { phase, text });
        Ok(())
    }

    fn settling(&mut self, check: &crate::protocol::Settling) -> Result<()> {
        self.progress.event(&Event::Settling(check));
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
