//! Writes a run's `run.mcap` and `series.csv` while the run goes.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use mcap::records::MessageHeader;
use mcap::{McapError, WriteOptions, Writer};

use super::series::{SeriesRow, csv_header, series_json_schema};
use super::snapshot::{SNAPSHOT_SCHEMA, Snapshot, layout_description};
use super::*;
use crate::config::Config;
use crate::error::{Error, Result};

/// Target uncompressed chunk size. Small, so that little is lost when a run is killed
/// between two flushes; zstd still finds the repetition of JSON keys within 64 KiB.
const CHUNK_SIZE: u64 = 64 * 1024;

/// Describes the checkpoint payload (stored as the schema data).
const CHECKPOINT_LAYOUT: &str = "cdlab.Checkpoint.v1, little-endian: u64 step, then the \
     state bytes of the protocol's resume format (opaque to the record).";

/// JSON schema of the `/config` message.
const CONFIG_JSON_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"cdlab.Config","type":"object","properties":{"version":{"type":"string","description":"cdlab version that wrote the run"},"config":{"type":"object","description":"the run configuration, SI units"}},"required":["version","config"]}"#;

/// Channel ids of one MCAP file.
struct Channels {
    series: u16,
    snapshot: u16,
    checkpoint: u16,
}

/// Records one run: the MCAP file (all channels) and the CSV of the series.
pub struct Recorder {
    mcap: Writer<BufWriter<File>>,
    /// A second handle on the MCAP file, to `sync_data` after a checkpoint: the MCAP writer
    /// owns the buffered one and has no accessor for it.
    sync: File,
    csv: BufWriter<File>,
    channels: Channels,
    /// Per-channel sequence numbers (series, snapshot, checkpoint).
    seq: [u32; 3],
    mcap_path: PathBuf,
    csv_path: PathBuf,
}

impl Recorder {
    /// Creates `dir` if needed and starts `run.mcap` and `series.csv` there, replacing any
    /// previous files of those names. Writes the configuration and flushes it at once, so
    /// that even a run killed in its first step leaves a file that names its configuration.
    pub fn create(dir: impl AsRef<Path>, config: &Config) -> Result<Self> {
        let dir = dir.as_ref();
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let mcap_path = dir.join(MCAP_FILE);
        let csv_path = dir.join(CSV_FILE);
        let file = File::create(&mcap_path).map_err(|e| Error::io(&mcap_path, e))?;
        let sync = file.try_clone().map_err(|e| Error::io(&mcap_path, e))?;
        let mcap_err = |e| mcap_error(&mcap_path, e);
        let options = WriteOptions::new()
            .compression(Some(mcap::Compression::Zstd))
            .chunk_size(Some(CHUNK_SIZE))
            // Without seeking, a chunk is written in one piece when it ends, never as a
            // header whose lengths get patched later: a killed run cannot leave a chunk
            // header that claims data which is not there.
            .disable_seeking(true)
            // The solver owns the cores; compressing 64 KiB needs no worker threads.
            .compression_threads(0)
            .library(format!("cdlab {}", env!("CARGO_PKG_VERSION")));
        let mut mcap = options.create(BufWriter::new(file)).map_err(mcap_err)?;

        let no_meta = BTreeMap::new();
        let config_schema = mcap
            .add_schema(CONFIG_SCHEMA, "jsonschema", CONFIG_JSON_SCHEMA.as_bytes())
            .map_err(mcap_err)?;
        let config_ch = mcap
            .add_channel(config_schema, TOPIC_CONFIG, "json", &no_meta)
            .map_err(mcap_err)?;
        let series_schema = mcap
            .add_schema(SERIES_SCHEMA, "jsonschema", series_json_schema().as_bytes())
            .map_err(mcap_err)?;
        let series = mcap
            .add_channel(series_schema, TOPIC_SERIES, "json", &no_meta)
            .map_err(mcap_err)?;
        let snap_schema = mcap
            .add_schema(SNAPSHOT_SCHEMA, BIN_ENCODING, layout_description().as_bytes())
            .map_err(mcap_err)?;
        let snapshot = mcap
            .add_channel(snap_schema, TOPIC_SNAPSHOT, BIN_ENCODING, &no_meta)
            .map_err(mcap_err)?;
        let ckpt_schema = mcap
            .add_schema(CHECKPOINT_SCHEMA, BIN_ENCODING, CHECKPOINT_LAYOUT.as_bytes())
            .map_err(mcap_err)?;
        let checkpoint = mcap
            .add_channel(ckpt_schema, TOPIC_CHECKPOINT, BIN_ENCODING, &no_meta)
            .map_err(mcap_err)?;

        let payload = serde_json::json!({
            "version": env!("CARGO_PKG_VERSION"),
            "config": config,
        });
        let header = MessageHeader {
            channel_id: config_ch,
            sequence: 0,
            log_time: 0,
            publish_time: 0,
        };
        mcap.write_to_known_channel(&header, payload.to_string().as_bytes())
            .map_err(mcap_err)?;
        mcap.flush().map_err(mcap_err)?;

        let csv_file = File::create(&csv_path).map_err(|e| Error::io(&csv_path, e))?;
        let mut csv = BufWriter::new(csv_file);
        writeln!(csv, "{}", csv_header())
            .and_then(|_| csv.flush())
            .map_err(|e| Error::io(&csv_path, e))?;

        Ok(Recorder {
            mcap,
            sync,
            csv,
            channels: Channels {
                series,
                snapshot,
                checkpoint,
            },
            seq: [0; 3],
            mcap_path,
            csv_path,
        })
    }

    /// Path of the MCAP file.
    pub fn mcap_path(&self) -> &Path {
        &self.mcap_path
    }

    /// Path of the CSV file.
    pub fn csv_path(&self) -> &Path {
        &self.csv_path
    }

    fn write(&mut self, which: usize, channel_id: u16, time_s: f64, data: &[u8]) -> Result<()> {
        let t = log_time(time_s);
        let header = MessageHeader {
            channel_id,
            sequence: self.seq[which],
            log_time: t,
            publish_time: t,
        };
        self.seq[which] = self.seq[which].wrapping_add(1);
        self.mcap
            .write_to_known_channel(&header, data)
            .map_err(|e| mcap_error(&self.mcap_path, e))
    }

    /// Appends a measurement row to `/series` and to the CSV. The CSV line is flushed at once
    /// (a killed run keeps every row there); the MCAP row lands on disk with its chunk.
    pub fn series(&mut self, row: &SeriesRow) -> Result<()> {
        let json =
            serde_json::to_vec(row).map_err(|e| Error::Other(format!("cannot encode a series row: {e}")))?;
        self.write(0, self.channels.series, row.time_s, &json)?;
        writeln!(self.csv, "{}", row.csv_line())
            .and_then(|_| self.csv.flush())
            .map_err(|e| Error::io(&self.csv_path, e))
    }

    /// Writes a snapshot and ends the chunk, so that the snapshot survives a crash.
    pub fn snapshot(&mut self, snap: &Snapshot) -> Result<()> {
        let bytes = snap.encode()?;
        self.write(1, self.channels.snapshot, snap.time_s, &bytes)?;
        self.flush()
    }

    /// Writes a checkpoint (`state`: the caller's resume format), ends the chunk, flushes
    /// and syncs the file: after this returns, a crash cannot lose the checkpoint.
    pub fn checkpoint(&mut self, step: u64, time_s: f64, state: &[u8]) -> Result<()> {
        let mut bytes = Vec::with_capacity(8 + state.len());
        bytes.extend_from_slice(&step.to_le_bytes());
        bytes.extend_from_slice(state);
        self.write(2, self.channels.checkpoint, time_s, &bytes)?;
        self.flush()?;
        self.sync.sync_data().map_err(|e| Error::io(&self.mcap_path, e))
    }

    /// Ends the current chunk and pushes everything written so far to the operating system.
    pub fn flush(&mut self) -> Result<()> {
        self.mcap.flush().map_err(|e| mcap_error(&self.mcap_path, e))?;
        self.csv.flush().map_err(|e| Error::io(&self.csv_path, e))
    }

    /// Writes the MCAP summary and footer (indexes for fast seeking in Foxglove) and closes
    /// both files. A recorder dropped without `finish` also writes them, but cannot report
    /// an error.
    pub fn finish(mut self) -> Result<()> {
        self.mcap.finish().map_err(|e| mcap_error(&self.mcap_path, e))?;
        let mut inner = self.mcap.into_inner();
        inner.flush().map_err(|e| Error::io(&self.mcap_path, e))?;
        self.sync.sync_data().map_err(|e| Error::io(&self.mcap_path, e))?;
        self.csv.flush().map_err(|e| Error::io(&self.csv_path, e))
    }
}

/// An MCAP error with the file it concerns.
fn mcap_error(path: &Path, e: McapError) -> Error {
    match e {
        McapError::Io(io) => Error::io(path, io),
        other => Error::Other(format!("{}: MCAP: {other}", path.display())),
    }
}
