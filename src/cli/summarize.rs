//! `cdlab summarize DIR...`: writes the summaries of finished tests again from their
//! records, as this version computes them. A summary is derived from the recorded rows and
//! snapshots, so a test finished by an older version (whose stress-drop events were falls
//! from row to row, for instance) gets the current measures without being run again. What
//! the record does not hold is kept from the old summary: the backend's name and the wall
//! time.

use std::path::{Path, PathBuf};

use crate::analysis::report::NOT_RUN;
use crate::error::{Error, Result};
use crate::record::{MCAP_FILE, read_run};

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

/// What summarizing one test did.
#[derive(Debug, PartialEq)]
pub enum Outcome {
    /// The summary was written again; the top-level keys whose values changed.
    Rewritten(Vec<String>),
    /// The recomputed summary equals the one there (nothing written).
    Unchanged,
}

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

/// Computes the summary of the finished test in `dir` from its record and writes it (unless
/// `dry_run`) when it differs from the one there. A missing, empty or damaged summary, or
/// one of another record, is rebuilt from the record. A test without its record (an
/// archived one) or not finished is an error naming why.
pub fn summarize(dir: &Path, dry_run: bool) -> Result<Outcome> {
    if !dir.join(MCAP_FILE).exists() {
        return Err(Error::Other(format!(
            "no record ({MCAP_FILE}): an archived test keeps the summary it was archived with"
        )));
    }
    let record = read_run(dir)?;
    if let Some(why) = &record.damaged {
        return Err(Error::Other(format!(
            "{}: {why}: `cdlab biaxial --resume {}` recomputes the run from its last intact \
             checkpoint",
            dir.join(MCAP_FILE).display(),
            dir.display()
        )));
    }
    let fault = super::biaxial::summary_fault(dir, &record);
    let old = match &fault {
        None => {
            let old_path = dir.join("summary.json");
            let text = std::fs::read_to_string(&old_path).map_err(|e| Error::io(&old_path, e))?;
            Some(
                serde_json::from_str::<serde_json::Value>(&text)
                    .map_err(|e| Error::Other(format!("{}: {e}", old_path.display())))?,
            )
        }
        // The figures of another record's summary are not this one's.
        Some(_) => None,
    };
    let summary = super::biaxial::rebuild_summary(dir, &record, old.as_ref())?;
    let new = serde_json::to_value(&summary).map_err(|e| Error::Other(e.to_string()))?;
    let changed = match (&old, &fault) {
        (Some(old), None) => changed_keys(old, &new),
        _ => vec![format!("all (summary.json {})", fault.unwrap_or_default())],
    };
    // Which version wrote it is no change of the test's figures.
    if changed.iter().all(|k| k == "version") {
        return Ok(Outcome::Unchanged);
    }
    if !dry_run {
        super::biaxial::write_summary(dir, &summary)?;
    }
    Ok(Outcome::Rewritten(changed))
}

/// The top-level keys of `new` whose values differ in `old` (or that `old` lacks), and the
/// keys `old` has that `new` lacks.
fn changed_keys(old: &serde_json::Value, new: &serde_json::Value) -> Vec<String> {
    let empty = serde_json::Map::new();
    let (o, n) = (
        old.as_object().unwrap_or(&empty),
        new.as_object().unwrap_or(&empty),
    );
    let mut keys: Vec<String> = n
        .iter()
        .filter(|(k, v)| o.get(*k) != Some(v))
        .map(|(k, _)| k.clone())
        .collect();
    keys.extend(o.keys().filter(|k| !n.contains_key(*k)).cloned());
    keys
}
