//! Range checks of a configuration. Every error names the key by its TOML path
//! (`test.sigma3`) and says what is allowed, so a user can fix the file without the source.

use crate::error::{Error, Result, check_non_negative, check_positive, check_range};

use super::Config;
use crate::solver::Method;

use crate::protocol::limits::check_at_least;
pub use crate::protocol::limits::{
    BYTES_PER_DISK, DT_RANGE, MAX_DISKS, PRESSURE_RANGE, check_disk_count, check_pressure, check_time_step,
    max_disks_here,
};

impl Config {
    /// Checks every value against its allowed range; the first failure is returned. The
    /// values the protocol takes as they are (counts, stresses, velocities, ratios) are
    /// checked once, by the protocol's parameters ([`crate::protocol::ProtocolParams::validate`]);
    /// this checks what only the configuration holds, or holds in another form: fractions
    /// of `sample.r_min` (the protocol has lengths and velocities), counts that the
    /// protocol clamps, the method's own settings, the output directory.
    pub fn validate(&self) -> Result<()> {
        let s = &self.sample;
        // TOML integers are signed 64-bit: a larger seed could not be written back.
        if s.seed > i64::MAX as u64 {
            return Err(Error::invalid(
                "sample.seed",
                s.seed,
                &format!("must be <= {} (TOML integers are 64-bit signed)", i64::MAX),
            ));
        }
        let v = &self.solver;
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
        // The protocol takes these clamped to at least 1.
        check_at_least(
            "equilibrium.hold_steps",
            self.equilibrium.hold_steps,
            1,
            "a number of steps",
        )?;
        let o = &self.output;
        if o.dir.as_os_str().is_empty() {
            return Err(Error::invalid("output.dir", "\"\"", "must be a directory path"));
        }
        check_at_least("output.series_every", o.series_every, 1, "a number of steps")?;
        self.protocol().validate()
    }
}
