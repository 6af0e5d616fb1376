//! `cdlab summarize DIR...`: writes the summaries of finished tests again from their
//! records, as this version computes them. A summary is derived from the recorded rows and
//! snapshots, so a test finished by an older version (whose stress-drop events were falls
//! from row to row, for instance) gets the current measures without being run again. What
//! the record does not hold is kept from the old summary: the backend's name and the wall
//! time.

use std::path::PathBuf;

use crate::campaign::NOT_RUN;
use crate::error::{Error, Result};
use crate::record::MCAP_FILE;

/// Options of `cdlab summarize`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Run directories, or directories holding runs (searched recursively).
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Say what would change without writing anything.
    #[arg(long)]
    pub dry_run: bool,
}

pub use crate::run::{Summarized as Outcome, summarize};

/// Runs `cdlab summarize`.
pub fn run(args: &Args) -> Result<()> {
    let (points, missing) = super::report::collect_dirs(&args.dirs, false)?;
    let (mut rewritten, mut unchanged, mut failed) = (0, 0, 0);
    for p in &points {
        match summarize(&p.dir, args.dry_run) {
            Ok(Outcome::Rewritten(keys)) => {
                rewritten += 1;
                let verb = if args.dry_run { "would change" } else { "rewritten" };
                println!("{}: {verb}: {}", p.dir.display(), keys.join(", "));
            }
            Ok(Outcome::Unchanged) => unchanged += 1,
            Err(e) => {
                failed += 1;
                println!("{}: not summarized: {e}", p.dir.display());
            }
        }
    }
    for (dir, why) in &missing {
        if why == NOT_RUN {
            continue;
        }
        // A record whose summary is missing, unreadable or another record's: rebuilt from
        // the record when it is complete.
        if dir.join(MCAP_FILE).is_file() {
            match summarize(dir, args.dry_run) {
                Ok(Outcome::Rewritten(keys)) => {
                    rewritten += 1;
                    let verb = if args.dry_run { "would change" } else { "rewritten" };
                    println!("{}: {verb}: {}", dir.display(), keys.join(", "));
                    continue;
                }
                Ok(Outcome::Unchanged) => {
                    unchanged += 1;
                    continue;
                }
                Err(e) => {
                    failed += 1;
                    println!("{}: not summarized: {e}", dir.display());
                    continue;
                }
            }
        }
        failed += 1;
        println!("{}: not summarized: {why}", dir.display());
    }
    let verb = if args.dry_run {
        "would be rewritten"
    } else {
        "rewritten"
    };
    println!("{rewritten} summaries {verb}, {unchanged} unchanged, {failed} not summarized");
    if failed > 0 && rewritten + unchanged == 0 {
        return Err(Error::Other(format!(
            "no test below {:?} could be summarized",
            args.dirs
        )));
    }
    Ok(())
}
