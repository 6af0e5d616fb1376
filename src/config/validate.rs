//! Range checks of a configuration. Every error names the key by its TOML path
//! (`test.sigma3`) and says what is allowed, so a user can fix the file without the source.

use crate::error::{Error, Result, check_non_negative, check_positive, check_range};

use super::Config;
use crate::solver::Method;

/// Rejects a value outside the open interval `(lo, hi)` (and NaN).
fn check_open(field: &str, value: f64, lo: f64, hi: f64) -> Result<()> {
    if value > lo && value < hi {
        Ok(())
    } else {
        Err(Error::invalid(
            field,
            value,
            &format!("must lie in ({lo}, {hi}), bounds excluded"),
        ))
    }
}

/// Rejects a value outside `(lo, hi]` (and NaN).
fn check_half_open(field: &str, value: f64, lo: f64, hi: f64) -> Result<()> {
    if value > lo && value <= hi {
        Ok(())
    } else {
        Err(Error::invalid(field, value, &format!("must lie in ({lo}, {hi}]")))
    }
}

/// Rejects an integer below `min`.
fn check_at_least(field: &str, value: u64, min: u64, why: &str) -> Result<()> {
    if value >= min {
        Ok(())
    } else {
        Err(Error::invalid(field, value, &format!("must be >= {min} ({why})")))
    }
}

/// Most disks a sample may hold: contacts name their disks by 32-bit indices shared with the
/// walls, and a hundred million disks is far beyond what one step can solve in useful time.
pub const MAX_DISKS: usize = 100_000_000;

/// Memory a test needs per disk, at least (bytes): the disk's own state (about 150 bytes),
/// its share of the contacts (about 3 per disk, warm start and solver rows included), the
/// neighbour grid and the record's buffers. An estimate from below: a sample refused on it
/// could not run on this machine.
pub const BYTES_PER_DISK: u64 = 1024;

/// Total memory of this machine in bytes, when the system tells (`/proc/meminfo` on Linux).
fn machine_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// The most disks a sample may hold on this machine: [`MAX_DISKS`], or fewer where the
/// memory does not hold that many at [`BYTES_PER_DISK`].
pub fn max_disks_here() -> usize {
    machine_memory().map_or(MAX_DISKS, |total| {
        MAX_DISKS.min(usize::try_from(total / BYTES_PER_DISK).unwrap_or(usize::MAX))
    })
}

/// Refuses a disk count beyond [`MAX_DISKS`] or beyond what this machine's memory holds at
/// [`BYTES_PER_DISK`], before anything is allocated for the disks.
pub fn check_disk_count(field: &str, disks: usize) -> Result<()> {
    if disks > MAX_DISKS {
        return Err(Error::invalid(
            field,
            disks,
            &format!("must be <= {MAX_DISKS} (contacts index disks in 32 bits)"),
        ));
    }
    if let Some(total) = machine_memory() {
        let need = disks as u64 * BYTES_PER_DISK;
        if need > total {
            return Err(Error::invalid(
                field,
                disks,
                &format!(
                    "needs at least {:.1} GB of memory ({BYTES_PER_DISK} bytes a disk), this \
                     machine has {:.1} GB: at most {} disks here",
                    need as f64 / 1e9,
                    total as f64 / 1e9,
                    total / BYTES_PER_DISK
                ),
            ));
        }
    }
    Ok(())
}

/// Typical width of the compacted sample over the width of its deposition box: the
/// deposit is sized at a packing fraction of 0.84 and compaction (the right wall pushing)
/// brings it to about 0.89, so the width shrinks by about 0.84 / 0.89.
const COMPACTED_WIDTH: f64 = 0.95;

/// Confining and compaction stresses accepted (Pa): from 1 kPa, below which a bare number
/// meant as MPa lands (`sigma3 = 8` is 8 Pa), to 10 GPa, the stiffness of the grains
/// themselves, where rigid disks mean nothing.
pub const PRESSURE_RANGE: (f64, f64) = (1e3, 1e10);

/// Time steps accepted (s): from 1 ns, where a test of the paper's strain would take
/// billions of steps (and `r_min / dt` overflows below about 1e-308 s), to 1 s.
pub const DT_RANGE: (f64, f64) = (1e-9, 1.0);

/// Refuses a stress outside [`PRESSURE_RANGE`], naming `field` and hinting at a forgotten
/// unit.
pub fn check_pressure(field: &str, pa: f64) -> Result<()> {
    let (lo, hi) = PRESSURE_RANGE;
    if pa.is_finite() && (lo..=hi).contains(&pa) {
        return Ok(());
    }
    Err(Error::invalid(
        field,
        format!("{pa:e} Pa"),
        "must lie between 1 kPa and 10 GPa; give the unit, e.g. \"8 MPa\" (a bare number is \
         in Pa)",
    ))
}

/// Refuses a time step outside [`DT_RANGE`], naming `field`.
pub fn check_time_step(field: &str, s: f64) -> Result<()> {
    let (lo, hi) = DT_RANGE;
    if s.is_finite() && (lo..=hi).contains(&s) {
        return Ok(());
    }
    Err(Error::invalid(
        field,
        format!("{s:e} s"),
        "must lie between 1e-9 s and 1 s (the paper uses 5e-4 s); give the unit, e.g. \
         \"0.5 ms\" (a bare number is in s)",
    ))
}

impl Config {
    /// Checks every value against its allowed range; the first failure is returned.
    pub fn validate(&self) -> Result<()> {
        let s = &self.sample;
        // Each side strip is a few disks thick; below ~50 disks there is no bulk between them.
        check_at_least(
            "sample.disks",
            s.disks as u64,
            50,
            "the deformable-wall strips need disks on both sides of a bulk",
        )?;
        check_disk_count("sample.disks", s.disks)?;
        check_positive("sample.r_min", s.r_min.0)?;
        if !(s.r_max.0.is_finite() && s.r_max.0 >= s.r_min.0) {
            return Err(Error::invalid(
                "sample.r_max",
                s.r_max,
                &format!("must be finite and >= sample.r_min = {}", s.r_min),
            ));
        }
        check_positive("sample.density", s.density.0)?;
        // Masses, inverse masses and kinetic energies stay finite and normal far beyond
        // any material (aerogels to osmium, 1 to 22,600 kg/m3) and the density scaling of
        // quasi-static studies; 1e308 overflowed the masses and 1e-320 their inverses.
        if !(1e-6..=1e12).contains(&s.density.0) {
            return Err(Error::invalid(
                "sample.density",
                s.density,
                "must lie in [1e-6, 1e12] kg/m3 (the masses and their inverses must stay finite)",
            ));
        }
        // TOML integers are signed 64-bit: a larger seed could not be written back.
        if s.seed > i64::MAX as u64 {
            return Err(Error::invalid(
                "sample.seed",
                s.seed,
                &format!("must be <= {} (TOML integers are 64-bit signed)", i64::MAX),
            ));
        }
        check_positive("sample.aspect_ratio", s.aspect_ratio)?;
        // The deposit box's width comes from it: 1e-320 made the width infinite.
        if !(0.01..=100.0).contains(&s.aspect_ratio) {
            return Err(Error::invalid(
                "sample.aspect_ratio",
                s.aspect_ratio,
                "must lie in [0.01, 100] (sample height over width)",
            ));
        }

        let v = &self.solver;
        check_positive("solver.dt", v.dt.0)?;
        check_time_step("solver.dt", v.dt.0)?;
        check_range("solver.theta", v.theta, 0.5, 1.0)?;
        check_open("solver.tol", v.tol, 0.0, 1.0)?;
        check_at_least("solver.max_iter", v.max_iter.into(), 1, "at least one sweep")?;
        check_half_open("solver.jacobi_relax", v.jacobi_relax, 0.0, 1.0)?;
        check_half_open("solver.gs_relax", v.gs_relax, 0.0, 1.0)?;
        check_non_negative("solver.velocity_tol", v.velocity_tol)?;
        check_non_negative("solver.open_skip_gap", v.open_skip_gap)?;
        // Before deep_overlap, which must stay below it.
        check_positive("solver.overlap_limit", v.overlap_limit)?;
        let deep_overlap = v.deep_overlap_rel();
        check_non_negative("solver.deep_overlap", deep_overlap)?;
        if deep_overlap > 0.0 && v.method == Method::AndersonGs {
            return Err(Error::invalid(
                "solver.deep_overlap",
                deep_overlap,
                "is not implemented with method = \"anderson-gs\": 0 with it",
            ));
        }
        if deep_overlap > 0.0 {
            check_at_least("solver.deep_sweeps", v.deep_sweeps.into(), 1, "a local update")?;
            if deep_overlap >= v.overlap_limit {
                return Err(Error::invalid(
                    "solver.deep_overlap",
                    deep_overlap,
                    &format!(
                        "must be below solver.overlap_limit = {} (the run stops there)",
                        v.overlap_limit
                    ),
                ));
            }
        }
        check_range("solver.alert_distance", v.alert_distance, 0.0, 1.0)?;

        let c = &self.compaction;
        check_positive("compaction.sigma_c", c.sigma_c.0)?;
        check_pressure("compaction.sigma_c", c.sigma_c.0)?;
        check_non_negative("compaction.friction", c.friction)?;

        let t = &self.test;
        check_non_negative("test.mu", t.mu)?;
        if let Some(w) = t.wall_mu {
            check_non_negative("test.wall_mu", w)?;
        }
        check_positive("test.sigma3", t.sigma3.0)?;
        check_pressure("test.sigma3", t.sigma3.0)?;
        check_positive("test.strip_thickness", t.strip_thickness.0)?;
        // The strips need a core between them, which the confinement checks on the compacted
        // sample; a sample too narrow for them by far is refused here, before minutes of
        // deposition and compaction, from the width its disk count gives.
        let width =
            crate::sample::box_width_for(s.disks, s.r_min.0, s.r_max.0, s.aspect_ratio) * COMPACTED_WIDTH;
        let need = 2.0 * t.strip_thickness.0 + 2.0 * s.r_max.0;
        if width <= need {
            let area = crate::sample::mean_area(s.r_min.0, s.r_max.0);
            let min =
                (need / COMPACTED_WIDTH).powi(2) * crate::sample::DEPOSIT_PACKING * s.aspect_ratio / area;
            return Err(Error::invalid(
                "sample.disks",
                s.disks,
                &format!(
                    "a sample of {} disks will be about {width:.1} m wide once compacted, too \
                     narrow for two strips of test.strip_thickness = {} m and a core (at least \
                     {need:.1} m): use more than {} disks or thinner strips",
                    s.disks,
                    t.strip_thickness.0,
                    min.ceil() as u64
                ),
            ));
        }
        check_positive("test.axial_velocity", t.axial_velocity.0)?;
        // The top wall's travel per step, against the smallest disk: more than a tenth of
        // r_min per step is an impact, not a quasi-static test (1e308 m/s gave an infinite
        // travel); below 1e-9 r_min the test never ends (1e-320 m/s wrote 118 MB of rows
        // without moving).
        let travel = t.axial_velocity.0 * self.solver.dt.0 / s.r_min.0;
        if !(1e-9..=0.1).contains(&travel) {
            return Err(Error::invalid(
                "test.axial_velocity",
                t.axial_velocity,
                &format!(
                    "moves the top wall by {travel:.3e} r_min per step (solver.dt = {}, \
                     sample.r_min = {}): keep it between 1e-9 and 0.1",
                    self.solver.dt, s.r_min
                ),
            ));
        }
        check_open("test.strain_end", t.strain_end, 0.0, 1.0)?;
        check_range("test.e_n", t.e_n, 0.0, 1.0)?;
        check_range("test.e_t", t.e_t, -1.0, 1.0)?;

        let e = &self.equilibrium;
        check_positive("equilibrium.kinetic_ratio", e.kinetic_ratio)?;
        check_positive("equilibrium.runaway_kinetic_ratio", e.runaway_kinetic_ratio)?;
        check_positive("equilibrium.compaction_kinetic_ratio", e.compaction_kinetic_ratio)?;
        check_positive("equilibrium.force_imbalance", e.force_imbalance)?;
        check_non_negative("equilibrium.creep_rate", e.creep_rate)?;
        check_at_least("equilibrium.hold_steps", e.hold_steps, 1, "a number of steps")?;
        check_positive("equilibrium.max_time", e.max_time.0)?;

        let o = &self.output;
        if o.dir.as_os_str().is_empty() {
            return Err(Error::invalid("output.dir", "\"\"", "must be a directory path"));
        }
        check_at_least("output.series_every", o.series_every, 1, "a number of steps")?;
        check_non_negative("output.snapshot_every", o.snapshot_every)?;
        // What only the solver's own parameters can tell (e.g. deep_overlap with Jacobi), and
        // their bounds (deep_sweeps, anderson_depth), checked once there.
        self.protocol().step.solver.validate()?;
        Ok(())
    }
}
