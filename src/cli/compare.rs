//! `cdlab compare RUN... -o FIG.png|svg` draws several runs' curves on common axes: the
//! stress ratio and the volumetric strain against axial strain
//! ([`crate::run::write_comparison`]). Runs may be archived tests (drawn from their thinned
//! series), so a campaign's archive compares without its records.

use std::path::PathBuf;

use crate::error::Result;

/// Options of `cdlab compare`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Run directories or archived tests, e.g. a shell glob over a campaign
    /// (`assets/results/campaign5000/seed1_mu*_s8MPa`). Drawn in order of contact friction,
    /// then confining stress.
    #[arg(required = true)]
    pub runs: Vec<PathBuf>,
    /// Output: a .png or .svg file.
    #[arg(short, long)]
    pub out: PathBuf,
    /// Title (default: what the runs share, e.g. "σ₃ = 8 MPa, 5000 disks, 13 runs").
    #[arg(long)]
    pub title: Option<String>,
}

/// Runs `cdlab compare`.
pub fn run(args: &Args) -> Result<()> {
    let n = crate::run::write_comparison(&args.runs, args.title.as_deref(), &args.out)?;
    println!("{n} runs -> {}", args.out.display());
    Ok(())
}
