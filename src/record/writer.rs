//! Writes a run's `run.mcap` and `series.csv` while the run goes.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use mcap::records::MessageHeader;
use mcap::{McapError, WriteOptions, Writer};

use super::series::{csv_header, series_json_schema};
use super::snapshot::{SNAPSHOT_SCHEMA, Snapshot, layout_description};
use super::*;
use crate::config::Config;
use crate::error::{Error, Result};
use crate::fsio::{FaultFile, check_replaceable, rename, sync_dir, tmp_path};
use crate::measure::SeriesRow;

/// Target uncompressed chunk size. Small, so that little is lost when a run is killed
/// between two flushes; zstd still finds the repetition of JSON keys within 64 KiB.
const CHUNK_SIZE: u64 = 64 * 1024;

/// Describes the checkpoint payload (stored as the schema data).
const CHECKPOINT_LAYOUT: &str = "cdlab.Checkpoint.v2, little-endian: u64 step, then the \
     state bytes of the protocol's resume format (opaque to the record), then the u32 \
     CRC-32 (IEEE) of the step and state bytes.";

/// JSON schema of the `/config` message.
const CONFIG_JSON_SCHEMA: &str = r#"{"$schema":"https://json-schema.org/draft/2020-12/schema","title":"cdlab.Config","type":"object","properties":{"version":{"type":"string","description":"cdlab version that wrote the run"},"config":{"type":"object","description":"the run configuration, SI units"}},"required":["version","config"]}"#;

/// Channel ids of one MCAP file.
struct Channels {
    series: u16,
    snapshot: u16,
    checkpoint: u16,
}

impl Seek for FaultFile {
    fn seek(&mut self, pos: SeekFrom) -> std::io::Result<u64> {
        self.0.seek(pos)
    }
}

/// What the `/config` message says besides the configuration: which run the record
/// belongs to (kept by a resume, so a summary can name its record) and the backend that
/// wrote it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RecordHead {
    /// The run's identity ([`new_run_id`]); `summary.json` repeats it as `record_id`.
    pub run_id: String,
    /// The backend that writes this part of the run, if known.
    pub backend: Option<String>,
    /// The backends that wrote the run's earlier parts, in order (a resumed run; empty for
    /// a new one): a GPU run resumed on the CPU says so ([`RunRecord::backends`]).
    pub earlier_backends: Vec<String>,
}

impl RecordHead {
    /// The head of a resume of `rec` on `backend`: the same run identity (a new one for a
    /// record written before records had one) and the record's backends as the earlier
    /// parts'.
    pub fn resumed(rec: &RunRecord, backend: String) -> RecordHead {
        RecordHead {
            run_id: rec.run_id.clone().unwrap_or_else(new_run_id),
            backend: Some(backend),
            earlier_backends: rec.backends.clone(),
        }
    }
}

/// A fresh run identity: 128 bits from the clock, the process and the standard library's
/// per-process random hash keys, as 32 hex digits. Unique enough to tell two runs of one
/// directory apart; it is not a secret.
pub fn new_run_id() -> String {
    use std::hash::{BuildHasher, Hasher};
    let now = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let word = |salt: u64| {
        let mut h = std::collections::hash_map::RandomState::new().build_hasher();
        h.write_u128(now);
        h.write_u32(std::process::id());
        h.write_u64(salt);
        h.finish()
    };
    format!("{:016x}{:016x}", word(1), word(2))
}

/// Records one run: the MCAP file (all channels) and the CSV of the series.
///
/// A recorder starts on temporary names ([`Recorder::stage`]) and moves its files into
/// place with [`Recorder::commit`]: a resume copies the old record's content up to its
/// checkpoint into the new file before it replaces the old one, so a kill or a full disk
/// at any instant leaves a record with that checkpoint under the real name. After the
/// commit the files grow in place; a run killed then leaves its complete chunks, which
/// [`super::read_run`] reads.
pub struct Recorder {
    mcap: Writer<BufWriter<FaultFile>>,
    /// A second handle on the MCAP file, to `sync_data` after a checkpoint: the MCAP writer
    /// owns the buffered one and has no accessor for it.
    sync: File,
    csv: BufWriter<FaultFile>,
    csv_sync: File,
    channels: Channels,
    /// Per-channel sequence numbers (series, snapshot, checkpoint).
    seq: [u32; 3],
    mcap_path: PathBuf,
    csv_path: PathBuf,
    /// Whether the files are still under their temporary names.
    staged: bool,
}

impl Recorder {
    /// Creates `dir` if needed and starts `run.mcap` and `series.csv` there with a new run
    /// identity, replacing any previous files of those names only once the new ones hold
    /// the configuration (see [`Recorder::stage`] and [`Recorder::commit`]).
    pub fn create(dir: impl AsRef<Path>, config: &Config) -> Result<Self> {
        let head = RecordHead {
            run_id: new_run_id(),
            ..Default::default()
        };
        let mut rec = Self::stage(dir, config, &head)?;
        rec.commit()?;
        Ok(rec)
    }

    /// Starts the record in `dir` (created if needed) under temporary names
    /// (`run.mcap.tmp`, `series.csv.tmp`), with the configuration written and flushed:
    /// the files of those names in `dir` are untouched until [`Recorder::commit`]. Either
    /// of them existing as anything but a regular file is refused before anything is
    /// written ([`check_replaceable`]).
    pub fn stage(dir: impl AsRef<Path>, config: &Config, head: &RecordHead) -> Result<Self> {
        let dir = dir.as_ref();
        crate::fsio::create_dir_all(dir)?;
        let mcap_path = dir.join(MCAP_FILE);
        let csv_path = dir.join(CSV_FILE);
        // The commit would refuse them too, but only after a resume's copy of the record.
        check_replaceable(&mcap_path)?;
        check_replaceable(&csv_path)?;
        let mcap_tmp = tmp_path(&mcap_path);
        let file = FaultFile::create_tmp(&mcap_tmp).map_err(|e| Error::io(&mcap_tmp, e))?;
        let sync = file.0.try_clone().map_err(|e| Error::io(&mcap_tmp, e))?;
        let mcap_err = |e| mcap_error(&mcap_tmp, e);
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

        let mut payload = serde_json::json!({
            "version": env!("CARGO_PKG_VERSION"),
            "config": config,
            "run_id": head.run_id,
        });
        if let Some(b) = &head.backend {
            payload["backend"] = serde_json::Value::from(b.as_str());
        }
        if !head.earlier_backends.is_empty() {
            payload["earlier_backends"] = serde_json::Value::from(head.earlier_backends.clone());
        }
        let header = MessageHeader {
            channel_id: config_ch,
            sequence: 0,
            log_time: 0,
            publish_time: 0,
        };
        mcap.write_to_known_channel(&header, payload.to_string().as_bytes())
            .map_err(mcap_err)?;
        mcap.flush().map_err(mcap_err)?;

        let csv_tmp = tmp_path(&csv_path);
        let csv_file = FaultFile::create_tmp(&csv_tmp).map_err(|e| Error::io(&csv_tmp, e))?;
        let csv_sync = csv_file.0.try_clone().map_err(|e| Error::io(&csv_tmp, e))?;
        let mut csv = BufWriter::new(csv_file);
        writeln!(csv, "{}", csv_header())
            .and_then(|_| csv.flush())
            .map_err(|e| Error::io(&csv_tmp, e))?;

        Ok(Recorder {
            mcap,
            sync,
            csv,
            csv_sync,
            channels: Channels {
                series,
                snapshot,
                checkpoint,
            },
            seq: [0; 3],
            mcap_path,
            csv_path,
            staged: true,
        })
    }

    /// Ends the current chunk, syncs both files and renames them over `run.mcap` and
    /// `series.csv` (the record first: a CSV is a copy that a resume writes again), then
    /// syncs the directory. Later writes go on growing the renamed files. Does nothing
    /// once committed.
    ///
    /// The old `series.csv` is removed (synced) before the new record takes its place: a
    /// CSV rename that then fails, or a kill between the two renames, leaves the new record
    /// without a CSV (the next resume writes it) rather than beside the rows of the run it
    /// replaced.
    pub fn commit(&mut self) -> Result<()> {
        if !self.staged {
            return Ok(());
        }
        let (mcap_tmp, csv_tmp) = (tmp_path(&self.mcap_path), tmp_path(&self.csv_path));
        self.mcap.flush().map_err(|e| mcap_error(&mcap_tmp, e))?;
        self.sync.sync_all().map_err(|e| Error::io(&mcap_tmp, e))?;
        self.csv
            .flush()
            .and_then(|_| self.csv_sync.sync_all())
            .map_err(|e| Error::io(&csv_tmp, e))?;
        crate::fsio::remove_file(&self.csv_path)?;
        rename(&mcap_tmp, &self.mcap_path)?;
        rename(&csv_tmp, &self.csv_path)?;
        sync_dir(&self.mcap_path)?;
        self.staged = false;
        Ok(())
    }

    /// The path the MCAP file is written under now (its temporary name before the commit).
    fn mcap_now(&self) -> PathBuf {
        if self.staged {
            tmp_path(&self.mcap_path)
        } else {
            self.mcap_path.clone()
        }
    }

    /// The path the CSV file is written under now.
    fn csv_now(&self) -> PathBuf {
        if self.staged {
            tmp_path(&self.csv_path)
        } else {
            self.csv_path.clone()
        }
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
            .map_err(|e| mcap_error(&self.mcap_now(), e))
    }

    /// Appends a measurement row to `/series` and to the CSV. The CSV line is flushed at once
    /// (a killed run keeps every row there); the MCAP row lands on disk with its chunk.
    pub fn series(&mut self, row: &SeriesRow) -> Result<()> {
        let json =
            serde_json::to_vec(row).map_err(|e| Error::Other(format!("cannot encode a series row: {e}")))?;
        self.write(0, self.channels.series, row.time_s, &json)?;
        writeln!(self.csv, "{}", row.csv_line())
            .and_then(|_| self.csv.flush())
            .map_err(|e| Error::io(self.csv_now(), e))
    }

    /// Writes a snapshot and ends the chunk, so that the snapshot survives a crash.
    pub fn snapshot(&mut self, snap: &Snapshot) -> Result<()> {
        let bytes = snap.encode()?;
        self.write(1, self.channels.snapshot, snap.time_s, &bytes)?;
        self.flush()
    }

    /// Writes a checkpoint (`state`: the caller's resume format) with its CRC-32, ends the
    /// chunk, flushes and syncs the file: after this returns, a crash cannot lose the
    /// checkpoint, and a damaged copy of it is recognised ([`super::read_run`]).
    pub fn checkpoint(&mut self, step: u64, time_s: f64, state: &[u8]) -> Result<()> {
        let mut bytes = Vec::with_capacity(12 + state.len());
        bytes.extend_from_slice(&step.to_le_bytes());
        bytes.extend_from_slice(state);
        let crc = crc32fast::hash(&bytes);
        bytes.extend_from_slice(&crc.to_le_bytes());
        self.write(2, self.channels.checkpoint, time_s, &bytes)?;
        self.flush()?;
        self.sync.sync_data().map_err(|e| Error::io(self.mcap_now(), e))
    }

    /// Ends the current chunk and pushes everything written so far to the operating system.
    pub fn flush(&mut self) -> Result<()> {
        self.mcap.flush().map_err(|e| mcap_error(&self.mcap_now(), e))?;
        self.csv.flush().map_err(|e| Error::io(self.csv_now(), e))
    }

    /// Writes the MCAP summary and footer (indexes for fast seeking in Foxglove) and closes
    /// both files. A recorder dropped without `finish` also writes them, but cannot report
    /// an error.
    /// A staged recorder is committed first.
    pub fn finish(mut self) -> Result<()> {
        self.commit()?;
        self.mcap.finish().map_err(|e| mcap_error(&self.mcap_path, e))?;
        let mut inner = self.mcap.into_inner();
        inner.flush().map_err(|e| Error::io(&self.mcap_path, e))?;
        self.sync.sync_data().map_err(|e| Error::io(&self.mcap_path, e))?;
        self.csv
            .flush()
            .and_then(|_| self.csv_sync.sync_data())
            .map_err(|e| Error::io(&self.csv_path, e))
    }
}

/// An MCAP error with the file it concerns.
fn mcap_error(path: &Path, e: McapError) -> Error {
    match e {
        McapError::Io(io) => Error::io(path, io),
        other => Error::io(
            path,
            std::io::Error::new(std::io::ErrorKind::InvalidData, format!("MCAP: {other}")),
        ),
    }
}
