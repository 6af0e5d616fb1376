//! Samples prepared once and reused across tests: preparing one, reading it back, and
//! making a configuration describe it.

use std::path::{Path, PathBuf};
use std::time::Instant;

use super::{Cancel, Event, Progress, open_backend_told};
use crate::config::{Config, Density, Length, Pressure};
use crate::error::{Error, Result, RunFault};
use crate::model::Scene;
use crate::protocol::biaxial::Lab;
use crate::protocol::{Collect, Phase, PhaseEnd, ProtocolParams, prepare as protocol_prepare};

pub use crate::protocol::sample_file::PreparedSample;

/// A sample prepared by [`prepare`] and written.
#[derive(Clone, Debug)]
pub struct Prepared {
    /// The file written.
    pub path: PathBuf,
    /// The compacted scene.
    pub scene: Scene,
    /// The end of the compaction (settled, or at its time cap).
    pub compaction: PhaseEnd,
    /// Sample width and height at the end of the compaction (m).
    pub width_m: f64,
    /// See `width_m`.
    pub height_m: f64,
    /// Mean number of force-carrying contacts per disk at the end of the compaction,
    /// rattlers left out (the series' `coordination`).
    pub coordination: f64,
    /// Wall-clock seconds of the preparation.
    pub wall_s: f64,
}

impl Prepared {
    /// Packing fraction of the compacted sample: disk area over the box's (0 when the
    /// box has no area).
    pub fn packing_fraction(&self) -> f64 {
        let area: f64 = self
            .scene
            .disks
            .radius
            .iter()
            .map(|r| std::f64::consts::PI * r * r)
            .sum();
        area / (self.width_m * self.height_m)
    }
}

/// Deposits and compacts the sample of `config` and writes it to `path` (replacing a
/// regular file there; anything else there is refused before any work:
/// [`crate::fsio::check_replaceable`]). `cancel` stops it between windows of steps, with
/// nothing written (a sample has no checkpoint to resume from): [`Error::Interrupted`] at
/// step 0.
pub fn prepare(
    config: &Config,
    path: &Path,
    progress: &mut dyn Progress,
    cancel: &Cancel,
) -> Result<Prepared> {
    // Refused now rather than after minutes of compaction (the write checks again).
    crate::fsio::check_replaceable(path)?;
    let params = config.protocol();
    let t0 = Instant::now();
    let (scene, rep) = protocol_prepare::deposit_scene(&params)?;
    progress.event(&Event::Deposited {
        disks: params.disks,
        report: &rep,
    });
    let backend = open_backend_told(config, scene.clone(), params.step, progress)?;
    let mut lab = Lab::new(backend, params, &scene, false)?;
    let mut obs = Preparing {
        seen: Collect::default(),
        progress,
        t0,
    };
    while lab.state.phase == Phase::Compaction {
        lab.advance(&mut obs)?;
        if let Some(signal) = cancel.requested() {
            return Err(Error::Interrupted { signal, step: 0 });
        }
    }
    obs.progress.event(&Event::StepsEnded);
    let obs = obs.seen;
    let compaction = obs.ends.last().cloned().ok_or_else(|| Error::Numerical {
        step: obs.rows.last().map_or(0, |r| r.step),
        message: "the compaction ended without reporting its end".into(),
    })?;
    let scene = crate::backend::Backend::scene(&mut lab.backend)?;
    crate::protocol::sample_file::write_sample(path, &lab.state, &scene)?;
    let last = obs.rows.last();
    Ok(Prepared {
        path: path.to_path_buf(),
        scene,
        compaction,
        width_m: last.map_or(0.0, |r| r.width_m),
        height_m: last.map_or(0.0, |r| r.height_m),
        coordination: last.map_or(0.0, |r| r.coordination),
        wall_s: t0.elapsed().as_secs_f64(),
    })
}

/// The observer of a preparation: keeps what [`prepare`] reports and shows the rows and
/// the equilibrium checks as they come (the compaction of a large sample takes minutes).
struct Preparing<'a> {
    seen: Collect,
    progress: &'a mut dyn Progress,
    t0: Instant,
}

impl crate::protocol::Observer for Preparing<'_> {
    fn series(&mut self, row: &crate::measure::SeriesRow) -> Result<()> {
        let row = crate::measure::SeriesRow {
            wall_s: self.t0.elapsed().as_secs_f64(),
            ..row.clone()
        };
        self.progress.event(&Event::Row {
            row: &row,
            strain_end: 0.0,
        });
        self.seen.series(&row)
    }
    fn phase_end(&mut self, end: &PhaseEnd) -> Result<()> {
        self.progress.event(&Event::PhaseEnd(end));
        self.seen.phase_end(end)
    }
    fn snapshot(
        &mut self,
        strain: f64,
        scene: &Scene,
        contacts: &[crate::backend::ContactRecord],
        reference: &[glam::DVec2],
    ) -> Result<()> {
        self.seen.snapshot(strain, scene, contacts, reference)
    }
    fn checkpoint(&mut self, step: u64, bytes: &[u8]) -> Result<()> {
        self.seen.checkpoint(step, bytes)
    }
    fn activity(&mut self, phase: Phase, text: &str) -> Result<()> {
        self.progress.event(&Event::Activity { phase, text });
        Ok(())
    }
    fn settling(&mut self, check: &crate::protocol::Settling) -> Result<()> {
        self.progress.event(&Event::Settling(check));
        Ok(())
    }
}

/// Reads a sample written by [`prepare`] (or `cdlab prepare`), checking that its scene
/// holds the disks its parameters announce.
pub fn read_sample(path: &Path) -> Result<PreparedSample> {
    crate::protocol::sample_file::read_sample(path)
}

/// The `[sample]` and `[compaction]` settings of `config` that differ from those a sample
/// was prepared with, as `key: configuration value, sample value` descriptions.
pub fn sample_differences(config: &Config, sample: &ProtocolParams) -> Vec<String> {
    let c = config.protocol();
    let counts = [
        ("sample.disks", c.disks as u64, sample.disks as u64),
        ("sample.seed", c.seed, sample.seed),
    ];
    let values = [
        ("sample.r_min", c.r_min, sample.r_min, " m"),
        ("sample.r_max", c.r_max, sample.r_max, " m"),
        ("sample.density", c.density, sample.density, " kg/m3"),
        ("sample.aspect_ratio", c.aspect, sample.aspect, ""),
        ("compaction.sigma_c", c.sigma_c, sample.sigma_c, " Pa"),
        ("compaction.friction", c.mu_compaction, sample.mu_compaction, ""),
    ];
    differences(&counts, &values, "the sample")
}

/// `key: ours here, theirs in WHERE` for each setting that differs: `counts` as
/// `(key, ours, theirs)`, then `values` as `(key, ours, theirs, unit)`.
pub fn differences(
    counts: &[(&str, u64, u64)],
    values: &[(&str, f64, f64, &str)],
    theirs_in: &str,
) -> Vec<String> {
    let counts = counts
        .iter()
        .filter(|(_, ours, theirs)| ours != theirs)
        .map(|(key, ours, theirs)| format!("{key}: {ours} here, {theirs} in {theirs_in}"));
    let values = values
        .iter()
        .filter(|(_, ours, theirs, _)| ours != theirs)
        .map(|(key, ours, theirs, unit)| format!("{key}: {ours}{unit} here, {theirs}{unit} in {theirs_in}"));
    counts.chain(values).collect()
}

/// Makes `config` describe the prepared sample a test starts from: its `[sample]` and
/// `[compaction]` settings become the sample's, so that the record, the summary and the
/// quantities scaled by `r_min` (overlaps, the velocity test) are those of the disks
/// actually simulated. `asked` lists what the caller asked for explicitly, as
/// `(name, disks, seed)` (a name such as `--disks`, the value or None): a value that
/// asks for another sample is an error ([`RunFault::OtherSettings`]) rather than silently
/// ignored. `path` names the sample in messages.
pub fn adopt_sample(
    config: &mut Config,
    sample: &ProtocolParams,
    asked: [(&str, Option<u64>); 2],
    path: &Path,
) -> Result<()> {
    let have = [sample.disks as u64, sample.seed];
    for ((flag, want), have) in asked.into_iter().zip(have) {
        if let Some(want) = want.filter(|w| *w != have) {
            return Err(Error::Run {
                path: path.to_path_buf(),
                fault: RunFault::OtherSettings,
                message: format!(
                    "{flag} {want} contradicts the sample {} ({have}); leave {flag} out to use \
                     the sample as prepared",
                    path.display()
                ),
                remedy: None,
            });
        }
    }
    let s = &mut config.sample;
    s.disks = sample.disks;
    s.seed = sample.seed;
    s.r_min = Length(sample.r_min);
    s.r_max = Length(sample.r_max);
    s.density = Density(sample.density);
    s.aspect_ratio = sample.aspect;
    config.compaction.sigma_c = Pressure(sample.sigma_c);
    config.compaction.friction = sample.mu_compaction;
    config.validate()
}
