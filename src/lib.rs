//! cdlab: a numerical laboratory for granular materials made of rigid frictional disks.
//!
//! It implements Moreau and Jean's nonsmooth contact dynamics (no contact stiffness, no
//! damping; impulses solved by nonlinear Gauss-Seidel) on a CPU reference path and in WGSL
//! compute shaders, and runs the biaxial test of Taboada, Chang, Radjai and Bouchette (2005).
//!
//! Module map (dependencies point down the list):
//! - [`cli`]: the `cdlab` command line: parses arguments, calls [`run`] and [`campaign`],
//!   prints;
//! - [`campaign`]: campaign grids (sweep files), their grid file and test names, worker
//!   pool, shards and tests held by other processes, the collection of their summaries and
//!   the report's text table;
//! - [`run`]: the library face of a test: configure, prepare a sample, run or resume with a
//!   progress callback and a cancellation token, open a finished run (`docs/library.md`);
//! - [`figures`]: PNG and SVG figures of runs, snapshots and campaign reports;
//! - [`analysis`]: fits of the campaign (Mohr-Coulomb envelopes, friction saturation), and the
//!   shear bands of a run found in its snapshots;
//! - [`record`]: run records (MCAP + CSV), written during a run and read back: they
//!   serialise the types of [`measure`];
//! - [`fc2d`]: Siconos frictional contact problems, an outside test of the local law;
//! - [`config`]: the run configuration (TOML with units);
//! - [`protocol`]: the biaxial test's phases (preparation, confinement, compression), the
//!   gauge that turns a backend's reductions into series rows, and the prepared-sample file
//!   (a checkpoint of the compacted sample);
//! - [`sample`]: grain sizes and geometric deposition;
//! - [`gpu`]: the GPU backend (wgpu, WGSL shaders in `shaders/`);
//! - [`backend`]: the interface the protocol drives, and the CPU backend;
//! - [`measure`]: what is measured, types and their maths: series rows, phases, micromechanics
//!   (the backends' reductions fill its sums), derived strength, summaries, shear-band report;
//! - [`engine`]: the CPU reference time stepper;
//! - [`solver`]: local law, coloring, Gauss-Seidel and Jacobi sweeps;
//! - [`contact`]: contact frame, cell grid and detection;
//! - [`model`]: disks, walls, material (the state a backend steps);
//! - [`fsio`]: files written whole or not at all (temporary name, fsync, rename);
//! - [`error`]: the error type;
//! - [`interrupt`]: the cancellation token that stops a run at a checkpoint, and SIGINT or
//!   SIGTERM as one source of it (installed only by the command line).

pub mod analysis;
pub mod backend;
pub mod campaign;
pub mod cli;
pub mod config;
pub mod contact;
pub mod engine;
pub mod error;
pub mod fc2d;
pub mod figures;
pub mod fsio;
pub mod gpu;
pub mod interrupt;
pub mod measure;
pub mod model;
pub mod protocol;
pub mod record;
pub mod run;
pub mod sample;
pub mod solver;

pub use error::{Error, Result};
