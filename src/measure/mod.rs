//! What a biaxial test measures, as types and their maths: the rows of the time series
//! (which `crate::protocol::Gauge` fills from a backend's reductions), the phases and how
//! they ended, the micromechanical sums the backends accumulate, the derived results (peak
//! and residual strength, Mohr-Coulomb angle), the summary and its shear-band report. It
//! sits below the backends and knows none of the modules that compute, record or analyse
//! these measurements.

pub mod bands;
pub mod derived;
pub mod micro;
pub mod phase;
mod series;
pub mod summary;

pub use series::SeriesRow;

impl SeriesRow {
    /// Fills the micromechanical columns from a row's sums, the Love-Weber stress over the
    /// row's `height_m * width_m` (0 without a positive, finite area). Called again by the
    /// protocol after it changes a row's width (compaction measures between the walls).
    pub fn with_micro(mut self, m: &micro::MicroSums) -> SeriesRow {
        self.a_c = m.a_c();
        self.theta_c_deg = m.theta_c().to_degrees();
        self.a_n = m.a_n();
        self.a_t = m.a_t();
        self.strong_fraction = m.strong_fraction();
        self.strong_q_share = m.strong_q_share();
        let area = self.height_m * self.width_m;
        (self.lw_sigma1_pa, self.lw_sigma3_pa) = if area > 0.0 && area.is_finite() {
            m.love_weber(area).principal()
        } else {
            (0.0, 0.0)
        };
        self.rose_max_dev = m.rose_max_deviation();
        self
    }
}
