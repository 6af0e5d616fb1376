//! Keeping finished tests without their records: per test, its summary (`summary.json`,
//! `summary.txt`), its configuration (`config.toml`) and its time series thinned to a few
//! hundred rows. An archived test counts as finished for a campaign (checked against the
//! sweep's settings through its `config.toml`) and the campaign report reads it like a run,
//! so a campaign can be kept in a repository, moved between machines and resumed by copying
//! the archive into its output directory. An unfinished test can be kept as a slim record
//! (configuration, time series and snapshots up to its last checkpoint, that checkpoint),
//! which a campaign resumes from as from its full record.

use std::path::{Path, PathBuf};

use crate::error::{Error, Result, RunFault};
use crate::protocol::checkpoint::decode;
use crate::record::{
    ARCHIVED_CONFIG_FILE, CSV_FILE, MCAP_FILE, Recorder, THINNED_SERIES_FILE, read_config, read_run,
};

pub use crate::record::LAST_SNAPSHOT_FILE;

/// Refuses to archive `source` into `dest` when they overlap: `dest` is `source`, lies
/// inside it, or contains it. An archive written there replaces the source's own files
/// (a running test's full record became its slim copy) or is found again among the tests
/// to archive. Both are compared resolved (symbolic links, `..` and relative paths), `dest`
/// through its nearest existing ancestor when it does not exist yet.
pub fn check_apart(source: &Path, dest: &Path) -> Result<()> {
    let (s, d) = (resolved(source)?, resolved(dest)?);
    let how = if s == d {
        "is the source"
    } else if d.starts_with(&s) {
        "lies inside the source"
    } else if s.starts_with(&d) {
        "contains the source"
    } else {
        return Ok(());
    };
    Err(Error::Run {
        path: dest.to_path_buf(),
        fault: RunFault::Occupied,
        message: format!(
            "cannot archive {} into {}: the destination {how} ({} and {} resolved); archive into \
             a directory apart from the tests",
            source.display(),
            dest.display(),
            s.display(),
            d.display()
        ),
        remedy: None,
    })
}

/// `path` made absolute, with its symbolic links, `.` and `..` resolved as far as it
/// exists; the part that does not exist yet is appended as written (it holds no link).
fn resolved(path: &Path) -> Result<PathBuf> {
    use std::path::Component;
    let abs = if path.is_absolute() {
        path.to_path_buf()
    } else {
        let cwd = std::env::current_dir().map_err(|e| Error::io(".", e))?;
        cwd.join(path)
    };
    let mut out = PathBuf::new();
    for part in abs.components() {
        match part {
            Component::Prefix(_) | Component::RootDir => out.push(part),
            Component::CurDir => {}
            // `out` is canonical or, past its existing part, free of links: `..` is its parent.
            Component::ParentDir => {
                out.pop();
            }
            Component::Normal(name) => {
                out.push(name);
                if let Ok(real) = out.canonicalize() {
                    out = real;
                }
            }
        }
    }
    Ok(out)
}

/// Writes the last snapshot of the run in `src` into the archived test `dest`, through a
/// temporary file synced and renamed; nothing when the record holds no snapshot.
pub fn keep_last_snapshot(src: &Path, dest: &Path) -> Result<()> {
    let rec = read_run(src)?;
    let Some(snap) = rec.snapshots.last() else {
        return Ok(());
    };
    let bytes = snap.encode()?;
    crate::record::atomic::write_file(&dest.join(LAST_SNAPSHOT_FILE), &bytes)
}

/// Keeps the unfinished test in `src` as a slim record in `dest` (see the module
/// documentation) and returns the step of its checkpoint. A finished test in `dest`, an
/// unfinished one of other settings, or a `dest` that overlaps `src` ([`check_apart`]), is
/// an error.
pub fn archive_unfinished(src: &Path, dest: &Path) -> Result<u64> {
    check_apart(src, dest)?;
    crate::record::atomic::remove_stale_tmps(dest, None);
    if dest.join("summary.json").exists() {
        return Err(occupied(
            dest,
            format!("{} already holds this test finished", dest.display()),
        ));
    }
    let rec = read_run(src)?;
    let config = rec.config()?;
    let Some((step, bytes)) = &rec.last_checkpoint else {
        return Err(Error::Run {
            path: src.to_path_buf(),
            fault: RunFault::NoCheckpoint,
            message: "no checkpoint yet, nothing to resume from".into(),
            remedy: None,
        });
    };
    check_same_test(dest, &config)?;
    let time = decode(bytes)?.scene.time;
    // Written beside the destination and moved in place: an archive is never left with a
    // half-written record.
    let mut name = dest.file_name().unwrap_or_default().to_os_string();
    name.push(".part");
    let part = dest.with_file_name(name);
    let _ = std::fs::remove_dir_all(&part);
    let mut recorder = Recorder::create(&part, &config)?;
    for row in rec.series.iter().filter(|r| r.step <= *step) {
        recorder.series(row)?;
    }
    // The snapshots up to the checkpoint go with it: the finished test's shear bands are
    // found from all its snapshots, and a slim record without them ended with none
    // ("fewer than two snapshots") where the uninterrupted test had its bands.
    for snap in rec.snapshots.iter().filter(|s| s.time_s <= time) {
        recorder.snapshot(snap)?;
    }
    recorder.checkpoint(*step, time, bytes)?;
    recorder.finish()?;
    // The sweep writes the CSV again when it resumes.
    let csv = part.join(CSV_FILE);
    std::fs::remove_file(&csv).map_err(|e| Error::io(&csv, e))?;
    crate::fsio::create_dir_all(dest)?;
    // Through the atomic rename: synced, and never over a link or a device.
    crate::record::atomic::rename(&part.join(MCAP_FILE), &dest.join(MCAP_FILE))?;
    let _ = std::fs::remove_dir_all(&part);
    Ok(*step)
}

/// False when `dest` holds another test than `config`'s (a slim record or an archived
/// test); true when it holds this one or nothing. Where the test was run from
/// (`output.dir`) does not count: a campaign may move.
pub fn same_test(dest: &Path, config: &crate::config::Config) -> Result<bool> {
    if !dest.join(MCAP_FILE).exists() && !dest.join(ARCHIVED_CONFIG_FILE).exists() {
        return Ok(true);
    }
    let mut kept = read_config(dest)?;
    kept.output.dir.clone_from(&config.output.dir);
    Ok(&kept == config)
}

/// An error when `dest` holds another test than `config`'s ([`same_test`]).
fn check_same_test(dest: &Path, config: &crate::config::Config) -> Result<()> {
    if same_test(dest, config)? {
        return Ok(());
    }
    Err(occupied(
        dest,
        format!(
            "{} already holds another test: archive into another directory",
            dest.display()
        ),
    ))
}

/// An [`Error::Run`] for an archive directory that holds another test, or this one finished.
fn occupied(dest: &Path, message: String) -> Error {
    Error::Run {
        path: dest.to_path_buf(),
        fault: RunFault::Occupied,
        message,
        remedy: None,
    }
}

/// What archiving one finished test did.
pub enum Archived {
    /// Newly archived.
    Written,
    /// Already there with another summary (written again by `cdlab summarize`, or the
    /// test run again with the same configuration): the summary replaced.
    Updated,
    /// Already there with this very summary.
    Same,
}

/// Archives the finished test in `src` to `dest`, its series thinned to about
/// `series_rows` rows (none kept at 0), with its last snapshot when `keep_snapshot`. A
/// different test already in `dest` is an error: an archive never overwrites one test with
/// another; so is a `dest` that overlaps `src` ([`check_apart`]).
pub fn archive_finished(
    src: &Path,
    dest: &Path,
    series_rows: usize,
    keep_snapshot: bool,
) -> Result<Archived> {
    check_apart(src, dest)?;
    // An archive is kept and copied whole: a killed archive's temporary files must not
    // stay in it, even when this test is already there and nothing is written.
    crate::record::atomic::remove_stale_tmps(dest, None);
    let read = |p: &Path| std::fs::read(p).map_err(|e| Error::io(p, e));
    // Checked as the report and the sweep check it (its checksum, its record): an archive
    // never carries a damaged or stale summary on.
    crate::run::read_checked_summary(src)?;
    let summary = read(&src.join("summary.json"))?;
    let kept = dest.join("summary.json");
    // The configuration first: a run whose record cannot give it is not archived at all.
    let config = read_config(src)?;
    if kept.exists() {
        if read(&kept)? == summary {
            return Ok(Archived::Same);
        }
        // The same test with another summary: one written again by `cdlab summarize`.
        if !same_test(dest, &config)? {
            return Err(occupied(
                dest,
                format!(
                    "{} already holds another test than {}: archive into another directory",
                    dest.display(),
                    src.display()
                ),
            ));
        }
        let write = |name: &str| {
            let (from, to) = (src.join(name), dest.join(name));
            crate::record::atomic::write_file(&to, &read(&from)?)
        };
        write("summary.txt")?;
        write("summary.json")?;
        return Ok(Archived::Updated);
    }
    check_same_test(dest, &config)?;
    let config = crate::config::with_checksum(&config.to_toml_string()?);
    crate::fsio::create_dir_all(dest)?;
    let write = |name: &str, bytes: &[u8]| crate::record::atomic::write_file(&dest.join(name), bytes);
    write(ARCHIVED_CONFIG_FILE, config.as_bytes())?;
    let text = src.join("summary.txt");
    if text.exists() {
        write("summary.txt", &read(&text)?)?;
    }
    if series_rows > 0 {
        let thinned = src.join(THINNED_SERIES_FILE);
        if src.join(MCAP_FILE).exists() {
            // From the record, whose every chunk is checked, never from `series.csv`
            // beside it: a CSV cut short, with a torn last row or a flipped digit was
            // copied on as it was, and a missing one left the archive without a series.
            write(
                THINNED_SERIES_FILE,
                thin_csv(&record_csv(src)?, series_rows).as_bytes(),
            )?;
        } else if thinned.exists() {
            // An archived test keeps only its thinned series; archiving it again copies
            // that, once it reads as a series.
            let csv = std::fs::read_to_string(&thinned).map_err(|e| Error::io(&thinned, e))?;
            crate::record::parse_csv(&csv)
                .map_err(|e| Error::io(&thinned, std::io::Error::new(std::io::ErrorKind::InvalidData, e)))?;
            write(THINNED_SERIES_FILE, csv.as_bytes())?;
        }
    }
    if keep_snapshot && src.join(MCAP_FILE).exists() {
        keep_last_snapshot(src, dest)?;
    }
    // The summary last: a directory with one is a finished test to the sweep and the report.
    write("summary.json", &summary)?;
    // A slim record kept while the test was unfinished is no longer needed.
    let slim = dest.join(MCAP_FILE);
    if slim.exists() && src.join(MCAP_FILE).exists() {
        std::fs::remove_file(&slim).map_err(|e| Error::io(&slim, e))?;
    }
    Ok(Archived::Written)
}

/// The time series of the finished test in `src` as CSV (what its `series.csv` holds when
/// intact), read from its record. A record that is damaged or cut short is an error naming
/// it: its rows would not be the whole test.
fn record_csv(src: &Path) -> Result<String> {
    let rec = read_run(src)?;
    if let Some(why) = rec.damaged.as_ref().or(rec.truncated.as_ref()) {
        let path = src.join(MCAP_FILE);
        return Err(Error::Run {
            path: path.clone(),
            fault: RunFault::Damaged,
            message: format!(
                "{}: {why}: its series would not be the whole test, not archived; resuming \
                 the run repairs it",
                path.display()
            ),
            remedy: Some(crate::error::Remedy::Resume(src.to_path_buf())),
        });
    }
    let mut csv = crate::record::csv_header();
    csv.push('\n');
    for row in &rec.series {
        csv.push_str(&row.csv_line());
        csv.push('\n');
    }
    Ok(csv)
}

/// The header and at most about `rows` data rows of a CSV text: every k-th row from the
/// first, and the last row always.
pub fn thin_csv(csv: &str, rows: usize) -> String {
    let mut lines = csv.lines();
    let mut out = String::new();
    let Some(header) = lines.next() else {
        return out;
    };
    out.push_str(header);
    out.push('\n');
    let data: Vec<&str> = lines.filter(|l| !l.is_empty()).collect();
    if data.is_empty() || rows == 0 {
        return out;
    }
    let every = data.len().div_ceil(rows).max(1);
    for (k, line) in data.iter().enumerate() {
        if k % every == 0 || k + 1 == data.len() {
            out.push_str(line);
            out.push('\n');
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::thin_csv;

    /// 10 rows thinned to about 4: rows 0, 3, 6, 9 (every third, the last one included);
    /// 10 rows to 20 keeps all; a header alone stays a header.
    #[test]
    fn thinning_keeps_every_kth_row_and_the_last() {
        let csv: String = std::iter::once("h".to_string())
            .chain((0..10).map(|k| k.to_string()))
            .collect::<Vec<_>>()
            .join("\n");
        assert_eq!(thin_csv(&csv, 4), "h\n0\n3\n6\n9\n");
        assert_eq!(thin_csv(&csv, 3), "h\n0\n4\n8\n9\n");
        assert_eq!(thin_csv(&csv, 20).lines().count(), 11);
        assert_eq!(thin_csv("h\n", 5), "h\n");
        assert_eq!(thin_csv(&csv, 0), "h\n");
    }
}
