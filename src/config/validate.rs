//! Range checks of a configuration. Every error names the key by its TOML path
//! (`test.sigma3`) and says what is allowed, so a user can fix the file without the source.

use crate::error::{Error, Result, check_non_negative, check_positive, check_range};

use super::Config;

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
        check_positive("sample.r_min", s.r_min.0)?;
        if !(s.r_max.0.is_finite() && s.r_max.0 >= s.r_min.0) {
            return Err(Error::invalid(
                "sample.r_max",
                s.r_max,
                &format!("must be finite and >= sample.r_min = {}", s.r_min),
            ));
        }
        check_positive("sample.density", s.density.0)?;
        // TOML integers are signed 64-bit: a larger seed could not be written back.
        if s.seed > i64::MAX as u64 {
            return Err(Error::invalid(
                "sample.seed",
                s.seed,
                &format!("must be <= {} (TOML integers are 64-bit signed)", i64::MAX),
            ));
        }
        check_positive("sample.aspect_ratio", s.aspect_ratio)?;

        let v = &self.solver;
        check_positive("solver.dt", v.dt.0)?;
        check_range("solver.theta", v.theta, 0.5, 1.0)?;
        check_open("solver.tol", v.tol, 0.0, 1.0)?;
        check_at_least("solver.max_iter", v.max_iter.into(), 1, "at least one sweep")?;
        check_half_open("solver.jacobi_relax", v.jacobi_relax, 0.0, 1.0)?;
        check_half_open("solver.gs_relax", v.gs_relax, 0.0, 1.0)?;
        check_non_negative("solver.velocity_tol", v.velocity_tol)?;
        check_non_negative("solver.open_skip_gap", v.open_skip_gap)?;
        check_non_negative("solver.deep_overlap", v.deep_overlap)?;
        if v.deep_overlap > 0.0 {
            check_at_least("solver.deep_sweeps", v.deep_sweeps.into(), 1, "a local update")?;
            if v.deep_overlap >= v.overlap_limit {
                return Err(Error::invalid(
                    "solver.deep_overlap",
                    v.deep_overlap,
                    &format!(
                        "must be below solver.overlap_limit = {} (the run stops there)",
                        v.overlap_limit
                    ),
                ));
            }
        }
        check_range("solver.alert_distance", v.alert_distance, 0.0, 1.0)?;
        check_at_least("solver.check_every", v.check_every.into(), 1, "a check interval")?;
        check_positive("solver.overlap_limit", v.overlap_limit)?;

        let c = &self.compaction;
        check_positive("compaction.sigma_c", c.sigma_c.0)?;
        check_non_negative("compaction.friction", c.friction)?;

        let t = &self.test;
        check_non_negative("test.mu", t.mu)?;
        if let Some(w) = t.wall_mu {
            check_non_negative("test.wall_mu", w)?;
        }
        check_positive("test.sigma3", t.sigma3.0)?;
        check_positive("test.strip_thickness", t.strip_thickness.0)?;
        check_positive("test.axial_velocity", t.axial_velocity.0)?;
        check_open("test.strain_end", t.strain_end, 0.0, 1.0)?;
        check_range("test.e_n", t.e_n, 0.0, 1.0)?;
        check_range("test.e_t", t.e_t, -1.0, 1.0)?;

        let e = &self.equilibrium;
        check_positive("equilibrium.kinetic_ratio", e.kinetic_ratio)?;
        check_positive("equilibrium.runaway_kinetic_ratio", e.runaway_kinetic_ratio)?;
        check_positive("equilibrium.compaction_kinetic_ratio", e.compaction_kinetic_ratio)?;
        check_positive("equilibrium.force_imbalance", e.force_imbalance)?;
        check_at_least("equilibrium.hold_steps", e.hold_steps, 1, "a number of steps")?;
        check_positive("equilibrium.max_time", e.max_time.0)?;

        let o = &self.output;
        if o.dir.as_os_str().is_empty() {
            return Err(Error::invalid("output.dir", "\"\"", "must be a directory path"));
        }
        check_at_least("output.series_every", o.series_every, 1, "a number of steps")?;
        check_non_negative("output.snapshot_every", o.snapshot_every)?;
        // What only the solver's own parameters can tell (e.g. deep_overlap with Jacobi).
        self.protocol().step.solver.validate()?;
        Ok(())
    }
}
