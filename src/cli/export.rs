//! `cdlab export RUN --vtk DIR`: the snapshots of a run as VTK files for ParaView.

use std::path::PathBuf;

use crate::error::{Error, Result, SnapshotFault};
use crate::record::{read_run, vtk};

/// Options of `cdlab export`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The run directory (or its run.mcap).
    pub run: PathBuf,
    /// Directory for the .vtp files and the .pvd series.
    #[arg(long)]
    pub vtk: PathBuf,
}

/// Runs `cdlab export`.
pub fn run(args: &Args) -> Result<()> {
    let rec = read_run(&args.run)?;
    if rec.snapshots.is_empty() {
        return Err(Error::Snapshot {
            path: args.run.clone(),
            fault: SnapshotFault::NoSnapshot,
            message: format!("{}: the run holds no snapshot", args.run.display()),
        });
    }
    let files = vtk::write_series(&rec.snapshots, &args.vtk)?;
    println!(
        "{} snapshots written to {} (open snapshots.pvd in ParaView)",
        files.len() - 1,
        args.vtk.display()
    );
    Ok(())
}
