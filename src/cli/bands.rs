//! `cdlab bands RUN [--from E --to E]`: the shear bands of a recorded run.

use std::path::PathBuf;

use crate::analysis::bands::{BandOptions, analyse_run};
use crate::error::{Error, Result};
use crate::record::read_run;

/// Options of `cdlab bands`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The run directory (or its run.mcap).
    pub run: PathBuf,
    /// Axial strain of the interval's start (the nearest snapshot is used; default: the
    /// second-to-last snapshot, or the first when --to is given).
    #[arg(long)]
    pub from: Option<f64>,
    /// Axial strain of the interval's end (the nearest snapshot is used; default: the last).
    #[arg(long)]
    pub to: Option<f64>,
    /// Smallest contrast, in [0, 1], reported as a band.
    #[arg(long)]
    pub min_contrast: Option<f64>,
    /// Print the report as JSON (the `shear_bands` object of summary.json) instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Runs `cdlab bands`.
pub fn run(args: &Args) -> Result<()> {
    let mut opts = BandOptions::default();
    if let Some(c) = args.min_contrast {
        if !(0.0..=1.0).contains(&c) {
            return Err(Error::invalid("--min-contrast", c, "in [0, 1]"));
        }
        opts.detect.min_contrast = c;
    }
    let rec = read_run(&args.run)?;
    let rep = analyse_run(&rec, args.from, args.to, &opts).map_err(|e| match e {
        // Kept a band-analysis error, so that a caller can tell "no bands to find here".
        Error::BandAnalysis(m) => Error::BandAnalysis(format!("{}: {m}", args.run.display())),
        e => Error::Other(format!("{}: {e}", args.run.display())),
    })?;
    if args.json {
        let json = serde_json::to_string_pretty(&rep).map_err(|e| Error::Other(e.to_string()))?;
        println!("{json}");
    } else {
        println!("shear bands of {}\n{}", args.run.display(), rep.table());
    }
    Ok(())
}
