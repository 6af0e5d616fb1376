//! `cdlab archive DIR... --to DEST`: the finished tests below the given directories kept
//! without their records (snapshots and checkpoints make a 5000-disk test's record tens of
//! megabytes): per test, its summary (`summary.json`, `summary.txt`), its configuration
//! (`config.toml`) and its time series thinned to a few hundred rows. An archived test
//! counts as finished for `cdlab sweep` (checked against the sweep's settings through its
//! `config.toml`) and `cdlab report` reads it like a run, so a campaign can be kept in a
//! repository, moved between machines and resumed by copying the archive into its output
//! directory.
//!
//! With `--with-unfinished`, an interrupted test is kept as a slim record instead (a test
//! another process is running now, its lock held, is skipped with a message): its configuration, its time series up to its last checkpoint and that
//! checkpoint, without snapshots (a 5000-disk test's comes to a few megabytes). The sweep
//! resumes it from there as from its full record and ends it bit for bit as an
//! uninterrupted run; only the snapshots before the checkpoint are missing from its new
//! record.

use std::path::{Path, PathBuf};

use crate::analysis::report::{GRID_FILE, NOT_RUN, add_to_grid, read_grid};
use crate::error::{Error, Result};
use crate::protocol::checkpoint::decode;
use crate::record::{
    ARCHIVED_CONFIG_FILE, CSV_FILE, MCAP_FILE, Recorder, THINNED_SERIES_FILE, read_config, read_run,
};

/// Options of `cdlab archive`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Run directories, or directories holding runs (searched recursively).
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// The archive directory; each test goes to a subdirectory of its run directory's name.
    #[arg(long)]
    pub to: PathBuf,
    /// Rows of the time series kept per test (every k-th row, the last one included);
    /// 0 keeps none.
    #[arg(long, default_value_t = 400)]
    pub series_rows: usize,
    /// Also keep the unfinished tests that have a checkpoint, as slim records the sweep
    /// resumes from (configuration, time series to the checkpoint, checkpoint).
    #[arg(long)]
    pub with_unfinished: bool,
    /// Also keep each finished test's last snapshot (`last_snapshot.bin`, the `/snapshot`
    /// layout: about 0.8 MB for 5000 disks), so that `cdlab fabric` can analyse the
    /// archived test.
    #[arg(long)]
    pub keep_last_snapshot: bool,
}

/// Runs `cdlab archive`.
pub fn run(args: &Args) -> Result<()> {
    // Unfinished tests alone are worth keeping when asked for.
    let (points, missing) = super::report::collect_dirs(&args.dirs, !args.with_unfinished)?;
    std::fs::create_dir_all(&args.to).map_err(|e| Error::io(&args.to, e))?;
    let (mut written, mut updated, mut same) = (0, 0, 0);
    for p in &points {
        let name = p
            .dir
            .file_name()
            .ok_or_else(|| Error::Other(format!("{}: a run directory needs a name", p.dir.display())))?;
        let dest = args.to.join(name);
        match archive_one(&p.dir, &dest, args.series_rows, args.keep_last_snapshot)? {
            Archived::Written => written += 1,
            Archived::Updated => {
                (same, updated) = (same + 1, updated + 1);
                println!(
                    "  summary updated (the run's differs from the archived one, e.g. written again by \
                     cdlab summarize): {}",
                    dest.display()
                );
            }
            Archived::Same => same += 1,
        }
    }
    let updated = match updated {
        0 => String::new(),
        n => format!(" ({n} with their summaries updated)"),
    };
    println!(
        "{written} tests archived, {same} already there{updated} -> {}",
        args.to.display()
    );
    // The campaign's list of tests goes with it, so that a report on the archive names the
    // tests not run yet; those have nothing to archive.
    let mut not_run = 0;
    for dir in &args.dirs {
        let grid = read_grid(dir).and_then(|names| add_to_grid(&args.to, &names));
        if let Err(e) = grid {
            println!("  campaign list not archived: {e}");
        }
    }
    let mut resumable = 0;
    for (dir, why) in &missing {
        if why == NOT_RUN {
            not_run += 1;
            continue;
        }
        // A run with a summary that could not be read is finished, not to be resumed.
        let unfinished = dir.join(MCAP_FILE).exists() && !dir.join("summary.json").exists();
        let kept = if args.with_unfinished && unfinished {
            // A test that a process is running now changes under the reader, and its
            // archived checkpoint would be stale the moment it is written: left alone.
            // Holding its lock while archiving keeps a sweep from starting it meanwhile.
            let _lock = match crate::record::RunLock::acquire(dir) {
                Ok(lock) => lock,
                Err(_) if crate::record::RunLock::held_elsewhere(dir) => {
                    println!(
                        "  running now in another process, not archived (archive it once it \
                         has ended or stopped): {}",
                        dir.display()
                    );
                    continue;
                }
                Err(e) => return Err(e),
            };
            let name = dir.file_name().unwrap_or_default();
            archive_unfinished(dir, &args.to.join(name))
        } else {
            Err(Error::Other(why.clone()))
        };
        match kept {
            Ok(step) => {
                resumable += 1;
                println!("  unfinished, kept to resume from step {step}: {}", dir.display());
            }
            Err(e) => println!("  not archived: {}: {e}", dir.display()),
        }
    }
    if args.with_unfinished {
        println!("{resumable} unfinished tests kept to resume");
    }
    if not_run > 0 {
        println!("{not_run} tests of the campaign's list ({GRID_FILE}) not run yet, nothing to archive");
    }
    Ok(())
}

/// Keeps the unfinished test in `src` as a slim record in `dest` (see the module
/// documentation) and returns the step of its checkpoint. A finished test in `dest`, or an
/// unfinished one of other settings, is an error.
fn archive_unfinished(src: &Path, dest: &Path) -> Result<u64> {
    if dest.join("summary.json").exists() {
        return Err(Error::Other(format!(
            "{} already holds this test finished",
            dest.display()
        )));
    }
    let rec = read_run(src)?;
    let config = rec.config()?;
    let Some((step, bytes)) = &rec.last_checkpoint else {
        return Err(Error::Other("no checkpoint yet, nothing to resume from".into()));
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
    recorder.checkpoint(*step, time, bytes)?;
    recorder.finish()?;
    // The sweep writes the CSV again when it resumes.
    let csv = part.join(CSV_FILE);
    std::fs::remove_file(&csv).map_err(|e| Error::io(&csv, e))?;
    std::fs::create_dir_all(dest).map_err(|e| Error::io(dest, e))?;
    let to = dest.join(MCAP_FILE);
    std::fs::rename(part.join(MCAP_FILE), &to).map_err(|e| Error::io(&to, e))?;
    let _ = std::fs::remove_dir_all(&part);
    Ok(*step)
}

/// False when `dest` holds another test than `config`'s (a slim record or an archived
/// test); true when it holds this one or nothing. Where the test was run from
/// (`output.dir`) does not count: a campaign may move.
fn same_test(dest: &Path, config: &crate::config::Config) -> Result<bool> {
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
    Err(Error::Other(format!(
        "{} already holds another test: archive into another directory",
        dest.display()
    )))
}

/// What archiving one finished test did.
enum Archived {
    /// Newly archived.
    Written,
    /// Already there with another summary (written again by `cdlab summarize`, or the
    /// test run again with the same configuration): the summary replaced.
    Updated,
    /// Already there with this very summary.
    Same,
}

/// Archives the finished test in `src` to `dest`. A different test already in `dest` is an
/// error: an archive never overwrites one test with another.
fn archive_one(src: &Path, dest: &Path, series_rows: usize, keep_snapshot: bool) -> Result<Archived> {
    let read = |p: &Path| std::fs::read(p).map_err(|e| Error::io(p, e));
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
            return Err(Error::Other(format!(
                "{} already holds another test than {}: archive into another directory",
                dest.display(),
                src.display()
            )));
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
    let config = config.to_toml_string()?;
    std::fs::create_dir_all(dest).map_err(|e| Error::io(dest, e))?;
    let write = |name: &str, bytes: &[u8]| crate::record::atomic::write_file(&dest.join(name), bytes);
    write(ARCHIVED_CONFIG_FILE, config.as_bytes())?;
    let text = src.join("summary.txt");
    if text.exists() {
        write("summary.txt", &read(&text)?)?;
    }
    if series_rows > 0 {
        let full = src.join(CSV_FILE);
        let thinned = src.join(THINNED_SERIES_FILE);
        // An archived test keeps only its thinned series; archiving it again copies that.
        let (from, rows) = if full.exists() {
            (full, series_rows)
        } else {
            (thinned, usize::MAX)
        };
        if from.exists() {
            let csv = std::fs::read_to_string(&from).map_err(|e| Error::io(&from, e))?;
            write(THINNED_SERIES_FILE, thin_csv(&csv, rows).as_bytes())?;
        }
    }
    if keep_snapshot && src.join(MCAP_FILE).exists() {
        super::fabric::keep_last_snapshot(src, dest)?;
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
