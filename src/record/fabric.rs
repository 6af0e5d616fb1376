//! Recorded snapshots picked and analysed: a run's (or an archived test's kept) snapshots
//! with its series, the one nearest a strain, and the microstructure of one
//! (`crate::measure::micro`, docs/micromechanics.md) as `cdlab fabric` prints it and the
//! Python package's `Snapshot.fabric()` returns it: one call, so that both divide the
//! stress by the same area and refuse the same snapshots.

use std::path::Path;

use super::snapshot::Snapshot;
use super::{LAST_SNAPSHOT_FILE, MCAP_FILE, read_run, read_series};
use crate::error::{Error, Result, SnapshotFault};
use crate::measure::SeriesRow;
use crate::measure::micro::Analysis;

/// The analysis of one snapshot with the series row that gave its sample area.
#[derive(Clone, Debug)]
pub struct SnapshotFabric<'a> {
    /// The fabric, force anisotropies, networks and Love-Weber stress of the snapshot.
    pub analysis: Analysis,
    /// The series row nearest the snapshot's time ([`SeriesRow::nearest`]): its height and
    /// width give the area, its boundary stresses are what the Love-Weber stress is set
    /// against.
    pub row: &'a SeriesRow,
}

/// The index of the snapshot whose axial strain is nearest `strain` (`None` when there is
/// none). Several snapshots share strain 0 (the end of each preparation phase): the last
/// of equals is taken, the start of the compression.
pub fn nearest_snapshot(snapshots: &[Snapshot], strain: f64) -> Option<usize> {
    let mut best: Option<(usize, f64)> = None;
    for (k, s) in snapshots.iter().enumerate() {
        let d = (s.strain - strain).abs();
        if best.is_none_or(|(_, b)| d <= b) {
            best = Some((k, d));
        }
    }
    best.map(|(k, _)| k)
}

/// The snapshot that rotations of snapshot `k` are measured from: the one of least strain
/// before it (the last of equals, nearest the compression's start). None for the first.
pub fn rotation_reference(snapshots: &[Snapshot], k: usize) -> Option<&Snapshot> {
    snapshots[..k.min(snapshots.len())]
        .iter()
        .rev()
        .min_by(|a, b| a.strain.total_cmp(&b.strain))
}

/// A [`Error::Snapshot`] about the test at `source`.
fn fault(source: &Path, fault: SnapshotFault, message: String) -> Error {
    Error::Snapshot {
        path: source.to_path_buf(),
        fault,
        message: format!("{}: {message}", source.display()),
    }
}

impl Snapshot {
    /// The microstructure of this snapshot, its stress divided by the sample area of the
    /// series row nearest its time (a snapshot holds no walls; an archived test's thinned
    /// series gives the nearest row it kept). `source` is the run directory or archived
    /// test, named in the errors: [`SnapshotFault::NoSeriesRow`] when `series` is empty,
    /// [`SnapshotFault::NoArea`] when that row's height times width is not a finite positive
    /// area, [`SnapshotFault::NoForce`] when no disk-disk contact carries force.
    pub fn fabric<'a>(&self, series: &'a [SeriesRow], source: &Path) -> Result<SnapshotFabric<'a>> {
        let row = SeriesRow::nearest(series, self.time_s).ok_or_else(|| {
            fault(
                source,
                SnapshotFault::NoSeriesRow,
                "the record holds no series row".into(),
            )
        })?;
        let area = row.height_m * row.width_m;
        if !(area > 0.0 && area.is_finite()) {
            return Err(fault(
                source,
                SnapshotFault::NoArea,
                format!(
                    "the series row at t = {:.3} s gives no sample area (height {} m, width {} m)",
                    row.time_s, row.height_m, row.width_m
                ),
            ));
        }
        let radius: Vec<f64> = self.disks.iter().map(|d| d.r).collect();
        let analysis = Analysis::of(&self.micro_contacts(), &radius, area);
        if analysis.sums.n_force == 0 {
            return Err(fault(
                source,
                SnapshotFault::NoForce,
                format!(
                    "the snapshot at strain {:.4} has no force-carrying contact",
                    self.strain
                ),
            ));
        }
        Ok(SnapshotFabric { analysis, row })
    }
}

/// The snapshot to analyse among `snapshots` of the test at `source`: the one nearest the
/// axial strain `at`, or the last one. [`SnapshotFault::NoSnapshot`] when there is none.
pub fn pick_snapshot<'a>(snapshots: &'a [Snapshot], at: Option<f64>, source: &Path) -> Result<&'a Snapshot> {
    let k = match at {
        Some(at) => nearest_snapshot(snapshots, at),
        None => snapshots.len().checked_sub(1),
    };
    k.map(|k| &snapshots[k]).ok_or_else(|| {
        fault(
            source,
            SnapshotFault::NoSnapshot,
            "the record holds no snapshot to analyse".into(),
        )
    })
}

/// The snapshots and series of the run in `run` (a run directory or its `run.mcap`, read
/// and checked by [`read_run`]), or of an archived test kept with its last snapshot
/// ([`LAST_SNAPSHOT_FILE`], with its thinned series).
pub fn read_snapshots(run: &Path) -> Result<(Vec<Snapshot>, Vec<SeriesRow>)> {
    let kept = run.join(LAST_SNAPSHOT_FILE);
    if run.is_dir() && !run.join(MCAP_FILE).exists() && kept.exists() {
        let bytes = std::fs::read(&kept).map_err(|e| Error::io(&kept, e))?;
        let snap = Snapshot::decode(&bytes)
            .map_err(|e| Error::io(&kept, std::io::Error::new(std::io::ErrorKind::InvalidData, e)))?;
        let (series, _) = read_series(run)?;
        return Ok((vec![snap], series));
    }
    let rec = read_run(run)?;
    Ok((rec.snapshots, rec.series))
}
