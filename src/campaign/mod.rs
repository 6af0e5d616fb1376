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
//! The command line's `cdlab sweep FILE` is this call with a display; the grid's list file
//! and the natural order of test names are those of `crate::analysis::report`, which reads
//! campaigns back.

pub mod archive;
mod pool;
mod sweep;

pub use pool::{CampaignOutcome, Event, Options, Quiet, TestOutcome, Watch, run};
pub use sweep::{Point, State, Sweep, check_point, point_config};
