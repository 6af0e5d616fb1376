//! The campaign report as text (what `cdlab report` prints): the friction table, the
//! saturation fits, and the tests to look at: missing, never run (named with the grid file
//! that lists them), not quasi-static, or past the overlap bound. It is the campaign's,
//! not the analysis's, because it names the campaign's grid file.

use super::grid::{GRID_FILE, NOT_RUN, tests};
use crate::analysis::report::{OVERLAP_BOUND_REL, Report};
use crate::measure::summary::QUASI_STATIC_KINETIC_RATIO;

// An inherent method of the report, defined where the campaign's files are known, so that
// `report.table()` reads as `report.csv()` does.
impl Report {
    /// A human-readable table; "n/a" marks a figure that the points cannot define (no
    /// standard error from one pressure, no intercept error from two).
    pub fn table(&self) -> String {
        let mut s = format!(
            "{:>8} {:>6} {:>18} {:>18} {:>22} {:>8} {:>9}\n",
            "mu", "tests", "mu_macro", "mu_macro_res", "cohesion (MPa)", "dt (ms)", "wall (h)"
        );
        let mut undefined = false;
        let mut num = |x: f64| {
            if x.is_finite() {
                format!("{x:.3}")
            } else {
                undefined = true;
                "n/a".to_string()
            }
        };
        for r in &self.frictions {
            s.push_str(&format!(
                "{:>8} {:>6} {:>9} +- {:<6} {:>9} +- {:<6} {:>11} +- {:<6} {:>8} {:>9.2}\n",
                r.mu,
                r.tests,
                num(r.mu_macro),
                num(r.mu_macro_se),
                num(r.mu_macro_res),
                num(r.mu_macro_res_se),
                num(r.peak_fit_free.intercept),
                num(r.peak_fit_free.intercept_se),
                r.dt_text(),
                r.wall_time_h
            ));
        }
        s.push_str(&format!(
            "wall time of the tests: {:.2} h summed over {} tests (each on its own threads)\n",
            self.wall_time_h,
            self.frictions.iter().map(|r| r.tests).sum::<usize>()
        ));
        for (name, f) in [
            ("mu_macro", &self.mu_macro_fit),
            ("mu_macro_res", &self.mu_macro_res_fit),
        ] {
            match f {
                Some(f) => s.push_str(&format!(
                    "{name} = a - b exp(-c mu): a = {} +- {}, b = {} +- {}, c = {} +- {} (rms {})\n",
                    num(f.a),
                    num(f.se[0]),
                    num(f.b),
                    num(f.se[1]),
                    num(f.c),
                    num(f.se[2]),
                    num(f.rms)
                )),
                None => s.push_str(&format!(
                    "{name}: fewer than three frictions, no saturation fit\n"
                )),
            }
        }
        if undefined {
            s.push_str(
                "n/a: not defined by these points (a standard error needs two pressures, an \
                 intercept error three, the saturation fit's errors four frictions)\n",
            );
        }
        // The tests never run are many in a campaign under way: one line names them all.
        let (not_run, other): (Vec<_>, Vec<_>) = self.missing.iter().partition(|(_, why)| why == NOT_RUN);
        for (d, why) in other {
            s.push_str(&format!("missing: {} ({why})\n", d.display()));
        }
        if let Some((first, _)) = not_run.first() {
            let names: Vec<String> = not_run
                .iter()
                .filter_map(|(d, _)| d.file_name().map(|n| n.to_string_lossy().into_owned()))
                .collect();
            s.push_str(&format!(
                "not run: {} listed in {} and found nowhere: {}\n",
                tests(names.len()),
                first.with_file_name(GRID_FILE).display(),
                names.join(", ")
            ));
        }
        for (d, k) in &self.suspect {
            s.push_str(&format!(
                "suspect: {} (largest kinetic ratio {k:.2e} above {QUASI_STATIC_KINETIC_RATIO:e}: \
                 not quasi-static; its points are in the fits)\n",
                d.display()
            ));
        }
        for (d, o) in &self.overlapping {
            s.push_str(&format!(
                "overlap: {} (largest overlap {:.2}% of r_min, above docs/method.md's {}%; its \
                 points are in the fits)\n",
                d.display(),
                o * 100.0,
                OVERLAP_BOUND_REL * 100.0
            ));
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use std::path::PathBuf;

    use crate::analysis::report::tests::{one_pressure_point, wall_time_report};
    use crate::analysis::report::{TestPoint, analyse};

    /// The table sums the wall times over the campaign, in hours (1800 s + 5400 s + 3600 s
    /// = 3 h over four tests, one without a wall time).
    #[test]
    fn table_sums_the_wall_times_in_hours() {
        let rep = wall_time_report();
        assert!(
            rep.table().contains("3.00 h summed over 4 tests"),
            "{}",
            rep.table()
        );
    }

    /// One pressure defines mu_macro (tan phi from sin phi = q / p: here q/p = 0.5, so
    /// phi = 30 degrees and mu_macro = 0.577) but not its standard error: the table says
    /// n/a, never NaN.
    #[test]
    fn table_marks_undefined_figures_as_not_available() {
        let table = analyse(&[one_pressure_point()], Vec::new()).table();
        assert!(table.contains("0.577 +- n/a"), "{table}");
        assert!(table.contains("n/a: not defined"), "{table}");
        assert!(!table.contains("NaN"), "{table}");
        assert!(!table.contains("suspect"), "{table}");
    }

    /// A test whose kinetic ratio passed 1e-3 (the summary's quasi-static bound) is named
    /// in the report; one below it, or from a summary without the figure, is not.
    #[test]
    fn tests_that_were_not_quasi_static_are_named() {
        let point = |dir: &str, k: Option<f64>| TestPoint {
            dir: PathBuf::from(dir),
            mu: 0.3,
            sigma3_mpa: 1.0,
            sigma1_peak_mpa: 3.0,
            sigma1_residual_mpa: Some(2.0),
            kinetic_ratio_max: k,
            ..Default::default()
        };
        let rep = analyse(
            &[
                point("calm", Some(9e-4)),
                point("wild", Some(5e-3)),
                point("old", None),
            ],
            Vec::new(),
        );
        assert_eq!(rep.suspect, vec![(PathBuf::from("wild"), 5e-3)]);
        let table = rep.table();
        assert!(
            table.contains("suspect: wild (largest kinetic ratio 5.00e-3"),
            "{table}"
        );
        assert_eq!(table.matches("suspect").count(), 1, "{table}");
    }

    /// A test whose largest overlap passed 1% of r_min (docs/method.md's bound) is named, one
    /// at the bound is not; the time steps of a friction's tests are listed, several when
    /// they differ.
    #[test]
    fn tests_past_the_overlap_bound_are_named_and_time_steps_listed() {
        let point = |dir: &str, s3: f64, o: f64, dt: Option<f64>| TestPoint {
            dir: PathBuf::from(dir),
            mu: 3.0,
            sigma3_mpa: s3,
            sigma1_peak_mpa: 3.0 * s3,
            sigma1_residual_mpa: Some(2.0 * s3),
            overlap_max_rel: Some(o),
            dt_s: dt,
            ..Default::default()
        };
        let rep = analyse(
            &[
                point("low", 1.0, 0.01, Some(2.5e-4)),
                point("deep", 4.0, 0.013, Some(5e-4)),
                point("unknown", 8.0, 0.002, None),
            ],
            Vec::new(),
        );
        assert_eq!(rep.overlapping, vec![(PathBuf::from("deep"), 0.013)]);
        assert_eq!(rep.frictions[0].dt_ms, vec![0.25, 0.5]);
        let table = rep.table();
        assert!(
            table.contains("overlap: deep (largest overlap 1.30% of r_min, above docs/method.md's 1%"),
            "{table}"
        );
        assert_eq!(table.matches("overlap:").count(), 1, "{table}");
        assert!(table.lines().nth(1).unwrap().contains(" 0.25;0.5 "), "{table}");
        assert!(
            rep.csv().lines().nth(1).unwrap().ends_with(",0.25;0.5,0"),
            "{}",
            rep.csv()
        );
    }
}
