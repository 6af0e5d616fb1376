//! `cdlab fc2d FILE`: solve a Siconos 2D frictional contact problem.

use std::path::PathBuf;

use crate::error::{Error, Result, check_positive};
use crate::fc2d::{SolveOptions, read, solve};

/// Options of `cdlab fc2d`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The problem file (Siconos fc2d text format).
    pub file: PathBuf,
    /// Target Siconos error (dimensionless).
    #[arg(long, default_value_t = 1e-5)]
    pub tol: f64,
    /// Gauss-Seidel sweep cap.
    #[arg(long, default_value_t = 100_000)]
    pub max_iter: usize,
}

/// Runs `cdlab fc2d`.
pub fn run(args: &Args) -> Result<()> {
    check_positive("--tol", args.tol)?;
    let p = read(&args.file)?;
    let rep = solve(
        &p,
        &SolveOptions {
            tol: args.tol,
            max_iter: args.max_iter,
            ..Default::default()
        },
    );
    println!("file        {}", args.file.display());
    println!("contacts    {}", rep.contacts);
    println!("iterations  {} Gauss-Seidel sweeps", rep.iterations);
    println!("time        {:.3} ms", rep.seconds * 1e3);
    println!(
        "error       {:.3e} (Siconos relative error, dimensionless; target {:.1e})",
        rep.error, args.tol
    );
    println!("converged   {}", if rep.converged { "yes" } else { "no" });
    if rep.converged {
        Ok(())
    } else {
        Err(Error::Other(format!(
            "not converged after {} sweeps (error {:.3e})",
            rep.iterations, rep.error
        )))
    }
}
