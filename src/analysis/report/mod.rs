//! The campaign report: for each contact friction, the peak and residual points in the
//! (p, q) plane, the Mohr-Coulomb fits, the macroscopic friction, and the fit of the
//! macroscopic friction against the contact friction.
//!
//! This module holds the report's model (what `report.json` holds); `analyse` builds it
//! from the tests' points, `csv` writes its tables. Finding a campaign's tests and the
//! report as text belong to the campaign (`crate::campaign::collect`, and
//! `crate::campaign::report_text`), which knows its grid file.

use std::path::PathBuf;

use super::fit::{Line, Saturation};

mod analyse;
mod csv;

pub use analyse::analyse;

/// The largest overlap, relative to the smallest radius, that docs/method.md allows at the
/// largest confining pressure; the report names the tests that passed it.
pub const OVERLAP_BOUND_REL: f64 = 0.01;

/// One finished test as the report sees it.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TestPoint {
    /// The run directory.
    pub dir: PathBuf,
    /// Contact friction.
    pub mu: f64,
    /// Confining stress (MPa).
    pub sigma3_mpa: f64,
    /// Peak and residual axial stress (MPa); the residual is absent for short tests.
    pub sigma1_peak_mpa: f64,
    /// See `sigma1_peak_mpa`.
    pub sigma1_residual_mpa: Option<f64>,
    /// The summary's largest kinetic ratio of the compression (absent in summaries
    /// written before it existed).
    #[serde(default)]
    pub kinetic_ratio_max: Option<f64>,
    /// The summary's largest overlap relative to r_min.
    #[serde(default)]
    pub overlap_max_rel: Option<f64>,
    /// The test's time step (s); absent in summaries written before it was recorded.
    #[serde(default)]
    pub dt_s: Option<f64>,
    /// The summary's wall-clock time (s), over all the parts of a resumed test.
    #[serde(default)]
    pub wall_time_s: Option<f64>,
    /// Axial strain at the peak.
    #[serde(default)]
    pub strain_peak: Option<f64>,
    /// Volumetric strain at the end (positive = dilation).
    #[serde(default)]
    pub volumetric_strain_final: Option<f64>,
    /// The shear bands of the summary's last snapshot interval, each as (angle from the
    /// axial direction in degrees, width in mean diameters); empty when none was found,
    /// absent when the summary holds no band analysis.
    #[serde(default)]
    pub bands: Option<Vec<[f64; 2]>>,
    /// Number of stress-drop events; absent in summaries that list them from row to row
    /// (written before the strain bins: `cdlab summarize` writes them again).
    #[serde(default)]
    pub stress_drops: Option<usize>,
    /// The largest stress drop (MPa); absent as `stress_drops`, or without events.
    #[serde(default)]
    pub stress_drop_max_mpa: Option<f64>,
    /// The overlap beyond which the test gave loaded contacts local updates
    /// (`solver.deep_overlap`, relative to r_min); absent when it gave none.
    #[serde(default)]
    pub deep_overlap_rel: Option<f64>,
}

impl TestPoint {
    /// The band angle from the axial direction that Coulomb's theory gives at the residual,
    /// `45 deg - phi/2` with `sin(phi) = (s1 - s3) / (s1 + s3)` (degrees): the reference
    /// the measured band angles are read against.
    pub fn coulomb_band_angle_deg(&self) -> Option<f64> {
        let s1 = self.sigma1_residual_mpa?;
        Some(45.0 - crate::measure::derived::friction_angle_deg(s1, self.sigma3_mpa) / 2.0)
    }
}

/// The analysis of one contact friction.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FrictionRow {
    /// Contact friction.
    pub mu: f64,
    /// Tests at this friction.
    pub tests: usize,
    /// Peak points: (p, q) = ((s1 + s3) / 2, (s1 - s3) / 2) in MPa.
    pub peak_pq_mpa: Vec<[f64; 2]>,
    /// Residual points (MPa).
    pub residual_pq_mpa: Vec<[f64; 2]>,
    /// `q = p sin(phi)` through the origin at the peak.
    pub peak_fit: Line,
    /// The unconstrained line at the peak (its intercept is the cohesion estimate, MPa).
    pub peak_fit_free: Line,
    /// Macroscopic friction at the peak `tan(phi)` and its standard error.
    #[serde(deserialize_with = "crate::analysis::fit::nan_as_null::number")]
    pub mu_macro: f64,
    /// See `mu_macro`.
    #[serde(deserialize_with = "crate::analysis::fit::nan_as_null::number")]
    pub mu_macro_se: f64,
    /// `q = p sin(phi)` through the origin at the residual (NaN slope when no residual).
    pub residual_fit: Line,
    /// Residual macroscopic friction and its standard error.
    #[serde(deserialize_with = "crate::analysis::fit::nan_as_null::number")]
    pub mu_macro_res: f64,
    /// See `mu_macro_res`.
    #[serde(deserialize_with = "crate::analysis::fit::nan_as_null::number")]
    pub mu_macro_res_se: f64,
    /// The distinct time steps of its tests (ms), in increasing order; empty when no
    /// summary recorded one.
    #[serde(default)]
    pub dt_ms: Vec<f64>,
    /// Wall-clock time of its tests, summed (hours; each test on its own threads).
    #[serde(default)]
    pub wall_time_h: f64,
}

/// The whole report (`report.json`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Report {
    /// One row per contact friction, in increasing friction.
    pub frictions: Vec<FrictionRow>,
    /// `mu_macro = a - b exp(-c mu)` (absent with fewer than three frictions).
    pub mu_macro_fit: Option<Saturation>,
    /// The same for the residual macroscopic friction.
    pub mu_macro_res_fit: Option<Saturation>,
    /// Run directories that could not be read, with the reason.
    pub missing: Vec<(PathBuf, String)>,
    /// Tests whose largest kinetic ratio exceeds
    /// [`crate::measure::summary::QUASI_STATIC_KINETIC_RATIO`], with that ratio: not
    /// quasi-static, their strengths suspect. They are in the fits; the table names them.
    #[serde(default)]
    pub suspect: Vec<(PathBuf, f64)>,
    /// Tests whose largest overlap passed [`OVERLAP_BOUND_REL`] of r_min, with that
    /// overlap: the solver fell short of docs/method.md's bound. They are in the fits; the table
    /// names them.
    #[serde(default)]
    pub overlapping: Vec<(PathBuf, f64)>,
    /// Wall-clock time of all the tests, summed (hours): what the campaign cost in
    /// test-hours, whatever the tests ran on and however many ran at once.
    #[serde(default)]
    pub wall_time_h: f64,
    /// Every test analysed, in increasing friction then confining stress (`tests.csv`).
    #[serde(default)]
    pub tests: Vec<TestPoint>,
}

impl FrictionRow {
    /// The time steps of the friction's tests for the CSV and the table (ms, `;` between
    /// several), "n/a" when no summary recorded one.
    pub fn dt_text(&self) -> String {
        if self.dt_ms.is_empty() {
            "n/a".into()
        } else {
            self.dt_ms
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(";")
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A friction tested at one pressure only: q/p = 0.5.
    pub(crate) fn one_pressure_point() -> TestPoint {
        TestPoint {
            dir: PathBuf::from("run"),
            mu: 0.3,
            sigma3_mpa: 1.0,
            sigma1_peak_mpa: 3.0,
            sigma1_residual_mpa: Some(2.0),
            kinetic_ratio_max: Some(1e-4),
            ..Default::default()
        }
    }

    /// The report of four tests with wall times 1800 s and 5400 s at friction 0.3, 3600 s
    /// and none at 0.5 (2 h, 1 h, 3 h in all).
    pub(crate) fn wall_time_report() -> Report {
        let at = |mu: f64, s3: f64, wall: Option<f64>| TestPoint {
            mu,
            sigma3_mpa: s3,
            wall_time_s: wall,
            ..one_pressure_point()
        };
        analyse(
            &[
                at(0.3, 1.0, Some(1800.0)),
                at(0.3, 2.0, Some(5400.0)),
                at(0.5, 1.0, Some(3600.0)),
                at(0.5, 2.0, None),
            ],
            Vec::new(),
        )
    }

    /// A report whose figures include NaN (one pressure: no standard errors) is written as
    /// JSON with `null` there and reads back with NaN in the same places.
    #[test]
    fn report_json_with_undefined_figures_reads_back() {
        let rep = analyse(&[one_pressure_point()], Vec::new());
        assert!(rep.frictions[0].mu_macro_se.is_nan());
        let json = serde_json::to_string(&rep).unwrap();
        assert!(json.contains("\"mu_macro_se\":null"), "{json}");
        let back: Report = serde_json::from_str(&json).unwrap();
        let (a, b) = (&rep.frictions[0], &back.frictions[0]);
        assert_eq!(a.mu_macro, b.mu_macro);
        assert!(b.mu_macro_se.is_nan() && b.peak_fit.intercept_se.is_nan());
        assert!(b.peak_fit_free.slope.is_nan());
    }
}
