//! `cdlab render RUN --at STRAIN --field NAME -o FIG` draws the snapshot nearest a strain;
//! `cdlab render RUN --curves -o DIR` draws the stress-strain and contact-count curves.

use std::path::PathBuf;

use crate::error::{Error, Result, SnapshotFault};
use crate::figures::{self, Field, Format, ShearField, SnapshotFigure};
use crate::record::{nearest_snapshot, read_run, rotation_reference};

/// Options of `cdlab render`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The run directory (or its run.mcap).
    pub run: PathBuf,
    /// Draw the snapshot nearest this axial strain (a fraction, e.g. 0.09).
    #[arg(long, conflicts_with = "curves", required_unless_present = "curves")]
    pub at: Option<f64>,
    /// With --at: displacement, rotation, velocity, forces, or shear (the local shear strain
    /// since the snapshot before, with the shear bands found in it).
    #[arg(long, default_value = "displacement")]
    pub field: String,
    /// Draw the curves against axial strain (stress_strain and contacts, PNG and SVG) into
    /// the directory given by -o.
    #[arg(long)]
    pub curves: bool,
    /// Output: a .png or .svg file with --at, a directory with --curves.
    #[arg(short, long)]
    pub out: PathBuf,
    /// Height of a snapshot's plot area in pixels (the width follows the sample's aspect),
    /// 50 to 20000.
    #[arg(long, default_value_t = 900)]
    pub height: u32,
}

/// Largest snapshot height accepted (pixels): 20,000 px is about 30 cm at 1,600 dpi, more than
/// a poster needs, and its RGB image in memory stays in the gigabyte range.
pub const MAX_HEIGHT: u32 = 20_000;

/// Largest snapshot figure accepted, in pixels (a 20,000 x 20,000 image, 1.2 GB in RGB).
pub const MAX_PIXELS: u64 = 400_000_000;

/// Runs `cdlab render`.
pub fn run(args: &Args) -> Result<()> {
    match args.at {
        Some(at) => snapshot(args, at),
        None => curves(args),
    }
}

fn snapshot(args: &Args, at: f64) -> Result<()> {
    if !at.is_finite() {
        return Err(Error::invalid("--at", at, "must be a finite axial strain"));
    }
    let field: Field = args.field.parse()?;
    Format::from_path(&args.out)?;
    if !(50..=MAX_HEIGHT).contains(&args.height) {
        return Err(Error::invalid(
            "--height",
            args.height,
            &format!("must lie in [50, {MAX_HEIGHT}] pixels"),
        ));
    }
    let rec = read_run(&args.run)?;
    let k = nearest_snapshot(&rec.snapshots, at).ok_or_else(|| Error::Snapshot {
        path: args.run.clone(),
        fault: SnapshotFault::NoSnapshot,
        message: format!("{}: the run holds no snapshot", args.run.display()),
    })?;
    let snap = &rec.snapshots[k];
    if let Some(note) = not_exact(&rec.snapshots, snap.strain, at, "drawing") {
        eprintln!("{note}");
    }
    // Rotations count from the snapshot nearest the start of the compression recorded
    // before the one drawn (the record keeps total rotations since the deposition).
    let reference = rotation_reference(&rec.snapshots, k);
    let shear = match field {
        Field::Shear => {
            let Some(prev) = k.checked_sub(1).map(|j| &rec.snapshots[j]) else {
                return Err(Error::Snapshot {
                    path: args.run.clone(),
                    fault: SnapshotFault::NoEarlier,
                    message: "the shear field needs a snapshot before the one drawn: ask for a larger --at"
                        .into(),
                });
            };
            Some(ShearField::between(prev, snap)?)
        }
        _ => None,
    };
    let fig = SnapshotFigure {
        snap,
        reference,
        field,
        plot_height: args.height,
        shear: shear.as_ref(),
    };
    // The width follows the sample's shape: a wide sample could still ask for more pixels
    // than the memory holds (3 bytes each, drawn in memory before encoding).
    let (w, h) = figures::Figure::size(&fig);
    if u64::from(w) * u64::from(h) > MAX_PIXELS {
        return Err(Error::invalid(
            "--height",
            args.height,
            &format!(
                "the figure would be {w} x {h} pixels, above the limit of {MAX_PIXELS}: \
                 ask for a smaller height"
            ),
        ));
    }
    figures::save(&fig, &args.out)?;
    println!(
        "{} at axial strain {:.5} (requested {at}; snapshot {} of {}, t = {:.4} s) -> {}",
        field.name(),
        snap.strain,
        k + 1,
        rec.snapshots.len(),
        snap.time_s,
        args.out.display()
    );
    Ok(())
}

/// How close a snapshot's strain must be to the one asked for to count as it (the
/// strains printed have five decimals).
const SAME_STRAIN: f64 = 5e-6;

/// The note that the snapshot used, the nearest to axial strain `at` (at strain `got`), is
/// not at it: what the command does with it (`doing`: "drawing", "analysing"...), its
/// strain and where the run's `snapshots` are. `None` when it is.
pub fn not_exact(snapshots: &[crate::record::Snapshot], got: f64, at: f64, doing: &str) -> Option<String> {
    if (got - at).abs() <= SAME_STRAIN {
        return None;
    }
    let strains: Vec<String> = snapshots.iter().map(|s| format!("{:.5}", s.strain)).collect();
    let list = if strains.len() <= 12 {
        strains.join(", ")
    } else {
        format!(
            "{}, ..., {} ({} snapshots)",
            strains[..3].join(", "),
            strains[strains.len() - 3..].join(", "),
            strains.len()
        )
    };
    Some(format!(
        "note: no snapshot at axial strain {at}: {doing} the nearest, at axial strain {got:.5}. \
         The run's snapshots are at {list} (every output.snapshot_every of the compression, \
         and at the end of each phase)"
    ))
}

fn curves(args: &Args) -> Result<()> {
    for p in write_curves(&args.run, &args.out)? {
        println!("{}", p.display());
    }
    Ok(())
}

pub use crate::run::write_curves;
