//! The sections of a run configuration, with the paper's values as defaults.
//!
//! The defaults are written here in Rust and again, with comments, in `assets/default.toml`;
//! a test checks that the two agree. (They cannot be derived from the file at run time:
//! serde's `#[serde(default)]` builds the whole default value before reading a section, so a
//! `Default` that parsed the file would recurse.)

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::units::{Density, Duration, Length, Pressure, Velocity};

/// `[sample]`: the disks and the shape of the sample.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Sample {
    /// Number of disks (paper: 5000; default 1000 for a run of a few minutes).
    pub disks: usize,
    /// Smallest radius (m).
    pub r_min: Length,
    /// Largest radius (m).
    pub r_max: Length,
    /// Density of the disks (kg/m^3).
    pub density: Density,
    /// Seed of the random radii and deposition.
    pub seed: u64,
    /// Target height / width after compaction.
    pub aspect_ratio: f64,
}

impl Default for Sample {
    fn default() -> Self {
        Sample {
            disks: 1000,
            r_min: Length(0.5),
            r_max: Length(2.0),
            density: Density(2600.0),
            seed: 1,
            aspect_ratio: 2.5,
        }
    }
}

/// Iteration scheme of the contact solver (`"colored-gs"`, `"gs"`, `"jacobi"`).
pub use crate::solver::Method;

/// Where the time steps run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Backend {
    /// CPU reference path.
    Cpu,
    /// WGSL compute shaders.
    Gpu,
    /// The GPU on a hardware adapter for samples of at least
    /// [`crate::run::AUTO_GPU_FROM_DISKS`] disks, otherwise the CPU.
    Auto,
}

impl std::str::FromStr for Backend {
    type Err = crate::Error;
    fn from_str(s: &str) -> crate::Result<Self> {
        match s {
            "cpu" => Ok(Backend::Cpu),
            "gpu" => Ok(Backend::Gpu),
            "auto" => Ok(Backend::Auto),
            _ => Err(crate::Error::invalid(
                "solver.backend",
                s,
                "must be one of \"cpu\", \"gpu\", \"auto\"",
            )),
        }
    }
}

/// `[solver]`: time stepping and the contact solver.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Solver {
    /// Time step (s).
    pub dt: Duration,
    /// Moreau-Jean theta, in [0.5, 1].
    pub theta: f64,
    /// Tolerance on the relative quadratic change of the impulses per iteration.
    pub tol: f64,
    /// Iteration cap per step.
    pub max_iter: u32,
    /// Iteration scheme.
    pub method: Method,
    /// Relaxation of the Jacobi update, in (0, 1].
    pub jacobi_relax: f64,
    /// Alert distance as a fraction of `sample.r_min`.
    pub alert_distance: f64,
    /// Iterations between two convergence tests; 0: every iteration on the CPU, every
    /// [`crate::solver::GPU_CHECK_EVERY`] on the GPU.
    pub check_every: u32,
    /// Overlap, as a fraction of `sample.r_min`, above which the run stops with an error.
    pub overlap_limit: f64,
    /// Where the steps run.
    pub backend: Backend,
    /// CPU threads of the colored Gauss-Seidel sweeps; 0 takes every core.
    pub threads: usize,
    /// Relaxation of the Gauss-Seidel update, in (0, 1].
    pub gs_relax: f64,
    /// Iterations of a step swept unrelaxed before `gs_relax` applies.
    pub gs_relax_after: u32,
    /// Velocity test, as a fraction of `sample.r_min` per time step; 0 turns it off.
    pub velocity_tol: f64,
    /// Open contacts whose gap would stay above this fraction of `sample.r_min` at the end
    /// of the step are left out of the sweeps; 0 sweeps every candidate.
    pub open_skip_gap: f64,
    /// Overlap, as a fraction of `sample.r_min`, beyond which a loaded contact gets
    /// `deep_sweeps` more local updates after each solve; 0 turns them off. Unset, it is
    /// the method's own ([`Solver::deep_overlap_rel`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub deep_overlap: Option<f64>,
    /// Local updates of each contact beyond `deep_overlap` after a solve.
    pub deep_sweeps: u32,
    /// Anderson depth of `method = "anderson-gs"` (iterates mixed, minus one).
    pub anderson_depth: u32,
}

impl Default for Solver {
    fn default() -> Self {
        Solver {
            dt: Duration(5e-4),
            theta: 1.0,
            tol: 3e-4,
            max_iter: 1000,
            method: Method::ColoredGs,
            jacobi_relax: 0.5,
            alert_distance: 0.1,
            check_every: 0,
            overlap_limit: 0.05,
            backend: Backend::Auto,
            threads: 0,
            gs_relax: crate::solver::default_gs_relax(),
            gs_relax_after: crate::solver::default_gs_relax_after(),
            velocity_tol: crate::solver::default_velocity_tol_rel(),
            open_skip_gap: crate::solver::default_open_skip_gap(),
            deep_overlap: None,
            deep_sweeps: crate::solver::default_deep_sweeps(),
            anderson_depth: crate::solver::default_anderson_depth(),
        }
    }
}

impl Solver {
    /// The overlap beyond which loaded contacts get local updates (fraction of
    /// `sample.r_min`; 0 for none): `deep_overlap` when set, else
    /// [`crate::solver::default_deep_overlap_rel`] for Gauss-Seidel and Jacobi and 0 for
    /// the others, which do not implement the updates.
    pub fn deep_overlap_rel(&self) -> f64 {
        self.deep_overlap.unwrap_or(match self.method {
            Method::Gs | Method::ColoredGs | Method::Jacobi => crate::solver::default_deep_overlap_rel(),
            Method::Apgd | Method::AndersonGs => 0.0,
        })
    }
}

/// `[compaction]`: the uniaxial compaction that follows the deposition.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Compaction {
    /// Stress on the right wall (Pa). The paper is silent; default 8 MPa, the largest sigma3.
    pub sigma_c: Pressure,
    /// Friction during compaction (paper: 0).
    pub friction: f64,
}

impl Default for Compaction {
    fn default() -> Self {
        Compaction {
            sigma_c: Pressure(8e6),
            friction: 0.0,
        }
    }
}

/// `[test]`: confinement and biaxial compression.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Test {
    /// Disk-disk friction coefficient.
    pub mu: f64,
    /// Disk-wall friction; `None` means the same as `mu`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub wall_mu: Option<f64>,
    /// Confining pressure (Pa).
    pub sigma3: Pressure,
    /// Thickness of the deformable-wall strips (m).
    pub strip_thickness: Length,
    /// Steps between two recomputations of which disks form the strips (0: the disks
    /// chosen at the start of confinement stay the strips).
    pub strip_refresh_every: u64,
    /// Downward velocity of the top wall (m/s).
    pub axial_velocity: Velocity,
    /// Axial strain at which the test ends.
    pub strain_end: f64,
    /// Normal restitution.
    pub e_n: f64,
    /// Tangential restitution.
    pub e_t: f64,
}

impl Default for Test {
    fn default() -> Self {
        Test {
            mu: 0.3,
            wall_mu: None,
            sigma3: Pressure(8e6),
            strip_thickness: Length(7.5),
            strip_refresh_every: crate::protocol::default_strip_refresh_every() as u64,
            axial_velocity: Velocity(0.5),
            strain_end: 0.1,
            e_n: 0.0,
            e_t: 0.0,
        }
    }
}

impl Test {
    /// The disk-wall friction in force: `wall_mu`, or `mu` when it is not set.
    pub fn wall_friction(&self) -> f64 {
        self.wall_mu.unwrap_or(self.mu)
    }
}

/// `[equilibrium]`: when a preparation phase is over.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Equilibrium {
    /// Threshold on K / (sigma A): translational kinetic energy of the connected disks over
    /// the applied stress times the disk area.
    pub kinetic_ratio: f64,
    /// The same threshold for the frictionless compaction, whose packing creeps on at a
    /// ratio of a few 1e-8 (see the default file).
    pub compaction_kinetic_ratio: f64,
    /// Threshold on |F_contacts - F_target| / F_target of the loaded wall.
    pub force_imbalance: f64,
    /// The sample's creep (relative change of height and width per second of simulated
    /// time) below which a phase settles whatever its kinetic ratio (1/s; 0: off).
    pub creep_rate: f64,
    /// Steps per check window: both criteria are evaluated at the end of each window.
    pub hold_steps: u64,
    /// Simulated-time cap of a phase (s).
    pub max_time: Duration,
    /// Kinetic energy over sigma3 x height x width above which the compression stops with
    /// an error: the test is no longer quasi-static.
    pub runaway_kinetic_ratio: f64,
}

impl Default for Equilibrium {
    fn default() -> Self {
        Equilibrium {
            kinetic_ratio: 1e-8,
            compaction_kinetic_ratio: 1e-7,
            force_imbalance: 0.01,
            creep_rate: crate::protocol::default_creep_rate(),
            hold_steps: 200,
            max_time: Duration(60.0),
            runaway_kinetic_ratio: crate::protocol::default_runaway_kinetic_ratio(),
        }
    }
}

/// `[output]`: where and how often the run records.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Output {
    /// Directory of the run's files.
    pub dir: PathBuf,
    /// Steps between two measurement rows.
    pub series_every: u64,
    /// Axial strain between two snapshots during compression (0: end-of-phase only).
    pub snapshot_every: f64,
    /// Steps between two checkpoints (0: end-of-phase only).
    pub checkpoint_every: u64,
}

impl Default for Output {
    fn default() -> Self {
        Output {
            dir: PathBuf::from("out/biaxial"),
            series_every: 10,
            snapshot_every: 0.01,
            checkpoint_every: 5000,
        }
    }
}
