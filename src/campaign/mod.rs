//! Campaigns: a grid of biaxial tests (contact friction x confining stress x sample seed)
//! described by a sweep file, run by a pool of workers, one compacted sample per seed reused
//! by every test of that seed (compaction is frictionless, so the sample does not depend on
//! the test's friction). Finished tests are skipped, half-finished ones resumed, tests that
//! another process runs (their lock is held) left to it, and a shard `I/N` runs the I-th
//! of N disjoint parts.
//!
//! ```no_run
//! use cdlab::campaign::{Options, Quiet, Sweep};
//! use cdlab::interrupt::Cancel;
//!
//! let sweep = Sweep::load("assets/campaign1000.toml".as_ref())?;
//! let options = Options { jobs: 2, ..Options::default() };
//! let outcome = cdlab::campaign::run(&sweep, &options, &Quiet, &Cancel::new())?;
//! println!("{} of {} tests ended, {} failed", outcome.ended, outcome.total, outcome.failed.len());
//! # Ok::<(), cdlab::Error>(())
//! ```
//!
//! The command line's `cdlab sweep FILE` is this call with a display. A campaign lists its
//! tests in a grid file ([`grid`]); [`collect()`] reads a campaign back as the points of
//! `crate::analysis::report`, whose text form ([`report_text`]) names the tests never run.

pub mod archive;
pub mod collect;
pub mod grid;
mod pool;
pub mod report_text;
mod sweep;

pub use collect::collect;
pub use grid::{GRID_FILE, NOT_RUN, add_to_grid, natural_order, read_grid, tests};

pub use pool::{CampaignOutcome, Event, Options, Quiet, TestOutcome, Watch, run};
pub use sweep::{Point, State, Sweep, check_point, point_config};
