//! `cdlab fabric RUN [--at STRAIN] [-o DIR]`: the microstructure of a recorded run's
//! snapshot (`crate::measure::micro`, docs/micromechanics.md): fabric and force
//! anisotropies, the strong and weak networks, the Love-Weber stress against the boundary
//! stresses, the force-chain observables; with the rose diagram and the force PDF as
//! figures (PNG and SVG). An archived test can be analysed when it was archived with
//! `--keep-last-snapshot` (its last snapshot, with the area from its thinned series).
//! The analysis is the library's (`crate::record::Snapshot::fabric`); this file parses,
//! prints and draws.

use std::path::PathBuf;

use super::fabric_report::report;
use crate::error::{Error, Result};
use crate::figures::rose::{ForcePdfFigure, RoseFigure};
use crate::record::{pick_snapshot, read_snapshots};

/// Options of `cdlab fabric`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The run directory (or its run.mcap).
    pub run: PathBuf,
    /// Analyse the snapshot nearest this axial strain (default: the last snapshot).
    #[arg(long)]
    pub at: Option<f64>,
    /// Directory for the figures (rose.png/svg, force_pdf.png/svg); default: `fabric/` in
    /// the run directory.
    #[arg(short = 'o', long = "out")]
    pub out: Option<PathBuf>,
}

/// Runs `cdlab fabric`.
pub fn run(args: &Args) -> Result<()> {
    if let Some(at) = args.at.filter(|a| !a.is_finite() || *a < 0.0) {
        return Err(Error::invalid("--at", at, "an axial strain (>= 0)"));
    }
    let (snapshots, series) = read_snapshots(&args.run)?;
    let snap = pick_snapshot(&snapshots, args.at, &args.run)?;
    // The snapshot analysed is printed below; a strain asked for that has none is said too.
    if let Some(at) = args.at
        && let Some(note) = super::render::not_exact(&snapshots, snap.strain, at, "analysing")
    {
        eprintln!("{note}");
    }
    let fabric = snap.fabric(&series, &args.run)?;
    let a = &fabric.analysis;
    print!("{}", report(a, snap.strain, snap.time_s, fabric.row));
    let dir = match &args.out {
        Some(d) => d.clone(),
        None if args.run.is_dir() => args.run.join("fabric"),
        None => args.run.with_file_name("fabric"),
    };
    crate::fsio::create_dir_all(&dir)?;
    let title = format!("contact orientations at axial strain {:.4}", snap.strain);
    let rose = RoseFigure {
        all: &a.rose_all,
        strong: &a.rose_strong,
        title,
    };
    let [p1, p2] = crate::figures::save_both(&rose, &dir, "rose")?;
    let pdf = ForcePdfFigure {
        pdf: &a.pdf,
        title: format!("normal force distribution at axial strain {:.4}", snap.strain),
    };
    let [p3, p4] = crate::figures::save_both(&pdf, &dir, "force_pdf")?;
    for p in [p1, p2, p3, p4] {
        println!("wrote {}", p.display());
    }
    Ok(())
}
