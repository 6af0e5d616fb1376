//! The report's tables as CSV: one row per contact friction (`report.csv`) and one per
//! test (`tests.csv`), each with a header that names the units.

use super::Report;

impl Report {
    /// The friction table as CSV (header with units).
    pub fn csv(&self) -> String {
        let mut s = String::from(
            "mu,tests,mu_macro,mu_macro_se,mu_macro_res,mu_macro_res_se,cohesion_peak_mpa,cohesion_peak_se_mpa,dt_ms,wall_time_h\n",
        );
        for r in &self.frictions {
            s.push_str(&format!(
                "{},{},{},{},{},{},{},{},{},{}\n",
                r.mu,
                r.tests,
                r.mu_macro,
                r.mu_macro_se,
                r.mu_macro_res,
                r.mu_macro_res_se,
                r.peak_fit_free.intercept,
                r.peak_fit_free.intercept_se,
                r.dt_text(),
                r.wall_time_h
            ));
        }
        s
    }

    /// Every test as CSV (header with units): strengths, dilatancy, shear bands (the band
    /// rising towards +x, then the one towards -x, beside Coulomb's angle at the residual),
    /// stress drops, overlap, kinetic ratio, time step, wall time and the threshold of local
    /// updates of deep contacts. An empty cell is a figure the summary does not hold (or,
    /// for the threshold, a test without local updates).
    pub fn tests_csv(&self) -> String {
        let mut s = String::from(
            "dir,mu,sigma3_mpa,sigma1_peak_mpa,strain_peak,sigma1_residual_mpa,volumetric_strain_final,\
             band_pos_angle_deg,band_pos_width_diameters,band_neg_angle_deg,band_neg_width_diameters,\
             coulomb_band_angle_deg,stress_drops,stress_drop_max_mpa,overlap_max_rel,kinetic_ratio_max,dt_ms,wall_time_h,deep_overlap_rel\n",
        );
        let opt = |x: Option<f64>| x.map_or(String::new(), |v| v.to_string());
        for t in &self.tests {
            let side = |positive: bool| {
                t.bands
                    .as_ref()
                    .and_then(|b| b.iter().find(|[a, _]| (*a > 0.0) == positive))
                    .map_or([None, None], |[a, w]| [Some(*a), Some(*w)])
            };
            let ([pa, pw], [na, nw]) = (side(true), side(false));
            let cells = [
                format!("\"{}\"", t.dir.display().to_string().replace('"', "\"\"")),
                t.mu.to_string(),
                t.sigma3_mpa.to_string(),
                t.sigma1_peak_mpa.to_string(),
                opt(t.strain_peak),
                opt(t.sigma1_residual_mpa),
                opt(t.volumetric_strain_final),
                opt(pa),
                opt(pw),
                opt(na),
                opt(nw),
                opt(t.coulomb_band_angle_deg()),
                t.stress_drops.map_or(String::new(), |n| n.to_string()),
                opt(t.stress_drop_max_mpa),
                opt(t.overlap_max_rel),
                opt(t.kinetic_ratio_max),
                opt(t.dt_s.map(|d| d * 1e3)),
                opt(t.wall_time_s.map(|w| w / 3600.0)),
                opt(t.deep_overlap_rel),
            ];
            s.push_str(&cells.join(","));
            s.push('\n');
        }
        s
    }
}
