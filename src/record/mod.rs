//! Run records: one MCAP file per run (`run.mcap`, readable by Foxglove and by cdlab) and a
//! CSV copy of the time series (`series.csv`).
//!
//! | topic | message encoding | schema (encoding) | content |
//! | --- | --- | --- | --- |
//! | `/config` | `json` | `cdlab.Config` (`jsonschema`) | once, at log time 0: `{"version", "config"}` |
//! | `/series` | `json` | `cdlab.SeriesRow` (`jsonschema`) | one [`SeriesRow`] per measurement |
//! | `/snapshot` | `cdlab-bin` | `cdlab.Snapshot.v1` (`cdlab-bin`, layout text) | a [`Snapshot`] |
//! | `/checkpoint` | `cdlab-bin` | `cdlab.Checkpoint.v1` (`cdlab-bin`, layout text) | u64 LE step + opaque state |
//!
//! Log times are simulated time in nanoseconds, so Foxglove's time axis is the run's clock.
//! Chunks are zstd-compressed and small, and the writer ends a chunk and flushes the file at
//! every snapshot and checkpoint: a run killed with `kill -9` leaves a file without summary
//! or footer whose complete chunks [`read_run`] still reads (it stops at the first incomplete
//! record and says so in [`RunRecord::truncated`]).

mod lock;
mod reader;
mod series;
mod snapshot;
pub mod vtk;
mod writer;

#[cfg(test)]
mod tests;

pub use lock::{LOCK_FILE, RunLock};
pub use reader::{RunRecord, read_config, read_run, read_series};
pub use series::{SERIES_FIELDS, SeriesRow, csv_header, parse_csv, series_json_schema};
pub use snapshot::{ContactClass, ContactRecord, DiskRecord, SNAPSHOT_SCHEMA, Snapshot};
pub use writer::Recorder;

/// The configuration of a test kept by `cdlab archive` in place of its record
/// ([`read_config`] reads it when the directory holds no record).
pub const ARCHIVED_CONFIG_FILE: &str = "config.toml";

/// The time series of a test kept by `cdlab archive`, thinned to a few hundred rows
/// ([`read_series`] reads it when the directory holds no record).
pub const THINNED_SERIES_FILE: &str = "series_thinned.csv";

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
/// Schema name of the checkpoint layout.
pub const CHECKPOINT_SCHEMA: &str = "cdlab.Checkpoint.v1";
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
