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

use std::path::PathBuf;

use crate::campaign::archive::{Archived, archive_finished, archive_unfinished, check_apart};
use crate::campaign::{GRID_FILE, NOT_RUN, add_to_grid, read_grid};
use crate::error::{Error, Result};
use crate::record::MCAP_FILE;

pub use crate::campaign::archive::thin_csv;

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
    // Before anything is read or created: an archive inside, over or around its sources
    // would replace their files.
    for dir in &args.dirs {
        check_apart(dir, &args.to)?;
    }
    // Unfinished tests alone are worth keeping when asked for.
    let (points, missing) = super::report::collect_dirs(&args.dirs, !args.with_unfinished)?;
    crate::fsio::create_dir_all(&args.to)?;
    // The campaign list's, left by a killed archive (each test's go in archive_finished).
    crate::record::atomic::remove_stale_tmps(&args.to, None);
    let (mut written, mut updated, mut same) = (0, 0, 0);
    for p in &points {
        let name = p
            .dir
            .file_name()
            .ok_or_else(|| Error::Other(format!("{}: a run directory needs a name", p.dir.display())))?;
        let dest = args.to.join(name);
        match archive_finished(&p.dir, &dest, args.series_rows, args.keep_last_snapshot)? {
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
