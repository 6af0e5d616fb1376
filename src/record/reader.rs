//! Reads a run back from its MCAP file, complete or cut short.
//!
//! The reader streams the file from the start (it never needs the summary or footer), so a
//! run killed mid-write is read up to its last complete record. The mcap crate's
//! `MessageStream` does exactly that: it yields every message of the complete chunks and then
//! one error for the broken tail, which is recorded in [`RunRecord::truncated`] instead of
//! failing the whole read.

use std::path::{Path, PathBuf};

use mcap::MessageStream;
use mcap::read::Options;

use super::series::SeriesRow;
use super::snapshot::{SNAPSHOT_SCHEMA, Snapshot};
use super::*;
use crate::config::Config;
use crate::error::{Error, Result};

/// Everything a run recorded.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RunRecord {
    /// The configuration of the run, as JSON (see [`RunRecord::config`]).
    pub config_json: String,
    /// The cdlab version that wrote the run.
    pub version: String,
    /// The measured rows, in the order written.
    pub series: Vec<SeriesRow>,
    /// The snapshots, in the order written.
    pub snapshots: Vec<Snapshot>,
    /// The last checkpoint: step and the caller's state bytes.
    pub last_checkpoint: Option<(u64, Vec<u8>)>,
    /// `None` for a complete file; otherwise why reading stopped early (a run killed before
    /// it finished, or a damaged tail). Everything before that point is in this record.
    pub truncated: Option<String>,
}

impl RunRecord {
    /// Parses the recorded configuration.
    pub fn config(&self) -> Result<Config> {
        serde_json::from_str(&self.config_json)
            .map_err(|e| Error::Other(format!("recorded configuration: {e}")))
    }
}

/// The cdlab version and the configuration (as JSON) of a `/config` message.
fn config_message(data: &[u8]) -> std::result::Result<(String, String), String> {
    let v: serde_json::Value = serde_json::from_slice(data).map_err(|e| format!("/config message: {e}"))?;
    let version = v["version"].as_str().ok_or("/config message has no version")?;
    let config = v.get("config").ok_or("/config message has no config")?;
    Ok((version.to_string(), config.to_string()))
}

/// The MCAP file of `path`: the file itself or `run.mcap` in a run directory.
fn mcap_path(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.join(MCAP_FILE)
    } else {
        path.to_path_buf()
    }
}

/// A directory that `cdlab archive` wrote: no record, the archived configuration.
fn is_archived(dir: &Path) -> bool {
    dir.is_dir() && !dir.join(MCAP_FILE).exists() && dir.join(ARCHIVED_CONFIG_FILE).exists()
}

/// Reads the time series of a run (`path` as for [`read_run`]) from its record, or of an
/// archived test from its thinned series ([`THINNED_SERIES_FILE`]: a few hundred rows
/// spread over the run, enough to draw its curves), with the configuration found beside
/// them in the same read. The configuration is a separate result: rows that read can still
/// be drawn when it does not.
pub fn read_series(path: impl AsRef<Path>) -> Result<(Vec<SeriesRow>, Result<Config>)> {
    let dir = path.as_ref();
    if !is_archived(dir) {
        let rec = read_run(dir)?;
        let config = rec.config();
        return Ok((rec.series, config));
    }
    let file = dir.join(THINNED_SERIES_FILE);
    let text = std::fs::read_to_string(&file).map_err(|e| Error::io(&file, e))?;
    let rows = super::series::parse_csv(&text)
        .map_err(|e| Error::io(&file, std::io::Error::new(std::io::ErrorKind::InvalidData, e)))?;
    Ok((rows, Config::load(dir.join(ARCHIVED_CONFIG_FILE))))
}

/// Reads only the configuration of a run (`path` as for [`read_run`]). The recorder writes
/// it first and its chunks are small, so the file's first megabyte normally holds it: a sweep
/// checks every finished test of a campaign this way without reading whole records. A head
/// that does not hold it falls back to [`read_run`], with its errors.
///
/// A directory written by `cdlab archive` holds no record but the test's configuration as
/// [`ARCHIVED_CONFIG_FILE`]: that file is read instead.
pub fn read_config(path: impl AsRef<Path>) -> Result<Config> {
    use std::io::Read;
    let dir = path.as_ref();
    if is_archived(dir) {
        return Config::load(dir.join(ARCHIVED_CONFIG_FILE));
    }
    let path = mcap_path(dir);
    let mut head = Vec::new();
    std::fs::File::open(&path)
        .and_then(|f| f.take(1 << 20).read_to_end(&mut head))
        .map_err(|e| Error::io(&path, e))?;
    let first = MessageStream::new_with_options(&head, Options::ValidateChunkCrcs.into())
        .ok()
        .and_then(|stream| {
            stream.map_while(|m| m.ok()).find(|m| {
                m.channel.topic == TOPIC_CONFIG
                    && m.channel.schema.as_ref().map(|s| s.name.as_str()) == Some(CONFIG_SCHEMA)
            })
        })
        .and_then(|m| config_message(&m.data).ok());
    let config_json = match first {
        Some((_, json)) => json,
        None => read_run(&path)?.config_json,
    };
    RunRecord {
        config_json,
        ..Default::default()
    }
    .config()
}

/// Reads a run from `path`: the MCAP file itself, or a run directory holding `run.mcap`.
///
/// A file cut short is read up to its last complete chunk. A file that is not MCAP, or an
/// MCAP file that is not a cdlab run (no `/config` message of schema `cdlab.Config`), or a
/// complete message that does not decode, is an error naming the file.
///
/// A directory written by `cdlab archive` (configuration, summary and thinned series, no
/// record) is an error that says so: snapshots and checkpoints went with the record.
pub fn read_run(path: impl AsRef<Path>) -> Result<RunRecord> {
    let path = path.as_ref();
    if is_archived(path) {
        return Err(Error::Other(format!(
            "{} is an archived test (`cdlab archive`: its configuration, summary and time \
             series thinned to {THINNED_SERIES_FILE}, without the record {MCAP_FILE}); this \
             needs the full record, which only the run's own directory holds (`cdlab render \
             DIR --curves` draws from the thinned series)",
            path.display()
        )));
    }
    let path = mcap_path(path);
    let bytes = std::fs::read(&path).map_err(|e| Error::io(&path, e))?;
    let bad = |msg: String| Error::io(&path, std::io::Error::new(std::io::ErrorKind::InvalidData, msg));

    // Chunk CRCs are checked so that a damaged chunk ends the read instead of being decoded.
    let stream = MessageStream::new_with_options(&bytes, Options::ValidateChunkCrcs.into())
        .map_err(|e| bad(format!("not a readable MCAP file: {e}")))?;
    let mut run = RunRecord::default();
    let mut have_config = false;
    for (n_messages, item) in stream.enumerate() {
        let msg = match item {
            Ok(m) => m,
            Err(e) if n_messages == 0 => {
                return Err(bad(format!("not a cdlab run (unreadable MCAP: {e})")));
            }
            Err(e) => {
                run.truncated = Some(format!("stopped after {n_messages} messages: {e}"));
                break;
            }
        };
        let schema = msg.channel.schema.as_ref().map(|s| s.name.as_str());
        let seq = msg.sequence;
        // A cdlab topic with a foreign or newer schema is refused rather than misread.
        let expect = |name: &str| {
            if schema == Some(name) {
                Ok(())
            } else {
                Err(bad(format!(
                    "topic {} has schema {schema:?}, expected {name}",
                    msg.channel.topic
                )))
            }
        };
        match msg.channel.topic.as_str() {
            TOPIC_CONFIG => {
                expect(CONFIG_SCHEMA)?;
                if have_config {
                    continue; // the first configuration is the run's
                }
                (run.version, run.config_json) = config_message(&msg.data).map_err(bad)?;
                have_config = true;
            }
            TOPIC_SERIES => {
                expect(SERIES_SCHEMA)?;
                let row = serde_json::from_slice(&msg.data)
                    .map_err(|e| bad(format!("/series message {seq}: {e}")))?;
                run.series.push(row);
            }
            TOPIC_SNAPSHOT => {
                expect(SNAPSHOT_SCHEMA)?;
                let snap =
                    Snapshot::decode(&msg.data).map_err(|e| bad(format!("/snapshot message {seq}: {e}")))?;
                run.snapshots.push(snap);
            }
            TOPIC_CHECKPOINT => {
                expect(CHECKPOINT_SCHEMA)?;
                if msg.data.len() < 8 {
                    return Err(bad(format!("/checkpoint message {seq} is shorter than 8 bytes")));
                }
                let (step, state) = msg.data.split_at(8);
                let step = u64::from_le_bytes(step.try_into().expect("8 bytes"));
                run.last_checkpoint = Some((step, state.to_vec()));
            }
            // Other topics (added by tools or later versions) are not ours to interpret.
            _ => {}
        }
    }
    if !have_config {
        let why = run.truncated.as_deref().unwrap_or("complete file");
        return Err(bad(format!(
            "not a cdlab run: no /config message of schema {CONFIG_SCHEMA} ({why})"
        )));
    }
    Ok(run)
}
