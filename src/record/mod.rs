//! Run records: one MCAP file per run (`run.mcap`, readable by Foxglove and by cdlab) and a
//! CSV copy of the time series (`series.csv`).
//!
//! | topic | message encoding | schema (encoding) | content |
//! | --- | --- | --- | --- |
//! | `/config` | `json` | `cdlab.Config` (`jsonschema`) | once, at log time 0: `{"version", "config"}` |
//! | `/series` | `json` | `cdlab.SeriesRow` (`jsonschema`) | one [`SeriesRow`] per measurement |
//! | `/snapshot` | `cdlab-bin` | `cdlab.Snapshot.v1` (`cdlab-bin`, layout text) | a [`Snapshot`] |
//! | `/checkpoint` | `cdlab-bin` | `cdlab.Checkpoint.v2` (`cdlab-bin`, layout text) | u64 LE step + opaque state + u32 LE CRC-32 |
//!
//! The `/config` message also holds `run_id`, the run's identity that `summary.json` repeats
//! as `record_id`, and `backend` when known (records written before them lack both).
//!
//! Log times are simulated time in nanoseconds, so Foxglove's time axis is the run's clock.
//! Chunks are zstd-compressed and small, each with the CRC-32 of its content, and the writer
//! ends a chunk and flushes the file at every snapshot and checkpoint: a run killed with
//! `kill -9` leaves a file without summary or footer whose complete chunks [`read_run`] still
//! reads. The reader checks each chunk's CRC before it hands out any of its messages, and
//! each checkpoint's own CRC; it stops at the first incomplete or damaged record and says so
//! in [`RunRecord::truncated`] (and [`RunRecord::damaged`] when a check failed), so the last
//! checkpoint it returns is the last intact one. How the files are replaced without a
//! window in which none is complete: [`atomic`].

pub mod atomic;
mod fabric;
mod lock;
mod reader;
mod series;
mod snapshot;
pub mod vtk;
mod writer;

#[cfg(test)]
mod tests;

pub use crate::measure::SeriesRow;
pub use fabric::{SnapshotFabric, nearest_snapshot, pick_snapshot, read_snapshots, rotation_reference};
pub use lock::{LOCK_FILE, RunLock};
pub use reader::{RunRecord, is_archived, parse_run, read_config, read_run, read_run_id, read_series};
pub use series::{SERIES_FIELDS, SeriesColumn, csv_header, parse_csv, series_column, series_json_schema};
pub use snapshot::{ContactClass, ContactRecord, DiskRecord, SNAPSHOT_SCHEMA, Snapshot};
pub use writer::{RecordHead, Recorder, new_run_id};

/// The configuration of a test, as TOML: written beside the record by every run and resume
/// (what was run, readable without cdlab; the record's copy is the one cdlab uses), and
/// kept by `cdlab archive` in place of the record ([`read_config`] reads it when the
/// directory holds no record).
pub const ARCHIVED_CONFIG_FILE: &str = "config.toml";

/// The time series of a test kept by `cdlab archive`, thinned to a few hundred rows
/// ([`read_series`] reads it when the directory holds no record).
pub const THINNED_SERIES_FILE: &str = "series_thinned.csv";

/// The last snapshot of a run kept by `cdlab archive --keep-last-snapshot` in an archived
/// test's directory: one snapshot in the `/snapshot` layout ([`Snapshot::encode`]).
pub const LAST_SNAPSHOT_FILE: &str = "last_snapshot.bin";

/// File name of the MCAP record inside a run directory.
pub const MCAP_FILE: &str = "run.mcap";
/// File name of the CSV time series inside a run directory.
pub const CSV_FILE: &str = "series.csv";

/// Topic of the configuration message.
pub const TOPIC_CONFIG: &str = "/config";
/// Topic of the time series.
pub const TOPIC_SERIES: &str = "/series";
/// Topic of the snapshots.
pub const TOPIC_SNAPSHOT: &str = "/snapshot";
/// Topic of the checkpoints.
pub const TOPIC_CHECKPOINT: &str = "/checkpoint";

/// Schema name of the configuration message.
pub const CONFIG_SCHEMA: &str = "cdlab.Config";
/// Schema name of a series row.
pub const SERIES_SCHEMA: &str = "cdlab.SeriesRow";
/// Schema name of the checkpoint layout: step, state and the CRC-32 of both.
pub const CHECKPOINT_SCHEMA: &str = "cdlab.Checkpoint.v2";
/// Schema name of the checkpoints of records written before they carried a CRC (read, not
/// written).
pub const CHECKPOINT_SCHEMA_V1: &str = "cdlab.Checkpoint.v1";
/// Message (and custom schema) encoding of the binary channels.
pub const BIN_ENCODING: &str = "cdlab-bin";

/// Simulated time (s) to an MCAP log time (ns); negative or non-finite times map to 0.
fn log_time(time_s: f64) -> u64 {
    if time_s.is_finite() && time_s > 0.0 {
        (time_s * 1e9).round() as u64
    } else {
        0
    }
}
