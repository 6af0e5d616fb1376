//! cdlab: a numerical laboratory for granular materials made of rigid frictional disks.
//!
//! It implements Moreau and Jean's nonsmooth contact dynamics (no contact stiffness, no
//! damping; impulses solved by nonlinear Gauss-Seidel) on a CPU reference path and in WGSL
//! compute shaders, and runs the biaxial test of Taboada, Chang, Radjai and Bouchette (2005).
//!
//! Module map (dependencies point down the list):
//! - [`cli`]: the `cdlab` command line;
//! - [`record`]: run records (MCAP + CSV), written during a run and read back;
//! - [`config`]: the run configuration (TOML with units);
//! - [`model`]: disks, walls, material (the state a backend steps);
//! - [`error`]: the error type.

pub mod cli;
pub mod config;
pub mod error;
pub mod model;
pub mod record;

pub use error::{Error, Result};
