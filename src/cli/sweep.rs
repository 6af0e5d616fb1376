//! `cdlab sweep FILE.toml`: the friction x pressure campaign of [`crate::campaign`], with a
//! display: on a terminal a bar of finished tests and one line per running test, in a log
//! each test's start and end and a line per running test every `--log-every` seconds.
//! `--shard I/N` runs the I-th of N disjoint parts (0 <= I < N).

use std::path::PathBuf;

use crate::campaign::tests;
use crate::campaign::{CampaignOutcome, Options, Sweep};
use crate::error::{Error, Result};

use super::campaign_display::CampaignDisplay;

/// Options of `cdlab sweep`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The sweep file (TOML), or `collect` followed by directories to merge into a report.
    pub file: PathBuf,
    /// With `collect`: the campaign directories to merge.
    pub dirs: Vec<PathBuf>,
    /// Run only the I-th of N disjoint parts, written `I/N` (0 <= I < N).
    #[arg(long)]
    pub shard: Option<String>,
    /// Tests run at once (default: the number of cores).
    #[arg(long)]
    pub jobs: Option<usize>,
    /// Seconds between two progress lines of each running test when stderr is not a
    /// terminal (a log); on a terminal the campaign's display updates continuously.
    #[arg(long, default_value_t = 120.0)]
    pub log_every: f64,
    /// Run nothing: say what the sweep would do with each test (skip, resume, start), in
    /// the order the tests would start, after checking the tests found in the output
    /// directory against the sweep's settings (a campaign copied from an archive, say).
    #[arg(long)]
    pub dry_run: bool,
}

fn parse_shard(s: &str) -> Result<(usize, usize)> {
    let bad = || Error::invalid("--shard", s, "I/N with 0 <= I < N");
    let (i, n) = s.split_once('/').ok_or_else(bad)?;
    let (i, n) = (
        i.parse::<usize>().map_err(|_| bad())?,
        n.parse::<usize>().map_err(|_| bad())?,
    );
    if n == 0 || i >= n {
        return Err(bad());
    }
    Ok((i, n))
}

/// Runs `cdlab sweep`.
pub fn run(args: &Args) -> Result<()> {
    if args.file.as_os_str() == "collect" {
        return super::report::run(&super::report::Args {
            dirs: args.dirs.clone(),
            out: None,
        });
    }
    let cancel = crate::interrupt::install();
    if !(args.log_every.is_finite() && args.log_every >= 0.0) {
        return Err(Error::invalid("--log-every", args.log_every, "seconds >= 0"));
    }
    let shard = args
        .shard
        .as_deref()
        .map(parse_shard)
        .transpose()?
        .unwrap_or((0, 1));
    let sweep = Sweep::load(&args.file)?;
    let options = Options {
        jobs: args.jobs.unwrap_or(Options::default().jobs).max(1),
        shard,
        dry_run: args.dry_run,
    };
    let display = CampaignDisplay::new(args.log_every);
    let outcome = crate::campaign::run(&sweep, &options, &display, &cancel)?;
    if let Some(b) = display.overall.get() {
        b.finish_and_clear();
    }
    conclude(&outcome, &sweep, args.dry_run)
}

/// The end of a campaign: its closing line, and the error of a stopped or failed one.
fn conclude(o: &CampaignOutcome, sweep: &Sweep, dry_run: bool) -> Result<()> {
    let (ended, total) = (o.ended, o.total);
    if let Some(signal) = o.cancelled {
        note!(
            "sweep: stopped by {}: {ended} of {total} tests ended or were found finished ({} \
             failed), {} stopped at a checkpoint or before starting, {} running in another \
             process, {} not started; the same command resumes the campaign",
            crate::interrupt::signal_name(signal),
            o.failed.len(),
            o.stopped.len(),
            o.elsewhere.len(),
            total - ended - o.stopped.len() - o.elsewhere.len()
        );
        return Err(Error::Interrupted { signal, step: 0 });
    }
    if o.failed.is_empty() && dry_run {
        note!("sweep: dry run, nothing was run; {} checked", tests(total));
    } else if o.failed.is_empty() && !o.elsewhere.is_empty() {
        note!(
            "sweep: {ended} of this shard's {} finished, {} running in another process \
             (not failed: that process ends them); `cdlab report {}` analyses the campaign \
             once it has",
            tests(total),
            o.elsewhere.len(),
            sweep.out.display()
        );
    } else if o.failed.is_empty() {
        let which = if total == 1 {
            "the 1 test".to_string()
        } else {
            format!("all {total} tests")
        };
        note!(
            "sweep: {which} of this shard finished; `cdlab report {}` analyses the campaign",
            sweep.out.display()
        );
    } else {
        return Err(Error::Campaign {
            path: sweep.out.clone(),
            tests: o.failed.clone(),
            message: format!(
                "{} of {total} tests failed (the others finished): {:?}",
                o.failed.len(),
                o.failed
            ),
        });
    }
    Ok(())
}
