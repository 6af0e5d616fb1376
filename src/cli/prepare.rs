//! `cdlab prepare`: deposit and compact a sample once, to reuse it across tests
//! (`cdlab biaxial --sample FILE`), as the paper reuses one sample per friction value.

use std::path::PathBuf;

use crate::error::{Error, Result};
use crate::protocol::biaxial::Lab;
use crate::protocol::{Collect, Phase, prepare};

use super::run::open_backend;

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
    if args.output.exists() && !args.force {
        return Err(Error::Other(format!(
            "{} exists: pass --force to replace it",
            args.output.display()
        )));
    }
    let config = super::biaxial::configuration(&super::biaxial::Args {
        config: args.config.clone(),
        disks: args.disks,
        seed: args.seed,
        backend: args.backend.clone(),
        ..Default::default()
    })?;
    prepare_to(&config, &args.output, false)?;
    Ok(())
}

/// Deposits and compacts the sample of `config`, writes it to `path` and returns the
/// compacted scene (`quiet`: no report on stderr/stdout).
pub fn prepare_to(
    config: &crate::config::Config,
    path: &std::path::Path,
    quiet: bool,
) -> Result<crate::model::Scene> {
    let params = config.protocol();
    let t0 = std::time::Instant::now();
    let (scene, rep) = prepare::deposit_scene(&params)?;
    if !quiet {
        eprintln!(
            "deposited {} disks in {:.2} s: packing fraction {:.3}, coordination {:.2}, D10 {:.2} m, D60 {:.2} m",
            params.disks, rep.seconds, rep.packing_fraction, rep.coordination, rep.d10_m, rep.d60_m
        );
    }
    let backend = open_backend(config, scene.clone(), params.step)?;
    let mut lab = Lab::new(backend, params, &scene, false)?;
    let mut obs = Collect::default();
    while lab.state.phase == Phase::Compaction {
        lab.advance(&mut obs)?;
        // A sweep stops on a signal; the sample is not written, so nothing resumes it.
        if let Some(signal) = crate::interrupt::requested() {
            return Err(Error::Interrupted { signal, step: 0 });
        }
    }
    let end = obs
        .ends
        .last()
        .cloned()
        .ok_or_else(|| Error::Other("compaction did not end".into()))?;
    let scene = crate::backend::Backend::scene(&mut lab.backend)?;
    crate::sample::file::write_sample(path, &lab.state, &scene)?;
    if !quiet {
        let d = &scene.disks;
        let last = obs.rows.last();
        let (w, h) = (last.map_or(0.0, |r| r.width_m), last.map_or(0.0, |r| r.height_m));
        let area: f64 = d.radius.iter().map(|r| std::f64::consts::PI * r * r).sum();
        println!(
            "prepared sample written to {}: {} disks, {:.2} m x {:.2} m (height/width {:.2}), packing fraction {:.3}, \
             compaction {} at t = {:.2} s, wall time {:.1} s",
            path.display(),
            d.len(),
            w,
            h,
            h / w,
            area / (w * h),
            if end.settled { "settled" } else { "NOT settled" },
            end.time_s,
            t0.elapsed().as_secs_f64()
        );
    }
    Ok(scene)
}
