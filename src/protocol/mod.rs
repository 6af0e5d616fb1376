//! The biaxial test of Taboada et al. (2005) as a sequence of phases driven through the
//! [`Backend`](crate::backend::Backend) interface: deposition and compaction (sample preparation), confinement
//! through deformable walls, and compression at constant axial velocity.
//!
//! The protocol holds only host-side state ([`LabState`]): the phase, the strips, the gauge
//! and counters. A checkpoint is that state plus the backend's scene and warm-start
//! impulses, so every phase can resume from a saved state.

pub mod biaxial;
pub mod checkpoint;
mod gauge;
pub mod limits;
pub mod prepare;
pub mod sample_file;

pub use gauge::Gauge;

use crate::backend::ContactRecord;
use crate::engine::StepParams;
use crate::error::{Error, Result, check_positive, check_range};
use crate::measure::SeriesRow;
// The phases name parts of a test's measurements (rows, the summary's phase ends), so they
// are defined with them; the protocol drives them.
pub use crate::measure::phase::{Phase, PhaseEnd};
use crate::model::Scene;

/// When a phase counts as settled (docs/protocol.md, "Equilibrium"; recorded with each
/// phase end).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Equilibrium {
    /// Threshold on the kinetic ratio `K / (sigma A)`: the translational kinetic energy of
    /// the free disks with two or more force-carrying contacts over the phase's applied
    /// stress times the total disk area (dimensionless). Rattlers and spin are left out: a
    /// rattler spins on, or slides along its frictionless cage, forever without doing work
    /// on the sample (the 5000-disk compaction never settled while they counted).
    pub kinetic_ratio: f64,
    /// The kinetic threshold of the frictionless compaction (dimensionless). Frictionless
    /// disks keep sliding under the load, so the ratio fluctuates without decaying and
    /// `kinetic_ratio` would be met only by chance (docs/protocol.md, "Equilibrium"); the
    /// confinement that follows settles the sample at `kinetic_ratio` with friction on.
    #[serde(default = "default_compaction_kinetic_ratio")]
    pub compaction_kinetic_ratio: f64,
    /// Relative imbalance between the force the contacts exert on a force-driven wall and
    /// the force applied to it, `|F_contacts - F_applied| / F_applied`, averaged over a check
    /// window (dimensionless).
    pub force_imbalance: f64,
    /// The sample's creep below which a phase counts as settled whatever its kinetic ratio
    /// (1/s; 0: the kinetic ratio alone): the relative change of its height and of its
    /// width per second of simulated time, between the means over the last
    /// [`CREEP_WINDOWS`] check windows and the [`CREEP_WINDOWS`] before ([`creep_rate`]).
    /// At the solver's tolerance the kinetic ratio of a packing at rest fluctuates about a
    /// floor near its threshold, which it crosses only by chance (docs/protocol.md,
    /// "Equilibrium"). Checkpoints written before it existed read 0.
    #[serde(default)]
    pub creep_rate: f64,
    /// Steps per check window: both criteria are evaluated at the end of each window, the
    /// force averaged over it.
    pub window: u32,
    /// Simulated time after which a phase ends even if not settled (s); recorded.
    pub max_time: f64,
    /// During the compression, the run stops with an error when a row's kinetic energy
    /// over sigma3 x height x width ([`crate::measure::SeriesRow::kinetic_ratio`]) exceeds
    /// this: the test is no longer quasi-static.
    #[serde(default = "default_runaway_kinetic_ratio")]
    pub runaway_kinetic_ratio: f64,
}

/// Default of [`ProtocolParams::strip_refresh_every`]: 100 steps, 0.05 s of simulated time,
/// in which the top wall moves 2.5 cm during compression. The overturn that fixed strips
/// allowed grew by a factor e in about 1500 steps at contact friction 0.01, so a strip
/// that follows the sides every 100 steps never lags far behind them.
pub fn default_strip_refresh_every() -> u32 {
    100
}

/// Default of [`Equilibrium::runaway_kinetic_ratio`]: healthy compressions stay below 1e-3
/// (8e-5 for the 5000-disk DWL test, 4.6e-4 to 1e-3 at friction 0.01 on 1000 disks); the
/// samples that lost their confinement at friction 0.01 while the strips were fixed sets of
/// disks passed 1e-2 on their way to kinetic energies a thousand times larger.
pub fn default_runaway_kinetic_ratio() -> f64 {
    1e-2
}

/// Check windows averaged on each side of the creep comparison ([`creep_rate`]).
pub const CREEP_WINDOWS: usize = 5;

/// The sample's creep from its shape at the last checks of a phase, `(time (s), height (m),
/// width (m))` each: the larger of the relative rates of change of height and width (1/s)
/// between the means over the last [`CREEP_WINDOWS`] checks and the [`CREEP_WINDOWS`]
/// before, the times averaged alike. `None` before `2 * CREEP_WINDOWS` checks. Means, not
/// single checks: a force-driven wall jitters by about 1e-5 of the height from one window
/// to the next at rest.
pub fn creep_rate(shape: &[[f64; 3]]) -> Option<f64> {
    if shape.len() < 2 * CREEP_WINDOWS {
        return None;
    }
    let last = &shape[shape.len() - 2 * CREEP_WINDOWS..];
    let mean = |part: &[[f64; 3]], k: usize| part.iter().map(|s| s[k]).sum::<f64>() / part.len() as f64;
    let (before, recent) = last.split_at(CREEP_WINDOWS);
    let dt = mean(recent, 0) - mean(before, 0);
    let rate = |k: usize| {
        let now = mean(recent, k);
        ((now - mean(before, k)) / now / dt).abs()
    };
    let (rh, rw) = (rate(1), rate(2));
    // NaN (a degenerate shape) is no creep measured, never a settled phase; f64::max
    // would drop it.
    (rh.is_finite() && rw.is_finite()).then_some(rh.max(rw))
}

/// Default of [`Equilibrium::creep_rate`] in a new configuration: 1e-5 per second, which
/// over a whole compression of the 5000-disk test (about 43 s) adds up to 4e-4 of height or
/// width, under a tenth of the test's volumetric strain at its peak.
pub fn default_creep_rate() -> f64 {
    1e-5
}

/// Default of [`Equilibrium::compaction_kinetic_ratio`] (also for checkpoints written
/// before it existed).
pub fn default_compaction_kinetic_ratio() -> f64 {
    1e-7
}

/// Everything the protocol needs, in SI units.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ProtocolParams {
    /// Number of disks.
    pub disks: usize,
    /// Smallest and largest radius (m).
    pub r_min: f64,
    /// See `r_min`.
    pub r_max: f64,
    /// Grain density (kg/m^3).
    pub density: f64,
    /// Seed of the grain sizes (deposition is deterministic given the sizes).
    pub seed: u64,
    /// Height / width of the compacted sample.
    pub aspect: f64,
    /// Stress on the right wall during compaction (Pa).
    pub sigma_c: f64,
    /// Friction during compaction (paper: 0).
    pub mu_compaction: f64,
    /// Time stepping and solver.
    pub step: StepParams,
    /// Disk-disk friction during the test.
    pub mu: f64,
    /// Friction between disks and the plane walls during the test.
    pub mu_wall: f64,
    /// Normal and tangential restitution.
    pub e_n: f64,
    /// See `e_n`.
    pub e_t: f64,
    /// Confining stress (Pa).
    pub sigma3: f64,
    /// Thickness of the deformable-wall strips (m).
    pub strip_thickness: f64,
    /// Steps between two recomputations of which disks form the strips (see
    /// [`crate::backend::reduce::strip_members`]); 0 keeps the disks chosen at the start of
    /// confinement, as checkpoints written before this field existed did.
    #[serde(default)]
    pub strip_refresh_every: u32,
    /// Downward velocity of the top wall during compression (m/s).
    pub axial_velocity: f64,
    /// Axial strain at which compression ends.
    pub strain_end: f64,
    /// Equilibrium criteria for compaction and confinement.
    pub equilibrium: Equilibrium,
    /// Steps between two rows of the time series during compression. An output setting
    /// only: where the compression stops, when the strips are refreshed and when the run is
    /// checked never depend on it ([`biaxial::Lab::advance`]).
    pub series_every: u32,
    /// Axial strain between two snapshots of the compression (0: none but the snapshots
    /// at the end of each phase, which every run records: compaction and confinement at
    /// strain 0, the compression at its final strain).
    pub snapshot_every: f64,
    /// Steps between two checkpoints (taken at the end of the first window of steps that
    /// reaches it; a checkpoint changes nothing in the run).
    pub checkpoint_every: u32,
}

impl ProtocolParams {
    /// Rejects values the protocol cannot run with, naming each by its configuration key:
    /// the one check of every parameter a configuration gives in these units (the
    /// configuration checks only what it holds in other forms, [`crate::config::Config::validate`]).
    pub fn validate(&self) -> Result<()> {
        use limits::{COMPACTED_WIDTH, check_at_least, check_disk_count, check_open, check_pressure};
        // Each side strip is a few disks thick; below ~50 disks there is no bulk between them.
        check_at_least(
            "sample.disks",
            self.disks as u64,
            50,
            "the deformable-wall strips need disks on both sides of a bulk",
        )?;
        check_disk_count("sample.disks", self.disks)?;
        check_positive("sample.r_min", self.r_min)?;
        if !(self.r_max.is_finite() && self.r_max >= self.r_min) {
            return Err(Error::invalid(
                "sample.r_max",
                format!("{} m", self.r_max),
                &format!("must be finite and >= sample.r_min = {} m", self.r_min),
            ));
        }
        check_positive("sample.density", self.density)?;
        // Masses, inverse masses and kinetic energies stay finite and normal far beyond
        // any material (aerogels to osmium, 1 to 22,600 kg/m3) and the density scaling of
        // quasi-static studies; 1e308 overflowed the masses and 1e-320 their inverses.
        if !(1e-6..=1e12).contains(&self.density) {
            return Err(Error::invalid(
                "sample.density",
                format!("{} kg/m3", self.density),
                "must lie in [1e-6, 1e12] kg/m3 (the masses and their inverses must stay finite)",
            ));
        }
        check_positive("sample.aspect_ratio", self.aspect)?;
        // The deposit box's width comes from it: 1e-320 made the width infinite.
        if !(0.01..=100.0).contains(&self.aspect) {
            return Err(Error::invalid(
                "sample.aspect_ratio",
                self.aspect,
                "must lie in [0.01, 100] (sample height over width)",
            ));
        }
        self.step.validate()?;
        check_positive("compaction.sigma_c", self.sigma_c)?;
        check_pressure("compaction.sigma_c", self.sigma_c)?;
        crate::error::check_non_negative("compaction.friction", self.mu_compaction)?;
        crate::error::check_non_negative("test.mu", self.mu)?;
        crate::error::check_non_negative("test.wall_mu", self.mu_wall)?;
        check_positive("test.sigma3", self.sigma3)?;
        check_pressure("test.sigma3", self.sigma3)?;
        check_positive("test.strip_thickness", self.strip_thickness)?;
        // The strips need a core between them, which the confinement checks on the compacted
        // sample; a sample too narrow for them by far is refused here, before minutes of
        // deposition and compaction, from the width its disk count gives.
        let width =
            crate::sample::box_width_for(self.disks, self.r_min, self.r_max, self.aspect) * COMPACTED_WIDTH;
        let need = 2.0 * self.strip_thickness + 2.0 * self.r_max;
        if width <= need {
            let area = crate::sample::mean_area(self.r_min, self.r_max);
            let min = (need / COMPACTED_WIDTH).powi(2) * crate::sample::DEPOSIT_PACKING * self.aspect / area;
            return Err(Error::invalid(
                "sample.disks",
                self.disks,
                &format!(
                    "a sample of {} disks will be about {width:.1} m wide once compacted, too \
                     narrow for two strips of test.strip_thickness = {} m and a core (at least \
                     {need:.1} m): use more than {} disks or thinner strips",
                    self.disks,
                    self.strip_thickness,
                    min.ceil() as u64
                ),
            ));
        }
        check_positive("test.axial_velocity", self.axial_velocity)?;
        // The top wall's travel per step, against the smallest disk: more than a tenth of
        // r_min per step is an impact, not a quasi-static test (1e308 m/s gave an infinite
        // travel); below 1e-9 r_min the test never ends (1e-320 m/s wrote 118 MB of rows
        // without moving).
        let travel = self.axial_velocity * self.step.dt / self.r_min;
        if !(1e-9..=0.1).contains(&travel) {
            return Err(Error::invalid(
                "test.axial_velocity",
                format!("{} m/s", self.axial_velocity),
                &format!(
                    "moves the top wall by {travel:.3e} r_min per step (solver.dt = {} s, \
                     sample.r_min = {} m): keep it between 1e-9 and 0.1",
                    self.step.dt, self.r_min
                ),
            ));
        }
        check_open("test.strain_end", self.strain_end, 0.0, 1.0)?;
        check_range("test.e_n", self.e_n, 0.0, 1.0)?;
        check_range("test.e_t", self.e_t, -1.0, 1.0)?;
        let e = &self.equilibrium;
        check_positive("equilibrium.kinetic_ratio", e.kinetic_ratio)?;
        check_positive("equilibrium.runaway_kinetic_ratio", e.runaway_kinetic_ratio)?;
        check_positive("equilibrium.compaction_kinetic_ratio", e.compaction_kinetic_ratio)?;
        check_positive("equilibrium.force_imbalance", e.force_imbalance)?;
        crate::error::check_non_negative("equilibrium.creep_rate", e.creep_rate)?;
        check_at_least("equilibrium.hold_steps", e.window.into(), 1, "a number of steps")?;
        check_positive("equilibrium.max_time", e.max_time)?;
        check_at_least(
            "output.series_every",
            self.series_every.into(),
            1,
            "a number of steps",
        )?;
        check_at_least(
            "output.checkpoint_every",
            self.checkpoint_every.into(),
            1,
            "a number of steps",
        )?;
        crate::error::check_non_negative("output.snapshot_every", self.snapshot_every)?;
        Ok(())
    }
}

/// What a run reports as it goes; the CLI shows progress and records, tests collect.
pub trait Observer {
    /// A row of the time series.
    fn series(&mut self, row: &SeriesRow) -> Result<()>;
    /// A phase ended.
    fn phase_end(&mut self, end: &PhaseEnd) -> Result<()>;
    /// A snapshot of the state and contacts: at the end of each phase, and every
    /// `snapshot_every` of axial strain during the compression.
    fn snapshot(
        &mut self,
        strain: f64,
        scene: &Scene,
        contacts: &[ContactRecord],
        reference: &[glam::DVec2],
    ) -> Result<()>;
    /// A checkpoint: `bytes` restore the run exactly ([`checkpoint::decode`]).
    fn checkpoint(&mut self, step: u64, bytes: &[u8]) -> Result<()>;
    /// The backend's account of where a phase's time went ([`Backend::activity`]), at the
    /// phase's end; ignored unless the observer shows it.
    ///
    /// [`Backend::activity`]: crate::backend::Backend::activity
    fn activity(&mut self, _phase: Phase, _text: &str) -> Result<()> {
        Ok(())
    }
    /// A preparation phase's equilibrium check, at the end of each window
    /// ([`Equilibrium::window`]); ignored unless the observer shows progress.
    fn settling(&mut self, _check: &Settling) -> Result<()> {
        Ok(())
    }
}

/// One equilibrium check of a preparation phase (compaction or confinement): where its two
/// criteria stand against their thresholds, and how long the phase may still last.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settling {
    /// The phase checked.
    pub phase: Phase,
    /// Simulated time (s).
    pub time_s: f64,
    /// Simulated time since the phase began (s).
    pub phase_time_s: f64,
    /// Kinetic ratio `K / (sigma A)` (dimensionless) and the threshold it must go below.
    pub kinetic_ratio: f64,
    /// See `kinetic_ratio`.
    pub kinetic_threshold: f64,
    /// Relative force imbalance of the loaded wall (dimensionless) and its bound.
    pub imbalance: f64,
    /// See `imbalance`.
    pub imbalance_limit: f64,
    /// The sample's creep ([`creep_rate`], 1/s), once enough checks have come, and the
    /// bound below which it settles the phase (0: the kinetic ratio alone).
    pub creep: Option<f64>,
    /// See `creep`.
    pub creep_limit: f64,
    /// Simulated-time cap of the phase ([`Equilibrium::max_time`], s).
    pub max_time_s: f64,
}

/// An observer that keeps everything in memory (tests, reports).
#[derive(Clone, Debug, Default)]
pub struct Collect {
    /// Rows received.
    pub rows: Vec<SeriesRow>,
    /// Phase ends received.
    pub ends: Vec<PhaseEnd>,
    /// Strain of each snapshot received.
    pub snapshots: Vec<f64>,
    /// Last checkpoint received.
    pub last_checkpoint: Option<(u64, Vec<u8>)>,
}

impl Observer for Collect {
    fn series(&mut self, row: &SeriesRow) -> Result<()> {
        self.rows.push(row.clone());
        Ok(())
    }
    fn phase_end(&mut self, end: &PhaseEnd) -> Result<()> {
        self.ends.push(end.clone());
        Ok(())
    }
    fn snapshot(&mut self, strain: f64, _: &Scene, _: &[ContactRecord], _: &[glam::DVec2]) -> Result<()> {
        self.snapshots.push(strain);
        Ok(())
    }
    fn checkpoint(&mut self, step: u64, bytes: &[u8]) -> Result<()> {
        self.last_checkpoint = Some((step, bytes.to_vec()));
        Ok(())
    }
}

/// The protocol's own state: small, serializable, everything a resume needs besides the
/// backend's scene and warm start.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct LabState {
    /// The parameters of the run.
    pub params: ProtocolParams,
    /// Current phase.
    pub phase: Phase,
    /// Loads the backend applies every step.
    pub loading: crate::backend::Loading,
    /// Geometry for stresses and strains.
    pub gauge: Gauge,
    /// Simulated time at which the current phase started (s).
    pub phase_start: f64,
    /// Axial strain of the next snapshot.
    pub next_snapshot: f64,
    /// Steps since the last checkpoint.
    pub since_checkpoint: u32,
    /// Phases finished so far.
    pub ends: Vec<PhaseEnd>,
    /// Steps since the strips were last recomputed.
    #[serde(default)]
    pub since_strips: u32,
    /// Compression steps since the last row of the series.
    #[serde(default)]
    pub since_series: u32,
    /// Compression steps since the last quasi-static check
    /// ([`biaxial::QUASI_STATIC_CHECK_EVERY`]).
    #[serde(default)]
    pub since_guard: u32,
    /// The sums of the compression windows since the last row, when a row spans several
    /// windows (a strip refresh or a check fell inside it): the row averages over all of
    /// them. Kept in checkpoints so a resumed run writes the same rows.
    #[serde(default)]
    pub row_sums: Option<biaxial::RowSums>,
    /// Axial strain at the end of the last compression window (`None` before it, and in
    /// checkpoints written before it was kept: then it is measured from the scene).
    #[serde(default)]
    pub strain: Option<f64>,
    /// The sums of the compression windows since the last quasi-static check, when a block
    /// of [`biaxial::QUASI_STATIC_CHECK_EVERY`] steps spans several windows (a row or a
    /// strip refresh fell inside it).
    #[serde(default)]
    pub block_sums: Option<biaxial::RowSums>,
    /// The compression's derived results, fed at every quasi-static check and at the end
    /// ([`crate::measure::derived::DerivedCurve`]): the summary's peak, residual, stress
    /// drops and largest kinetic ratio, whatever `series_every` is. `None` before the
    /// compression, and for a compression resumed from a checkpoint written before it was
    /// kept (the summary then derives them from the rows).
    #[serde(default)]
    pub derived: Option<crate::measure::derived::DerivedCurve>,
    /// The sample's `(time (s), height (m), width (m))` at the current preparation phase's
    /// checks, the last `2 * CREEP_WINDOWS` of them ([`creep_rate`]).
    #[serde(default)]
    pub shape: Vec<[f64; 3]>,
}

impl LabState {
    /// The state of a lab about to start its compaction at time `phase_start`: no phase
    /// ended yet, every counter at zero, the loading and the gauge as given.
    pub fn new(
        params: ProtocolParams,
        loading: crate::backend::Loading,
        gauge: Gauge,
        phase_start: f64,
    ) -> Self {
        LabState {
            params,
            phase: Phase::Compaction,
            loading,
            gauge,
            phase_start,
            next_snapshot: 0.0,
            since_checkpoint: 0,
            ends: Vec::new(),
            since_strips: 0,
            since_series: 0,
            since_guard: 0,
            row_sums: None,
            strain: None,
            block_sums: None,
            derived: None,
            shape: Vec::new(),
        }
    }
}

/// Wall indices of the biaxial scene.
pub mod walls {
    /// Bottom wall (inward normal +y).
    pub const BOTTOM: usize = 0;
    /// Top wall (inward normal -y).
    pub const TOP: usize = 1;
    /// Left wall (inward normal +x), removed at confinement.
    pub const LEFT: usize = 2;
    /// Right wall (inward normal -x), pushes during compaction, removed at confinement.
    pub const RIGHT: usize = 3;
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A width shrinking by 1e-4 of itself per second reads as a creep of 1e-4/s, whatever
    /// the jitter of single checks (here 1e-5 of the height, alternating, which the means
    /// over five checks cancel); a sample at rest reads 0; fewer than ten checks read none.
    #[test]
    fn creep_is_the_relative_rate_of_the_mean_shape() {
        let shape: Vec<[f64; 3]> = (0..10)
            .map(|k| {
                let t = 0.1 * k as f64;
                let jitter = if k % 2 == 0 { 1e-5 } else { -1e-5 };
                [t, 200.0 * (1.0 + jitter), 80.0 * (1.0 - 1e-4 * t)]
            })
            .collect();
        let c = creep_rate(&shape).unwrap();
        assert!((c - 1e-4).abs() < 2e-7, "{c}");
        let rest: Vec<[f64; 3]> = (0..12).map(|k| [0.1 * k as f64, 200.0, 80.0]).collect();
        assert_eq!(creep_rate(&rest), Some(0.0));
        assert_eq!(creep_rate(&shape[..9]), None);
        let broken: Vec<[f64; 3]> = (0..10).map(|k| [0.1 * k as f64, f64::NAN, 80.0]).collect();
        assert_eq!(creep_rate(&broken), None);
    }
}
