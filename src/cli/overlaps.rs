//! `cdlab overlaps RUN [--at STRAIN] [--top N]`: where a recorded run's deepest overlaps
//! sit, snapshot by snapshot, or the deepest pairs of one snapshot.

use std::path::PathBuf;

use crate::analysis::overlaps::{PairOverlap, deepest_pairs};
use crate::error::{Error, Result, SnapshotFault};
use crate::record::nearest_snapshot;
use crate::record::read_run;

/// Options of `cdlab overlaps`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The run directory (or its run.mcap).
    pub run: PathBuf,
    /// List the deepest pairs of the snapshot nearest this axial strain; without it, the
    /// deepest pair of every snapshot (the same pair from one snapshot to the next is a
    /// contact sinking slowly under load).
    #[arg(long)]
    pub at: Option<f64>,
    /// How many pairs to list with --at.
    #[arg(long, default_value_t = 10)]
    pub top: usize,
}

fn line(p: &PairOverlap) -> String {
    format!(
        "disks {:>5}-{:<5} at ({:>8.2}, {:>8.2}) m  overlap {:6.3}% of r_min  normal force \
         {:10.4e} N/m ({:5.2} x mean)  normal velocity {:+.2e} m/s",
        p.i,
        p.j,
        p.x_m,
        p.y_m,
        p.overlap_rel * 100.0,
        p.f_n,
        p.f_n_rel,
        p.u_n
    )
}

/// Runs `cdlab overlaps`.
pub fn run(args: &Args) -> Result<()> {
    if let Some(at) = args.at.filter(|a| !a.is_finite()) {
        return Err(Error::invalid("--at", at, "an axial strain"));
    }
    let rec = read_run(&args.run)?;
    if rec.snapshots.is_empty() {
        return Err(Error::Snapshot {
            path: args.run.clone(),
            fault: SnapshotFault::NoSnapshot,
            message: format!(
                "{}: the record holds no snapshot (an archived test keeps none)",
                args.run.display()
            ),
        });
    }
    println!(
        "disk pairs only (a snapshot does not hold the walls' positions); normal velocity < 0: \
         still closing at the snapshot's step"
    );
    match args.at {
        Some(at) => {
            let k = nearest_snapshot(&rec.snapshots, at).expect("snapshots exist");
            let snap = &rec.snapshots[k];
            if let Some(note) = super::render::not_exact(&rec.snapshots, snap.strain, at, "listing") {
                eprintln!("{note}");
            }
            println!(
                "snapshot at axial strain {:.4} (t = {:.3} s):",
                snap.strain, snap.time_s
            );
            let pairs = deepest_pairs(snap, args.top);
            if pairs.is_empty() {
                println!("  no overlapping disk pair");
            }
            for p in &pairs {
                println!("  {}", line(p));
            }
        }
        None => {
            for snap in &rec.snapshots {
                let deepest = deepest_pairs(snap, 1);
                let what = deepest.first().map_or("no overlapping disk pair".into(), line);
                println!("strain {:.4} (t = {:8.3} s): {what}", snap.strain, snap.time_s);
            }
        }
    }
    Ok(())
}
