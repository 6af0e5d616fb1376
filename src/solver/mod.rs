//! The contact problem of one time step: local law, coloring and the iterative sweeps
//! (Gauss-Seidel in plain or colored order, relaxed Jacobi) with the convergence test of
//! docs/method.md, "Convergence".

pub mod anderson;
pub mod apgd;
pub mod captured;
pub mod color;
mod convergence;
mod ctx;
mod gauss_seidel;
mod jacobi;
mod lanes;
pub mod law;
mod quads;
pub(crate) mod resident;
mod rows;
#[cfg(target_arch = "x86_64")]
mod simd;
mod single;
pub mod space;
pub mod sweep;
mod team;
mod update;

use crate::error::{Error, Result};

/// Order in which contacts are updated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Nonlinear Gauss-Seidel in detection order (contacts sorted by body indices).
    Gs,
    /// Gauss-Seidel in color order; each color is swept in parallel.
    ColoredGs,
    /// Jacobi: every contact solved from the same velocities, impulses relaxed by `relax`.
    Jacobi,
    /// Accelerated projected Jacobi on the Coulomb fixed point (`apgd.rs`,
    /// docs/method.md, "Accelerated projected Jacobi (apgd)"); CPU only.
    Apgd,
    /// Plain Gauss-Seidel sweeps in contact order with Anderson mixing of the last
    /// `anderson_depth + 1` iterates (CPU only; [`anderson`]).
    AndersonGs,
}

impl std::str::FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "gs" => Ok(Method::Gs),
            "colored-gs" => Ok(Method::ColoredGs),
            "jacobi" => Ok(Method::Jacobi),
            "apgd" => Ok(Method::Apgd),
            "anderson-gs" => Ok(Method::AndersonGs),
            _ => Err(Error::invalid(
                "solver.method",
                s,
                "one of gs, colored-gs, jacobi, anderson-gs, apgd",
            )),
        }
    }
}

impl Method {
    /// The method's name in the configuration (`solver.method`).
    pub fn name(self) -> &'static str {
        match self {
            Method::Gs => "gs",
            Method::ColoredGs => "colored-gs",
            Method::Jacobi => "jacobi",
            Method::AndersonGs => "anderson-gs",
            Method::Apgd => "apgd",
        }
    }

    /// Whether the GPU path implements the method; the others run on the CPU only, and
    /// `backend = "auto"` then takes the CPU.
    pub fn on_gpu(self) -> bool {
        matches!(self, Method::Gs | Method::ColoredGs | Method::Jacobi)
    }
}

/// Parameters of the iterative contact solver.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SolverParams {
    /// Sweep order.
    pub method: Method,
    /// Tolerance on the relative quadratic change of the impulses over one iteration,
    /// `sqrt(sum |R' - R|^2) / sqrt(sum |R|^2)` (dimensionless).
    pub tol: f64,
    /// Iteration cap; reaching it is recorded in the step statistics.
    pub max_iter: u32,
    /// Jacobi's own settings (`Method::Jacobi`).
    #[serde(flatten)]
    pub jacobi: JacobiSettings,
    /// Use several threads for colors and Jacobi (results are bit-identical either way).
    pub parallel: bool,
    /// Smallest contact problem worth solving on several threads. Colored Gauss-Seidel
    /// then runs on a team of `threads` threads kept from step to step, with a spin barrier
    /// between colors; Jacobi on the rayon pool.
    #[serde(default = "default_parallel_min")]
    pub parallel_min: usize,
    /// Threads of the colored Gauss-Seidel team; 0 means every available core.
    #[serde(default)]
    pub threads: usize,
    /// Gauss-Seidel's own settings (`Method::Gs`, `Method::ColoredGs`).
    #[serde(flatten)]
    pub gauss_seidel: GaussSeidelSettings,
    /// Velocity test (m/s), from iteration [`GaussSeidelSettings::relax_after`] + 1 of a
    /// step on (the plain iterations of every method that runs the test): the step also
    /// ends when no body's velocity (rim speed `r |omega|` included) changed over the last
    /// iteration by more than this times the iteration's relaxation (so that, as in the
    /// impulse test, the bound is on the change the local solutions ask for). 0 turns it
    /// off, as in records written before it.
    #[serde(default)]
    pub velocity_tol: f64,
    /// Open contacts left out of the sweeps (m/s): a candidate that carries no impulse and
    /// whose normal velocity at the start of the solve, shifted by its gap (`U_n +
    /// bias_n`), exceeds this cannot take an impulse unless the velocities change by as
    /// much during the step. Such rows are swept only if, once the others have converged,
    /// one of them would close; then the step is solved again with every row, and the step
    /// counts the iterations of both solves (up to twice `max_iter`). 0 sweeps every
    /// candidate, as in records written before this field.
    #[serde(default)]
    pub open_skip: f64,
    /// Overlap (m) beyond which a contact that carries a normal impulse at the end of the
    /// Gauss-Seidel or Jacobi iterations gets `deep_sweeps` more local updates (unrelaxed,
    /// in the order of the iterations: contact order for Jacobi), so that it leaves the step satisfying its own law: a loaded contact
    /// the stopping tests leave closing by a small residual velocity would otherwise
    /// deepen by it step after step (docs/results.md, "Which contact, and why"). Its neighbours
    /// take the change. Contacts with a force-driven wall (solved with the full 2x2 law)
    /// are left out. 0 turns it off, as in records written before it; Gauss-Seidel and
    /// Jacobi only (on the GPU, in color order for both: WGSL `deep_updates`).
    #[serde(default)]
    pub deep_gap: f64,
    /// See `deep_gap`.
    #[serde(default)]
    pub deep_sweeps: u32,
    /// Anderson's own settings (`Method::AndersonGs`).
    #[serde(flatten)]
    pub anderson: AndersonSettings,
    /// Iterations between two convergence tests (Gauss-Seidel and Jacobi); 0 lets the
    /// backend choose ([`SolverParams::check_interval`]). A step then stops only at a
    /// multiple of it (or at `max_iter`). On the CPU a test costs nothing beyond the sweep's
    /// sums; on the GPU each is a reduction over the contacts.
    #[serde(default)]
    pub check_every: u32,
}

/// The settings of the Gauss-Seidel methods. Their names in records and checkpoints are
/// those of the configuration's keys (`gs_relax`, `gs_relax_after`).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct GaussSeidelSettings {
    /// Relaxation of the update in (0, 1], applied from iteration `relax_after + 1` of a
    /// step on: each contact moves this fraction of the way from its impulse to its local
    /// solution. The convergence test divides the change by it, so `tol` keeps bounding the
    /// distance to the local solutions. Records written before this field existed ran
    /// unrelaxed (1).
    #[serde(rename = "gs_relax", default = "unrelaxed")]
    pub relax: f64,
    /// Iterations of a step swept unrelaxed before `relax` applies; steps that converge
    /// within them are unaffected by it. The velocity test starts after them too, whatever
    /// the method.
    #[serde(rename = "gs_relax_after", default)]
    pub relax_after: u32,
}

/// The settings of the Jacobi method.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct JacobiSettings {
    /// Relaxation factor in (0, 1] (the configuration's `solver.jacobi_relax`; `relax` in
    /// records and checkpoints).
    pub relax: f64,
}

/// The settings of Anderson-accelerated Gauss-Seidel.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct AndersonSettings {
    /// Anderson depth: the differences between the last `depth + 1` iterates enter the
    /// mixing; 0 is plain Gauss-Seidel (`anderson_depth` in records and checkpoints).
    #[serde(rename = "anderson_depth", default = "default_anderson_depth")]
    pub depth: u32,
}

/// Iterations between two convergence tests on the GPU when `solver.check_every` is 0: a
/// test there is one reduction over the contacts (a single-workgroup dispatch) plus a copy of
/// the dispatch arguments it writes, against one dispatch per color per iteration
/// (docs/gpu.md, "Measured on hardware").
pub const GPU_CHECK_EVERY: u32 = 8;

/// Default of the configuration's `solver.deep_overlap` for Gauss-Seidel and Jacobi, as a
/// fraction of `r_min` ([`SolverParams::deep_gap`] is this times `r_min`): loaded contacts
/// deeper than this leave each step satisfying their law, which holds the largest overlap
/// near it at every friction at the paper's time step (docs/results.md, "Every friction at
/// 0.5 ms"). Contacts that stay shallower, as every contact of most low-friction tests
/// does, are not affected.
pub fn default_deep_overlap_rel() -> f64 {
    0.005
}

/// Default of [`SolverParams::deep_sweeps`] (and of the configuration's `solver.deep_sweeps`):
/// chains of deep contacts sharing disks need tens of sweeps before the update of one no
/// longer undoes another's (docs/results.md, "Every friction at 0.5 ms").
pub fn default_deep_sweeps() -> u32 {
    50
}

/// Default of [`AndersonSettings::depth`] (docs/method.md, "Anderson-accelerated
/// Gauss-Seidel").
pub fn default_anderson_depth() -> u32 {
    5
}

fn unrelaxed() -> f64 {
    1.0
}

/// Default of the velocity test as a fraction of `r_min` per time step
/// ([`SolverParams::velocity_tol`] is this times `r_min / dt`): at high friction it ends
/// the steps whose velocities have settled while undetermined forces keep drifting, at a
/// cost in strength within the scatter between trajectories (docs/results.md, "The
/// velocity test").
pub fn default_velocity_tol_rel() -> f64 {
    1e-5
}

/// Default of [`GaussSeidelSettings::relax`]. Some contacts of a high-friction packing flip
/// between two states from one sweep to the next (a disk whose second contact opens and
/// closes every iteration), and plain Gauss-Seidel then runs to the cap; relaxation damps
/// these cycles. 0.5 needed the fewest iterations and capped steps among the values tried
/// (docs/results.md, "Relaxed Gauss-Seidel").
pub fn default_gs_relax() -> f64 {
    0.5
}

/// Default of [`GaussSeidelSettings::relax_after`]. At friction 0.3 (40-60 iterations per step
/// on average) relaxation from the first iteration cost 20-30% more iterations, while 50,
/// 100 or 200 plain iterations first gave the same count as plain Gauss-Seidel within the
/// scatter between trajectories, and the same gain at friction 3 (docs/results.md,
/// "Relaxed Gauss-Seidel").
pub fn default_gs_relax_after() -> u32 {
    100
}

impl Default for SolverParams {
    fn default() -> Self {
        SolverParams {
            method: Method::ColoredGs,
            tol: 1e-4,
            max_iter: 1000,
            jacobi: JacobiSettings { relax: 0.5 },
            parallel: true,
            parallel_min: default_parallel_min(),
            threads: 0,
            gauss_seidel: GaussSeidelSettings {
                relax: default_gs_relax(),
                relax_after: default_gs_relax_after(),
            },
            velocity_tol: 0.0,
            open_skip: 0.0,
            deep_gap: 0.0,
            deep_sweeps: 0,
            anderson: AndersonSettings {
                depth: default_anderson_depth(),
            },
            check_every: 0,
        }
    }
}

/// The cores this process may use, asked once: the standard library reads the cgroup's
/// quota files on every call, which cost 1-2% of a 5000-disk compression step when asked
/// per step (docs/benchmarks.md, "Where a compression step waits"). The CPU team's size and
/// the GPU path's recording threads (asked once per window) come from it.
pub(crate) fn cores() -> usize {
    static CORES: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get()))
}

/// Default of [`SolverParams::parallel_min`]. Below a few thousand contacts a color is a
/// few chunks and the barriers between colors cost more than the halved work.
pub fn default_parallel_min() -> usize {
    4096
}

impl SolverParams {
    /// Whether the steps give deep contacts local updates ([`SolverParams::deep_gap`]),
    /// on either backend.
    pub fn deep_updates(&self) -> bool {
        self.deep_gap > 0.0 && self.deep_sweeps > 0
    }

    /// The Gauss-Seidel relaxation of iteration `it` (1-based) of a step.
    pub fn relax_at(&self, it: u32) -> f64 {
        if it > self.gauss_seidel.relax_after {
            self.gauss_seidel.relax
        } else {
            1.0
        }
    }

    /// Iterations between two convergence tests: `check_every`, or when it is 0 every
    /// iteration on the CPU and [`GPU_CHECK_EVERY`] on the GPU.
    pub fn check_interval(&self, gpu: bool) -> u32 {
        match (self.check_every, gpu) {
            (0, false) => 1,
            (0, true) => GPU_CHECK_EVERY,
            (k, _) => k,
        }
    }

    /// Whether iteration `it` of a step ends with a convergence test (every
    /// [`SolverParams::check_interval`] iterations on the CPU, and at the cap).
    pub fn checks_at(&self, it: u32) -> bool {
        it.is_multiple_of(self.check_interval(false)) || it >= self.max_iter
    }

    /// Threads of the colored Gauss-Seidel team (1 when `parallel` is off).
    pub fn team_size(&self) -> usize {
        if !self.parallel {
            return 1;
        }
        match self.threads {
            0 => cores(),
            n => n,
        }
    }

    /// Rejects a non-positive tolerance, a zero iteration cap and a relaxation outside (0, 1].
    pub fn validate(&self) -> Result<()> {
        use crate::protocol::limits::{check_at_least, check_half_open, check_open};
        check_open("solver.tol", self.tol, 0.0, 1.0)?;
        check_at_least("solver.max_iter", self.max_iter.into(), 1, "at least one sweep")?;
        check_half_open("solver.jacobi_relax", self.jacobi.relax, 0.0, 1.0)?;
        if !(self.gauss_seidel.relax > 0.0 && self.gauss_seidel.relax <= 1.0) {
            return Err(Error::invalid(
                "solver.gs_relax",
                self.gauss_seidel.relax,
                "must lie in (0, 1]",
            ));
        }
        if !(self.velocity_tol >= 0.0 && self.velocity_tol.is_finite()) {
            return Err(Error::invalid(
                "solver.velocity_tol",
                self.velocity_tol,
                "must be finite and >= 0",
            ));
        }
        if !(self.open_skip >= 0.0 && self.open_skip.is_finite()) {
            return Err(Error::invalid(
                "solver.open_skip_gap",
                self.open_skip,
                "must be finite and >= 0",
            ));
        }
        if !(self.deep_gap >= 0.0 && self.deep_gap.is_finite()) {
            return Err(Error::invalid(
                "solver.deep_overlap",
                self.deep_gap,
                "must be finite and >= 0",
            ));
        }
        if self.deep_gap > 0.0 && self.method == Method::AndersonGs {
            return Err(Error::invalid(
                "solver.deep_overlap",
                self.deep_gap,
                "is not implemented with method = \"anderson-gs\": 0 with it",
            ));
        }
        if self.deep_sweeps > MAX_DEEP_SWEEPS {
            return Err(Error::invalid(
                "solver.deep_sweeps",
                self.deep_sweeps,
                &format!("must be <= {MAX_DEEP_SWEEPS}"),
            ));
        }
        if self.anderson.depth > MAX_ANDERSON_DEPTH {
            return Err(Error::invalid(
                "solver.anderson_depth",
                self.anderson.depth,
                &format!("must be <= {MAX_ANDERSON_DEPTH}"),
            ));
        }
        if self.deep_gap > 0.0 && self.method == Method::Apgd {
            return Err(Error::invalid(
                "solver.deep_overlap",
                self.deep_gap,
                "applies to Gauss-Seidel and Jacobi only: 0 with method = \"apgd\"",
            ));
        }
        Ok(())
    }
}

/// Largest [`AndersonSettings::depth`]: the history holds two vectors of all impulses per
/// unit of depth, and beyond a few tens the fit is dominated by stale differences.
pub const MAX_ANDERSON_DEPTH: u32 = 50;

/// Largest [`SolverParams::deep_sweeps`]: chains of deep contacts converge within a few
/// hundred sweeps, and the GPU runs them all in one workgroup, whose loops a software
/// adapter (lavapipe) cuts off after 65,535 iterations (shaders/solve.wgsl, `deep_updates`):
/// at this bound and 11 colors, that leaves room for about 300 deep contacts per color.
/// Beyond that the kernel runs fewer sweeps on such an adapter, counts them and warns
/// (`gpu::backend::DEEP_LOOP_BUDGET`).
pub const MAX_DEEP_SWEEPS: u32 = 1000;

/// Default of the gap beyond which an open contact is left out of the sweeps, as a
/// fraction of `r_min` ([`SolverParams::open_skip`] is this times `r_min / dt`): a contact
/// whose gap, at the start-of-solve velocities, would stay open by more than 1e-3 `r_min` at
/// the end of the step closes only if the relative velocity of its disks changes by 1e-3
/// `r_min / dt` (1 m/s with the paper's `r_min` and `dt`, twice the top wall's speed)
/// within the step. How many it leaves out, and how rarely a step needs the second solve:
/// docs/benchmarks.md, "Open candidates left out".
pub fn default_open_skip_gap() -> f64 {
    1e-3
}

/// What the solver did in one step.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveStats {
    /// Iterations (sweeps over all contacts) performed.
    pub iterations: u32,
    /// True when the tolerance was met before the cap.
    pub converged: bool,
    /// The last relative quadratic change (dimensionless).
    pub residual: f64,
    /// Number of colors (0 unless colored).
    pub colors: u32,
    /// True when a left-out contact would have closed, so the step was solved again with
    /// every contact.
    pub unparked: bool,
    /// Contacts given local updates after the iterations ([`SolverParams::deep_gap`]).
    pub deep: u32,
}
