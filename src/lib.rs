//! cdlab: a numerical laboratory for granular materials made of rigid frictional disks.
//!
//! It implements Moreau and Jean's nonsmooth contact dynamics (no contact stiffness, no
//! damping; impulses solved by nonlinear Gauss-Seidel) on a CPU reference path and in WGSL
//! compute shaders, and runs the biaxial test of Taboada, Chang, Radjai and Bouchette (2005).
//!
//! The library's face (`docs/library.md`; `examples/run_test.rs` runs it):
//! - [`run`]: one test: configure, prepare a sample, run or resume with a progress callback
//!   and a cancellation token, open a finished run or an archived test;
//! - [`campaign`]: campaign grids (sweep files), the worker pool, shards, and the collection
//!   of their summaries;
//! - [`config`]: the run configuration (TOML with units), the only source of defaults;
//! - [`record`]: run records (MCAP + CSV) read back: series, snapshots, checkpoints;
//! - [`measure`]: what is measured: series rows, phases, micromechanics, summaries;
//! - [`analysis`]: fits of a campaign (Mohr-Coulomb envelopes, friction saturation) and the
//!   shear bands of a run;
//! - [`figures`]: PNG and SVG figures of runs, snapshots and campaign reports;
//! - [`error`]: the error type.
//!
//! The types a program names most are re-exported here ([`Config`], [`RunOutcome`],
//! [`Summary`], [`SeriesRow`], ...).
//!
//! Under the face, public for the command line, the tests and the benches but hidden from
//! this documentation and not promised to stay as they are (dependencies point down the
//! list): `cli` (the `cdlab` command line, cargo feature `cli`, on by default), `protocol`
//! (the biaxial test's phases and the prepared-sample file), `sample` (grain sizes and
//! deposition), `gpu` (the WGSL backend), `backend` (the interface the protocol drives, and
//! the CPU backend), `engine` (the CPU time stepper), `solver` (local law, coloring, sweeps),
//! `contact` (detection), `model` (disks, walls, material), `fc2d` (Siconos problems),
//! `fsio` (files written whole or not at all) and `interrupt` (signals as a cancellation).

// The face: what a user's program calls (docs/library.md).
pub mod analysis;
pub mod campaign;
pub mod config;
pub mod error;
pub mod figures;
pub mod measure;
pub mod record;
pub mod run;

pub use campaign::{CampaignOutcome, Sweep};
pub use config::{Backend, Config, Method, Overrides};
pub use error::{Error, Result};
pub use measure::SeriesRow;
pub use measure::summary::Summary;
pub use record::{RunRecord, Snapshot};
pub use run::{Cancel, Event, Existing, FinishedRun, Progress, RunOutcome};

// The machinery under the face: public for the command line, the tests, the benches and
// the examples that measure it, hidden from the documentation and from what the library
// promises to keep.
#[doc(hidden)]
pub mod backend;
#[cfg(feature = "cli")]
#[doc(hidden)]
pub mod cli;
#[doc(hidden)]
pub mod contact;
#[doc(hidden)]
pub mod engine;
#[doc(hidden)]
pub mod fc2d;
#[doc(hidden)]
pub mod fsio;
#[doc(hidden)]
pub mod gpu;
#[doc(hidden)]
pub mod hugepages;
#[doc(hidden)]
pub mod interrupt;
#[doc(hidden)]
pub mod model;
#[doc(hidden)]
pub mod protocol;
#[doc(hidden)]
pub mod sample;
#[doc(hidden)]
pub mod solver;
