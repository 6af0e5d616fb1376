//! One row of the measured time series. The records serialise it (`crate::record`, the
//! `/series` channel and `series.csv`); the serde attributes here say how a row reads back
//! from records written before a column existed.

use serde::{Deserialize, Deserializer, Serialize};

/// Measurements at one step. Non-finite values (e.g. the inertial number before the
/// compression starts, stored as NaN) are written as JSON `null` and read back as NaN.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SeriesRow {
    /// Simulated time (s).
    #[serde(deserialize_with = "f64_or_nan")]
    pub time_s: f64,
    /// Step index.
    pub step: u64,
    /// Phase name ("compaction", "confinement", "compression").
    pub phase: String,
    /// Axial strain `dz / h0` (compressive positive; 0 before the compression).
    #[serde(deserialize_with = "f64_or_nan")]
    pub strain_axial: f64,
    /// Axial stress on the top wall (Pa).
    #[serde(deserialize_with = "f64_or_nan")]
    pub sigma1_pa: f64,
    /// Confining stress applied by the strips (Pa).
    #[serde(deserialize_with = "f64_or_nan")]
    pub sigma3_pa: f64,
    /// Volumetric strain `dV / V0` (positive = dilation).
    #[serde(deserialize_with = "f64_or_nan")]
    pub volumetric_strain: f64,
    /// Candidate contacts (disk-disk and disk-wall).
    pub n_contacts: u64,
    /// Force-carrying contacts.
    pub n_force: u64,
    /// Force-carrying, non-slipping contacts.
    pub n_rolling: u64,
    /// Force-carrying, slipping contacts.
    pub n_sliding: u64,
    /// Geometric contacts without force.
    pub n_zero_force: u64,
    /// Coordination number `Z = 2 N_c / N'`.
    #[serde(deserialize_with = "f64_or_nan")]
    pub coordination: f64,
    /// Fraction of free disks with fewer than two force-carrying contacts.
    #[serde(deserialize_with = "f64_or_nan")]
    pub isolated_fraction: f64,
    /// Mean overlap over `r_min`.
    #[serde(deserialize_with = "f64_or_nan")]
    pub overlap_mean_rel: f64,
    /// Maximum overlap over `r_min`.
    #[serde(deserialize_with = "f64_or_nan")]
    pub overlap_max_rel: f64,
    /// Mean solver iterations per step over the row's interval.
    #[serde(deserialize_with = "f64_or_nan")]
    pub iterations: f64,
    /// Largest iteration count of a step in the interval.
    pub iterations_max: u64,
    /// Kinetic energy of the free disks (J per metre of thickness).
    #[serde(deserialize_with = "f64_or_nan")]
    pub kinetic_energy_j: f64,
    /// Inertial number.
    #[serde(deserialize_with = "f64_or_nan")]
    pub inertial_number: f64,
    /// Sample height between the walls (m).
    #[serde(deserialize_with = "f64_or_nan")]
    pub height_m: f64,
    /// Sample width between the outer edges of the strips (m).
    #[serde(deserialize_with = "f64_or_nan")]
    pub width_m: f64,
    /// Wall-clock time since the run started (s), summed over the parts of a resumed run
    /// (the time between a part's last checkpoint and its interruption is not counted).
    /// Filled by the recording, not the protocol; NaN in records written before it.
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub wall_s: f64,
    /// Mean number of contacts per step given local updates after the solver's iterations
    /// (`solver.deep_overlap`); 0 without them, and in records written before them.
    #[serde(default, deserialize_with = "f64_or_nan")]
    pub deep_contacts: f64,
    /// Fabric anisotropy `a_c = 2 (phi_1 - phi_2)` of the force-carrying disk-disk contacts
    /// ([`crate::measure::micro`]); 0 without such contacts, NaN in records written before
    /// the micromechanical columns (as are the columns below).
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub a_c: f64,
    /// Principal direction of the fabric (degrees in [0, 180), from the x axis).
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub theta_c_deg: f64,
    /// Normal force anisotropy `a_n`.
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub a_n: f64,
    /// Tangential force anisotropy `a_t`.
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub a_t: f64,
    /// Fraction of the force-carrying disk-disk contacts with `f_n > <f_n>` (strong network).
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub strong_fraction: f64,
    /// Share of the network's deviatoric stress carried by the strong network.
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub strong_q_share: f64,
    /// Larger principal value of the Love-Weber stress over the sample area `h w` (Pa); 0
    /// without a positive area.
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub lw_sigma1_pa: f64,
    /// Smaller principal value of the Love-Weber stress (Pa).
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub lw_sigma3_pa: f64,
    /// Largest deviation of the contact orientation histogram (18 bins of 10 degrees) from
    /// its mean, relative to the mean.
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub rose_max_dev: f64,
}

fn nan() -> f64 {
    f64::NAN
}

/// JSON `null` (how serde_json writes NaN and infinities) becomes NaN.
fn f64_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

impl SeriesRow {
    /// Kinetic energy over the confining stress times the sample's area,
    /// `K / (sigma3 h w)`: the compression's measure of how far from quasi-static the test
    /// is (the summary's `kinetic_ratio_max`, the runaway guard). NaN without a confining
    /// stress or a positive area.
    pub fn kinetic_ratio(&self) -> f64 {
        let area = self.height_m * self.width_m;
        if self.sigma3_pa > 0.0 && area > 0.0 {
            self.kinetic_energy_j / (self.sigma3_pa * area)
        } else {
            f64::NAN
        }
    }

    /// The row of `series` recorded nearest in time to `time_s` (s), `None` for an empty
    /// series. A snapshot holds no walls: its sample area and boundary stresses come from
    /// this row (an archived test's thinned series gives the nearest row it kept).
    pub fn nearest(series: &[SeriesRow], time_s: f64) -> Option<&SeriesRow> {
        series
            .iter()
            .min_by(|a, b| (a.time_s - time_s).abs().total_cmp(&(b.time_s - time_s).abs()))
    }
}
