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
    /// The paper's parameters (docs/protocol.md) for a sample of `disks` disks, with the
    /// project's choices where the paper is silent (docs/protocol.md):
    /// compaction at 8 MPa (the campaign's largest sigma3), wall friction equal to the disk
    /// friction, alert distance 0.1 r_min, overlap hard stop at 0.05 r_min, local updates of
    /// loaded contacts deeper than 0.005 r_min, as the configuration's defaults.
    pub fn paper_defaults(disks: usize) -> Self {
        use crate::solver::{Method, SolverParams};
        let (r_min, dt) = (0.5, 5e-4);
        ProtocolParams {
            disks,
            r_min,
            r_max: 2.0,
            density: 2600.0,
            seed: 1,
            aspect: 2.5,
            sigma_c: 8e6,
            mu_compaction: 0.0,
            step: StepParams {
                dt,
                theta: 1.0,
                alert: 0.05,
                overlap_limit: 0.05,
                solver: SolverParams {
                    method: Method::ColoredGs,
                    tol: 3e-4,
                    max_iter: 1000,
                    relax: 0.5,
                    parallel: true,
                    parallel_min: crate::solver::default_parallel_min(),
                    threads: 0,
                    gs_relax: crate::solver::default_gs_relax(),
                    gs_relax_after: crate::solver::default_gs_relax_after(),
                    velocity_tol: crate::solver::default_velocity_tol_rel() * r_min / dt,
                    open_skip: crate::solver::default_open_skip_gap() * r_min / dt,
                    deep_gap: crate::solver::default_deep_overlap_rel() * r_min,
                    deep_sweeps: crate::solver::default_deep_sweeps(),
                    anderson_depth: crate::solver::default_anderson_depth(),
                    check_every: 0,
                },
            },
            mu: 0.3,
            mu_wall: 0.3,
            e_n: 0.0,
            e_t: 0.0,
            sigma3: 8e6,
            strip_thickness: 7.5,
            strip_refresh_every: default_strip_refresh_every(),
            axial_velocity: 0.5,
            strain_end: 0.1,
            equilibrium: Equilibrium {
                kinetic_ratio: 1e-8,
                compaction_kinetic_ratio: default_compaction_kinetic_ratio(),
                runaway_kinetic_ratio: default_runaway_kinetic_ratio(),
                force_imbalance: 0.01,
                window: 200,
                max_time: 60.0,
            },
            series_every: 10,
            snapshot_every: 0.01,
            checkpoint_every: 5000,
        }
    }

    /// Rejects values the protocol cannot run with, naming the field.
    pub fn validate(&self) -> Result<()> {
        if self.disks < 50 {
            return Err(Error::invalid(
                "sample.disks",
                self.disks,
                "must be >= 50 (the strips and glued walls need disks)",
            ));
        }
        check_positive("sample.r_min", self.r_min)?;
        if self.r_max.is_nan() || self.r_max < self.r_min || !self.r_max.is_finite() {
            return Err(Error::invalid(
                "sample.r_max",
                self.r_max,
                &format!("must be finite and >= sample.r_min = {}", self.r_min),
            ));
        }
        check_positive("sample.density", self.density)?;
        check_positive("sample.aspect", self.aspect)?;
        check_positive("compaction.sigma_c", self.sigma_c)?;
        self.step.validate()?;
        crate::error::check_non_negative("test.mu", self.mu)?;
        crate::error::check_non_negative("test.mu_wall", self.mu_wall)?;
        check_range("test.e_n", self.e_n, 0.0, 1.0)?;
        check_range("test.e_t", self.e_t, -1.0, 1.0)?;
        check_positive("test.sigma3", self.sigma3)?;
        check_positive("test.strip_thickness", self.strip_thickness)?;
        check_positive("test.axial_velocity", self.axial_velocity)?;
        if !(self.strain_end > 0.0 && self.strain_end < 1.0) {
            return Err(Error::invalid(
                "test.strain_end",
                self.strain_end,
                "must lie in (0, 1)",
            ));
        }
        check_positive("equilibrium.kinetic_ratio", self.equilibrium.kinetic_ratio)?;
        check_positive(
            "equilibrium.runaway_kinetic_ratio",
            self.equilibrium.runaway_kinetic_ratio,
        )?;
        check_positive(
            "equilibrium.compaction_kinetic_ratio",
            self.equilibrium.compaction_kinetic_ratio,
        )?;
        crate::error::check_non_negative("compaction.friction", self.mu_compaction)?;
        check_positive("equilibrium.force_imbalance", self.equilibrium.force_imbalance)?;
        check_positive("equilibrium.max_time", self.equilibrium.max_time)?;
        if self.equilibrium.window == 0 || self.series_every == 0 || self.checkpoint_every == 0 {
            return Err(Error::invalid(
                "equilibrium.window / output.series_every / output.checkpoint_every",
                0,
                "must be >= 1",
            ));
        }
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
