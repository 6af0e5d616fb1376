//! `cdlab report DIR...`: the campaign analysis of the finished tests below the given
//! directories, written as `report.json` and `report.csv` into the first one, with the
//! figures `envelope` (Mohr-Coulomb envelopes) and `mu_macro` (macroscopic against contact
//! friction), each as PNG and SVG.

use std::path::PathBuf;

use crate::analysis::report::analyse;
use crate::campaign::collect;
use crate::error::{Error, Result};
use crate::figures::{EnvelopeFigure, MuMacroFigure, save_both};

/// Options of `cdlab report`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Run directories, or directories holding runs (searched recursively).
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Where to write report.json, report.csv and the figures (default: the first
    /// directory).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// The finished tests below `dirs` and the runs that could not be read or are unfinished;
/// an error when a directory does not exist, or when no test is finished and `need_one`.
pub(super) fn collect_dirs(dirs: &[PathBuf], need_one: bool) -> Result<Collected> {
    for d in dirs {
        if !d.is_dir() {
            return Err(Error::io(
                d,
                std::io::Error::new(std::io::ErrorKind::NotADirectory, "not a directory"),
            ));
        }
    }
    let (points, missing) = collect(dirs);
    if points.is_empty() && need_one {
        return Err(Error::Campaign {
            path: dirs.first().cloned().unwrap_or_default(),
            tests: Vec::new(),
            message: format!(
                "no finished test (summary.json) below {dirs:?}{}",
                reasons(&missing)
            ),
        });
    }
    Ok((points, missing))
}

/// Why the runs found are not finished tests, one line each (the first ten): a single test
/// directory whose summary fails its checksum said only "no finished test" before, while
/// the same test in a campaign was listed with the reason.
fn reasons(missing: &[(PathBuf, String)]) -> String {
    const SHOWN: usize = 10;
    let mut text = String::new();
    for (dir, why) in missing.iter().take(SHOWN) {
        text += &format!("\n  {}: {why}", dir.display());
    }
    if missing.len() > SHOWN {
        text += &format!("\n  and {} more", missing.len() - SHOWN);
    }
    text
}

/// What [`collect_dirs`] finds: the finished tests, and each other run with the reason.
pub(super) type Collected = (Vec<crate::analysis::report::TestPoint>, Vec<(PathBuf, String)>);

/// Runs `cdlab report`.
pub fn run(args: &Args) -> Result<()> {
    let (points, missing) = collect_dirs(&args.dirs, true)?;
    let report = analyse(&points, missing);
    let out = args.out.clone().unwrap_or_else(|| args.dirs[0].clone());
    crate::fsio::create_dir_all(&out)?;
    let json = serde_json::to_string_pretty(&report).map_err(|e| Error::Other(e.to_string()))?;
    // Each file whole or not at all (a report killed midway leaves the previous one).
    let write = crate::record::atomic::write_file;
    write(&out.join("report.json"), json.as_bytes())?;
    write(&out.join("report.csv"), report.csv().as_bytes())?;
    write(&out.join("tests.csv"), report.tests_csv().as_bytes())?;
    // The tables are the report; a figure that cannot be drawn (every friction 0 has no
    // place on a log axis) is said, not fatal.
    let figures = [
        save_both(&EnvelopeFigure { report: &report }, &out, "envelope"),
        save_both(&MuMacroFigure { report: &report }, &out, "mu_macro"),
    ];
    for f in figures {
        if let Err(e) = f {
            eprintln!("warning: figure not written: {e}");
        }
    }
    println!(
        "{} tests, {} frictions -> {} (report.json, report.csv, tests.csv, envelope.png/svg, mu_macro.png/svg)\n{}",
        points.len(),
        report.frictions.len(),
        out.display(),
        report.table()
    );
    Ok(())
}
