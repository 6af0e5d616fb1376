//! Reads a run back from its MCAP file, complete, cut short or damaged.
//!
//! The reader streams the file from the start (it never needs the summary or footer), so a
//! run killed mid-write is read up to its last complete record. The mcap crate's sans-io
//! `MessageReader` does that with every chunk's CRC checked before any of the chunk's
//! messages is handed out (`prevalidate_chunk_crcs`), and with every record's length capped
//! so that a damaged length cannot ask for gigabytes. The first error ends the read; it is
//! recorded in [`RunRecord::truncated`] (and [`RunRecord::damaged`] unless the file merely
//! ends early) instead of failing the whole read, so what comes before it is usable: the
//! checkpoint a resume takes is the last intact one.

use std::path::{Path, PathBuf};

use mcap::McapError;
use mcap::sans_io::LinearReaderOptions;

use super::snapshot::{SNAPSHOT_SCHEMA, Snapshot};
use super::*;
use crate::config::Config;
use crate::error::{Error, Result};
use crate::measure::SeriesRow;

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
    /// The last intact checkpoint: step and the caller's state bytes (its CRC checked).
    pub last_checkpoint: Option<(u64, Vec<u8>)>,
    /// `None` for a complete file; otherwise why reading stopped early (a run killed before
    /// it finished, or a damaged tail). Everything before that point is in this record.
    pub truncated: Option<String>,
    /// `Some` when reading stopped at content that failed a check (a chunk or checkpoint
    /// CRC, a message that does not decode), not merely at the end of a file cut short:
    /// what the record held after that point is lost, and a resume falls back to
    /// [`RunRecord::last_checkpoint`], the last intact one before it.
    pub damaged: Option<String>,
    /// The run's identity (`run_id` of the `/config` message; `None` in records written
    /// before it).
    pub run_id: Option<String>,
    /// The backend that wrote the record's last part, when the record says.
    pub backend: Option<String>,
    /// Every backend that wrote a part of the run, in order, one that wrote several parts
    /// in a row named once (empty when the record names none): a run started on the GPU
    /// and resumed on the CPU lists both.
    pub backends: Vec<String>,
}

impl RunRecord {
    /// Parses the recorded configuration.
    pub fn config(&self) -> Result<Config> {
        serde_json::from_str(&self.config_json).map_err(|e| Error::BadRecord {
            path: None,
            message: format!("recorded configuration: {e}"),
        })
    }
}

/// What a `/config` message holds.
struct Head {
    version: String,
    config_json: String,
    run_id: Option<String>,
    backend: Option<String>,
    backends: Vec<String>,
}

/// The backends of a run's parts: the earlier parts' then `last`, repeats in a row merged.
fn parts_backends(earlier: Vec<String>, last: Option<&String>) -> Vec<String> {
    let mut all = earlier;
    all.extend(last.cloned());
    all.dedup();
    all
}

/// The cdlab version, the configuration (as JSON), the run identity and the backend of a
/// `/config` message.
fn config_message(data: &[u8]) -> std::result::Result<Head, String> {
    let v: serde_json::Value = serde_json::from_slice(data).map_err(|e| format!("/config message: {e}"))?;
    let version = v["version"].as_str().ok_or("/config message has no version")?;
    let config = v.get("config").ok_or("/config message has no config")?;
    let text = |k: &str| v.get(k).and_then(serde_json::Value::as_str).map(str::to_string);
    let earlier = match v.get("earlier_backends") {
        None => Vec::new(),
        Some(list) => list
            .as_array()
            .and_then(|l| l.iter().map(|b| b.as_str().map(str::to_string)).collect())
            .ok_or("/config message: earlier_backends is not a list of names")?,
    };
    let backend = text("backend");
    Ok(Head {
        version: version.to_string(),
        config_json: config.to_string(),
        run_id: text("run_id"),
        backends: parts_backends(earlier, backend.as_ref()),
        backend,
    })
}

/// The largest record (a chunk's compressed or decompressed content) accepted in a file of
/// `len` bytes: 64 times the file (cdlab's chunks compress by far less), at least 16 MiB,
/// at most 1 GiB. A damaged length beyond it is an error, not an allocation.
fn record_limit(len: usize) -> usize {
    len.saturating_mul(64).clamp(16 << 20, 1 << 30)
}

/// Why reading stopped.
#[derive(Debug)]
enum Stop {
    /// The file ends inside a record (a run killed while it wrote).
    Cut(String),
    /// A record failed a check.
    Damaged(String),
}

impl std::fmt::Display for Stop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Stop::Cut(s) | Stop::Damaged(s) => f.write_str(s),
        }
    }
}

impl From<McapError> for Stop {
    fn from(e: McapError) -> Self {
        match e {
            McapError::UnexpectedEof => Stop::Cut(e.to_string()),
            other => Stop::Damaged(other.to_string()),
        }
    }
}

/// Checks that the length-prefixed fields of a schema or channel record stay within it
/// before the mcap crate parses it: its parser allocates a string of the length a prefix
/// claims before reading it, so one damaged byte could ask for 4 GiB.
fn check_prefixes(opcode: u8, data: &[u8]) -> std::result::Result<(), Stop> {
    let mut rest = data;
    let bad = || Stop::Damaged(format!("record {opcode:#04x} has a length beyond its end"));
    let skip = |n: usize, rest: &mut &[u8]| -> std::result::Result<(), Stop> {
        if rest.len() < n {
            return Err(bad());
        }
        *rest = &rest[n..];
        Ok(())
    };
    fn prefix(rest: &[u8]) -> Option<usize> {
        Some(u32::from_le_bytes(rest.get(..4)?.try_into().ok()?) as usize)
    }
    let field = |rest: &mut &[u8]| -> std::result::Result<(), Stop> {
        let n = prefix(rest).ok_or_else(bad)?;
        skip(4, rest)?;
        skip(n, rest)
    };
    use mcap::records::op;
    match opcode {
        op::SCHEMA => {
            skip(2, &mut rest)?;
            for _ in 0..3 {
                field(&mut rest)?;
            }
        }
        op::CHANNEL => {
            skip(4, &mut rest)?;
            field(&mut rest)?;
            field(&mut rest)?;
            let n = prefix(rest).ok_or_else(bad)?;
            skip(4, &mut rest)?;
            let mut map = rest.get(..n).ok_or_else(bad)?;
            while !map.is_empty() {
                field(&mut map)?;
                field(&mut map)?;
            }
        }
        _ => {}
    }
    Ok(())
}

/// The messages of an MCAP file in memory, in file order, each chunk's CRC checked before
/// its messages come out, every record's length capped; the first error ends the stream.
/// Only schema, channel and message records are parsed (the others are not needed and
/// some have unchecked length prefixes); the statistics record of a finished file gives
/// its message count.
struct Messages<'a> {
    reader: mcap::sans_io::LinearReader,
    channels: mcap::read::ChannelAccumulator<'static>,
    rest: &'a [u8],
    /// Past the data section: only the statistics record is looked at.
    past_data: bool,
    done: bool,
    /// The message count of the statistics record, once read.
    count: Option<u64>,
}

impl<'a> Messages<'a> {
    fn new(bytes: &'a [u8]) -> Self {
        let options = LinearReaderOptions::default()
            .with_prevalidate_chunk_crcs(true)
            .with_record_length_limit(record_limit(bytes.len()));
        Messages {
            reader: mcap::sans_io::LinearReader::new_with_options(options),
            channels: Default::default(),
            rest: bytes,
            past_data: false,
            done: false,
            count: None,
        }
    }

    fn record(
        &mut self,
        opcode: u8,
        data: &[u8],
    ) -> std::result::Result<Option<mcap::Message<'static>>, Stop> {
        use mcap::records::{Record, op};
        if self.past_data {
            if opcode == op::STATISTICS && data.len() >= 8 {
                self.count = Some(u64::from_le_bytes(data[..8].try_into().expect("8 bytes")));
            }
            return Ok(None);
        }
        match opcode {
            op::DATA_END => self.past_data = true,
            op::SCHEMA | op::CHANNEL | op::MESSAGE => {
                check_prefixes(opcode, data)?;
                match mcap::parse_record(opcode, data)? {
                    Record::Schema { header, data } => {
                        self.channels
                            .add_schema(header, std::borrow::Cow::Owned(data.into_owned()))?;
                    }
                    Record::Channel(c) => self.channels.add_channel(c)?,
                    Record::Message { header, data } => {
                        let channel = self
                            .channels
                            .get(header.channel_id)
                            .ok_or(McapError::UnknownChannel(header.sequence, header.channel_id))?;
                        return Ok(Some(mcap::Message {
                            channel,
                            sequence: header.sequence,
                            log_time: header.log_time,
                            publish_time: header.publish_time,
                            data: std::borrow::Cow::Owned(data.into_owned()),
                        }));
                    }
                    _ => {}
                }
            }
            _ => {}
        }
        Ok(None)
    }
}

impl Iterator for Messages<'_> {
    type Item = std::result::Result<mcap::Message<'static>, Stop>;

    fn next(&mut self) -> Option<Self::Item> {
        use mcap::sans_io::LinearReadEvent;
        if self.done {
            return None;
        }
        loop {
            let event = match self.reader.next_event()? {
                Ok(e) => e,
                Err(e) => {
                    self.done = true;
                    return Some(Err(e.into()));
                }
            };
            match event {
                LinearReadEvent::ReadRequest(need) => {
                    let n = need.min(self.rest.len());
                    self.reader.insert(n).copy_from_slice(&self.rest[..n]);
                    self.reader.notify_read(n);
                    self.rest = &self.rest[n..];
                }
                LinearReadEvent::Record { opcode, data } => {
                    let data = data.to_vec();
                    match self.record(opcode, &data) {
                        Ok(Some(m)) => return Some(Ok(m)),
                        Ok(None) => {}
                        Err(e) => {
                            self.done = true;
                            return Some(Err(e));
                        }
                    }
                }
            }
        }
    }
}

/// Splits a checkpoint message into step and state, checking its CRC (layout v2); a v1
/// message (records written before the CRC) has none to check. `Err` says what is wrong.
pub(super) fn checkpoint_message(data: &[u8], v1: bool) -> std::result::Result<(u64, Vec<u8>), String> {
    let body = if v1 {
        data
    } else {
        if data.len() < 12 {
            return Err(format!("{} bytes, fewer than its 12-byte frame", data.len()));
        }
        let (body, crc) = data.split_at(data.len() - 4);
        let saved = u32::from_le_bytes(crc.try_into().expect("4 bytes"));
        let calculated = crc32fast::hash(body);
        if saved != calculated {
            return Err(format!(
                "CRC mismatch (saved {saved:08x}, calculated {calculated:08x})"
            ));
        }
        body
    };
    if body.len() < 8 {
        return Err("shorter than 8 bytes".into());
    }
    let (step, state) = body.split_at(8);
    Ok((
        u64::from_le_bytes(step.try_into().expect("8 bytes")),
        state.to_vec(),
    ))
}

/// The MCAP file of `path`: the file itself or `run.mcap` in a run directory.
fn mcap_path(path: &Path) -> PathBuf {
    if path.is_dir() {
        path.join(MCAP_FILE)
    } else {
        path.to_path_buf()
    }
}

/// A directory that `cdlab archive` wrote: no record, the archived configuration or the
/// thinned series (only an archive writes one: an archived test whose configuration was
/// lost is still one, and says so, rather than "run.mcap: No such file").
pub fn is_archived(dir: &Path) -> bool {
    dir.is_dir()
        && !dir.join(MCAP_FILE).exists()
        && (dir.join(ARCHIVED_CONFIG_FILE).exists() || dir.join(THINNED_SERIES_FILE).exists())
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
    Ok((rows, Config::load_archived(&dir.join(ARCHIVED_CONFIG_FILE))))
}

/// Reads only the configuration of a run (`path` as for [`read_run`]). The recorder writes
/// it first and its chunks are small, so the file's first megabyte normally holds it: a sweep
/// checks every finished test of a campaign this way without reading whole records. A head
/// that does not hold it falls back to [`read_run`], with its errors.
///
/// A directory written by `cdlab archive` holds no record but the test's configuration as
/// [`ARCHIVED_CONFIG_FILE`]: that file is read instead.
pub fn read_config(path: impl AsRef<Path>) -> Result<Config> {
    let dir = path.as_ref();
    if is_archived(dir) {
        return Config::load_archived(&dir.join(ARCHIVED_CONFIG_FILE));
    }
    RunRecord {
        config_json: read_head(dir)?.config_json,
        ..Default::default()
    }
    .config()
}

/// The run identity a record holds (`path` as for [`read_run`]), read from its head like
/// [`read_config`]; `None` for a record written before records had one.
pub fn read_run_id(path: impl AsRef<Path>) -> Result<Option<String>> {
    Ok(read_head(path.as_ref())?.run_id)
}

/// The `/config` message of a record, from the first megabyte of the file when it holds
/// it, else from a whole read.
fn read_head(dir: &Path) -> Result<Head> {
    use std::io::Read;
    let path = mcap_path(dir);
    let mut head = Vec::new();
    std::fs::File::open(&path)
        .and_then(|f| f.take(1 << 20).read_to_end(&mut head))
        .map_err(|e| Error::io(&path, e))?;
    let first = Messages::new(&head)
        .map_while(|m| m.ok())
        .find(|m| {
            m.channel.topic == TOPIC_CONFIG
                && m.channel.schema.as_ref().map(|s| s.name.as_str()) == Some(CONFIG_SCHEMA)
        })
        .and_then(|m| config_message(&m.data).ok());
    Ok(match first {
        Some(head) => head,
        None => {
            let run = read_run(&path)?;
            Head {
                version: run.version,
                config_json: run.config_json,
                run_id: run.run_id,
                backend: run.backend,
                backends: run.backends,
            }
        }
    })
}

/// Reads a run from `path`: the MCAP file itself, or a run directory holding `run.mcap`.
///
/// A file cut short is read up to its last complete chunk, a damaged one up to the damage
/// ([`RunRecord::damaged`]). A file that is not MCAP, or an MCAP file that is not a cdlab
/// run (no intact `/config` message of schema `cdlab.Config`), is an error naming the file.
///
/// A directory written by `cdlab archive` (configuration, summary and thinned series, no
/// record) is an error that says so: snapshots and checkpoints went with the record.
pub fn read_run(path: impl AsRef<Path>) -> Result<RunRecord> {
    let path = path.as_ref();
    if is_archived(path) {
        return Err(Error::Archived {
            dir: path.to_path_buf(),
            thinned: THINNED_SERIES_FILE,
            record: MCAP_FILE,
        });
    }
    let path = mcap_path(path);
    let bytes = crate::fsio::read(&path).map_err(|e| Error::io(&path, e))?;
    parse_run(&bytes).map_err(|e| match e {
        Error::BadRecord { path: None, message } => Error::BadRecord {
            path: Some(path),
            message,
        },
        other => other,
    })
}

/// Reads a run from the bytes of its MCAP file, as [`read_run`] does (errors do not name
/// the file: the caller knows it). Any input gives a record or an error, never a panic,
/// and allocates at most a bounded multiple of its length.
pub fn parse_run(bytes: &[u8]) -> Result<RunRecord> {
    let bad = |message: String| Error::BadRecord { path: None, message };
    let mut run = RunRecord::default();
    let mut have_config = false;
    // Ends the read at damaged content: what came before stays usable.
    let stop = |run: &mut RunRecord, n: usize, why: String| {
        let why = format!("damaged after {n} intact messages: {why}");
        run.truncated = Some(why.clone());
        run.damaged = Some(why);
    };
    // Each channel numbers its messages 0, 1, 2...: a jump means a whole record (a chunk
    // whose opcode was damaged, say) was skipped by the MCAP reader without an error. The
    // data channels start at 0, so a chunk lost before a channel's first message read is a
    // jump too (a damaged opcode of the first chunk once handed out the rows after it).
    let mut next_seq: std::collections::HashMap<u16, u32> = Default::default();
    let mut n_read = 0u64;
    let mut messages = Messages::new(bytes);
    for (n_messages, item) in messages.by_ref().enumerate() {
        let msg = match item {
            Ok(m) => m,
            Err(e) if n_messages == 0 => {
                return Err(bad(format!(
                    "not a cdlab run, or damaged before its first message (unreadable MCAP: {e})"
                )));
            }
            Err(Stop::Cut(e)) => {
                run.truncated = Some(format!("stopped after {n_messages} messages: {e}"));
                break;
            }
            Err(Stop::Damaged(e)) => {
                stop(&mut run, n_messages, e);
                break;
            }
        };
        let schema = msg.channel.schema.as_ref().map(|s| s.name.as_str());
        let seq = msg.sequence;
        let ours = [TOPIC_CONFIG, TOPIC_SERIES, TOPIC_SNAPSHOT, TOPIC_CHECKPOINT];
        if ours.contains(&msg.channel.topic.as_str()) {
            let first = (msg.channel.topic != TOPIC_CONFIG).then_some(0);
            let expected = next_seq.insert(msg.channel.id, seq.wrapping_add(1)).or(first);
            if let Some(expected) = expected.filter(|e| *e != seq) {
                stop(
                    &mut run,
                    n_messages,
                    if expected == 0 {
                        format!(
                            "the first {} message read is number {seq}: the records before it \
                             were lost",
                            msg.channel.topic
                        )
                    } else {
                        format!(
                            "{} message {seq} follows message {}: records between them were lost",
                            msg.channel.topic,
                            expected.wrapping_sub(1)
                        )
                    },
                );
                break;
            }
        }
        n_read += 1;
        // A cdlab topic with a foreign or newer schema is refused rather than misread.
        let expect = |names: &[&str]| {
            if names.iter().any(|n| schema == Some(*n)) {
                Ok(())
            } else {
                Err(bad(format!(
                    "topic {} has schema {schema:?}, expected {}",
                    msg.channel.topic,
                    names.join(" or ")
                )))
            }
        };
        match msg.channel.topic.as_str() {
            TOPIC_CONFIG => {
                expect(&[CONFIG_SCHEMA])?;
                if have_config {
                    continue; // the first configuration is the run's
                }
                let head = config_message(&msg.data).map_err(bad)?;
                run.version = head.version;
                run.config_json = head.config_json;
                run.run_id = head.run_id;
                run.backend = head.backend;
                run.backends = head.backends;
                have_config = true;
            }
            TOPIC_SERIES => {
                expect(&[SERIES_SCHEMA])?;
                match serde_json::from_slice(&msg.data) {
                    Ok(row) => run.series.push(row),
                    Err(e) => {
                        stop(&mut run, n_messages, format!("/series message {seq}: {e}"));
                        break;
                    }
                }
            }
            TOPIC_SNAPSHOT => {
                expect(&[SNAPSHOT_SCHEMA])?;
                match Snapshot::decode(&msg.data) {
                    Ok(snap) => run.snapshots.push(snap),
                    Err(e) => {
                        stop(&mut run, n_messages, format!("/snapshot message {seq}: {e}"));
                        break;
                    }
                }
            }
            TOPIC_CHECKPOINT => {
                expect(&[CHECKPOINT_SCHEMA, CHECKPOINT_SCHEMA_V1])?;
                match checkpoint_message(&msg.data, schema == Some(CHECKPOINT_SCHEMA_V1)) {
                    Ok(ck) => run.last_checkpoint = Some(ck),
                    Err(e) => {
                        stop(&mut run, n_messages, format!("/checkpoint message {seq}: {e}"));
                        break;
                    }
                }
            }
            // Other topics (added by tools or later versions) are not ours to interpret.
            _ => {}
        }
    }
    // A complete file counts its messages in its summary: fewer read means records at the
    // end were skipped (all those read are intact, so the last checkpoint stands).
    if run.truncated.is_none()
        && let Some(count) = messages.count
        && count != n_read
    {
        let why = format!("damaged: its summary counts {count} messages, {n_read} were read intact");
        run.truncated = Some(why.clone());
        run.damaged = Some(why);
    }
    // The indexes other readers seek through (Foxglove, the Python `mcap` package) are in
    // the summary section, which this reader does not use: its CRC is checked so that
    // damage there is found here, not by them.
    // Checked even when the stream stopped early: a damaged length there reads as a cut.
    if run.damaged.is_none()
        && let Some(why) = summary_section_fault(bytes)
    {
        run.truncated = Some(why.clone());
        run.damaged = Some(why);
    }
    if !have_config {
        let why = run.truncated.as_deref().unwrap_or("complete file");
        return Err(bad(format!(
            "not a cdlab run: no intact /config message of schema {CONFIG_SCHEMA} ({why})"
        )));
    }
    Ok(run)
}

/// Why the summary section of a complete MCAP file (`bytes`, ending with its footer and
/// magic) fails its check, if it does: the footer's `summary_crc` is the CRC-32 of every
/// byte from the summary's start up to that field. `None` for a file that does not end with
/// a footer (cut short: the streaming read says so), a file without a summary section, or a
/// CRC of 0 (the format's "not computed").
pub(super) fn summary_section_fault(bytes: &[u8]) -> Option<String> {
    // Footer record: opcode (1), length (8), summary_start (8), summary_offset_start (8),
    // summary_crc (4); then the closing magic (8).
    const FOOTER: usize = 1 + 8 + 8 + 8 + 4;
    let n = bytes.len();
    if n < FOOTER + 8 || bytes[n - 8..] != *mcap::MAGIC {
        return None;
    }
    let footer = &bytes[n - 8 - FOOTER..n - 8];
    let u64_at = |k: usize| u64::from_le_bytes(footer[k..k + 8].try_into().expect("8 bytes"));
    if footer[0] != mcap::records::op::FOOTER || u64_at(1) != 20 {
        return Some("damaged: the footer record is not where the file's end puts it".into());
    }
    let start = u64_at(9);
    let saved = u32::from_le_bytes(footer[25..29].try_into().expect("4 bytes"));
    if start == 0 || saved == 0 {
        return None;
    }
    let crc_field = n - 8 - 4;
    let Some(section) = usize::try_from(start).ok().and_then(|s| bytes.get(s..crc_field)) else {
        return Some(format!(
            "damaged: the footer puts the summary section at byte {start}, past the footer"
        ));
    };
    let calculated = crc32fast::hash(section);
    (calculated != saved).then(|| {
        format!(
            "damaged summary section (the chunk indexes other readers seek through): CRC \
             mismatch (saved {saved:08x}, calculated {calculated:08x})"
        )
    })
}
