//! `cdlab prepare`: deposit and compact a sample once, to reuse it across tests
//! (`cdlab biaxial --sample FILE`), as the paper reuses one sample per friction value.

use std::path::PathBuf;

use crate::error::{Error, Result, RunFault};
use crate::run;

/// Options of `cdlab prepare`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Where to write the prepared sample.
    #[arg(short, long)]
    pub output: PathBuf,
    /// Configuration file (TOML); the built-in default when absent.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Number of disks.
    #[arg(long)]
    pub disks: Option<usize>,
    /// Seed of the grain sizes.
    #[arg(long)]
    pub seed: Option<u64>,
    /// cpu, gpu or auto.
    #[arg(long)]
    pub backend: Option<String>,
    /// Replace an existing output file.
    #[arg(long)]
    pub force: bool,
}

/// Runs `cdlab prepare`.
pub fn run(args: &Args) -> Result<()> {
    // A link, a FIFO or a device under that name is refused with or without --force; a
    // dangling link counts as existing (`exists()` would follow it and say no).
    crate::fsio::check_replaceable(&args.output)?;
    if args.output.symlink_metadata().is_ok() && !args.force {
        return Err(Error::Run {
            path: args.output.clone(),
            fault: RunFault::Occupied,
            message: format!("{} exists: pass --force to replace it", args.output.display()),
            remedy: None,
        });
    }
    let config = super::biaxial::configuration(&super::biaxial::Args {
        config: args.config.clone(),
        disks: args.disks,
        seed: args.seed,
        backend: args.backend.clone(),
        ..Default::default()
    })?;
    // The deposition, the compaction's equilibrium checks with the time left, its end.
    let mut progress = super::run::Progress::Own.display();
    progress.start();
    // Signals keep their default action: a sample has no checkpoint to stop at.
    let p = run::prepare(&config, &args.output, &mut progress, &run::Cancel::with_signals())?;
    let (w, h) = (p.width_m, p.height_m);
    tell!(
        "prepared sample written to {}: {} disks, {:.2} m x {:.2} m (height/width {:.2}), packing fraction {:.3}, \
         coordination {:.2}, compaction {} at t = {:.2} s, wall time {:.1} s",
        p.path.display(),
        p.scene.disks.len(),
        w,
        h,
        h / w,
        p.packing_fraction(),
        p.coordination,
        if p.compaction.settled {
            "settled"
        } else {
            "NOT settled"
        },
        p.compaction.time_s,
        p.wall_s
    );
    Ok(())
}
