//! The contact problem of one time step: local law, coloring and the iterative sweeps
//! (Gauss-Seidel in plain or colored order, relaxed Jacobi) with the convergence test of
//! method.md.

pub mod color;
pub mod law;
pub mod sweep;
mod team;

use crate::error::{Error, Result, check_positive};

/// Order in which contacts are updated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Nonlinear Gauss-Seidel in detection order (contacts sorted by body indices).
    Gs,
    /// Gauss-Seidel in color order; each color is swept in parallel.
    ColoredGs,
    /// Jacobi: every contact solved from the same velocities, impulses relaxed by `relax`.
    Jacobi,
}

impl std::str::FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "gs" => Ok(Method::Gs),
            "colored-gs" => Ok(Method::ColoredGs),
            "jacobi" => Ok(Method::Jacobi),
            _ => Err(Error::invalid(
                "solver.method",
                s,
                "one of gs, colored-gs, jacobi",
            )),
        }
    }
}

/// Parameters of the iterative contact solver.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SolverParams {
    /// Sweep order.
    pub method: Method,
    /// Tolerance on the relative quadratic change of the impulses over one iteration,
    /// `sqrt(sum |R' - R|^2) / sqrt(sum |R|^2)` (dimensionless).
    pub tol: f64,
    /// Iteration cap; reaching it is recorded in the step statistics.
    pub max_iter: u32,
    /// Jacobi relaxation factor in (0, 1].
    pub relax: f64,
    /// Use several threads for colors and Jacobi (results are bit-identical either way).
    pub parallel: bool,
    /// Smallest contact problem worth solving on several threads. Colored Gauss-Seidel
    /// then runs on a team of `threads` threads started once per step, with a spin barrier
    /// between colors; Jacobi on the rayon pool.
    #[serde(default = "default_parallel_min")]
    pub parallel_min: usize,
    /// Threads of the colored Gauss-Seidel team; 0 means every available core.
    #[serde(default)]
    pub threads: usize,
}

impl Default for SolverParams {
    fn default() -> Self {
        SolverParams {
            method: Method::ColoredGs,
            tol: 1e-4,
            max_iter: 1000,
            relax: 0.5,
            parallel: true,
            parallel_min: default_parallel_min(),
            threads: 0,
        }
    }
}

/// Default of [`SolverParams::parallel_min`]. Below a few thousand contacts a color is a
/// few chunks and the barriers between colors cost more than the halved work.
pub fn default_parallel_min() -> usize {
    4096
}

impl SolverParams {
    /// Threads of the colored Gauss-Seidel team (1 when `parallel` is off).
    pub fn team_size(&self) -> usize {
        if !self.parallel {
            return 1;
        }
        match self.threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            n => n,
        }
    }

    /// Rejects a non-positive tolerance, a zero iteration cap and a relaxation outside (0, 1].
    pub fn validate(&self) -> Result<()> {
        check_positive("solver.tol", self.tol)?;
        if self.max_iter == 0 {
            return Err(Error::invalid("solver.max_iter", 0, "must be >= 1"));
        }
        if !(self.relax > 0.0 && self.relax <= 1.0) {
            return Err(Error::invalid("solver.relax", self.relax, "must lie in (0, 1]"));
        }
        Ok(())
    }
}

/// What the solver did in one step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveStats {
    /// Iterations (sweeps over all contacts) performed.
    pub iterations: u32,
    /// True when the tolerance was met before the cap.
    pub converged: bool,
    /// The last relative quadratic change (dimensionless).
    pub residual: f64,
    /// Number of colors (0 unless colored).
    pub colors: u32,
}
