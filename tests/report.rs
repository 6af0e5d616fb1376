//! The campaign report on synthetic test summaries with known Mohr-Coulomb parameters.

use std::path::PathBuf;

use cdlab::analysis::report::{analyse, collect};
use cdlab::measure::summary::Summary;

/// Writes a summary whose peak obeys sin(phi) = s and residual sin(phi_r) = sr.
fn write(dir: &PathBuf, mu: f64, sigma3: f64, s: f64, sr: f64) {
    std::fs::create_dir_all(dir).unwrap();
    // (s1 - s3) / (s1 + s3) = s  =>  s1 = s3 (1 + s) / (1 - s)
    let s1 = sigma3 * (1.0 + s) / (1.0 - s);
    let s1r = sigma3 * (1.0 + sr) / (1.0 - sr);
    let mut sum = Summary::new(&[], &[], sigma3 * 1e6, mu, 100, "synthetic".into(), 1.0);
    sum.sigma1_peak_mpa = s1;
    sum.sigma1_residual_mpa = Some(s1r);
    std::fs::write(dir.join("summary.json"), serde_json::to_string(&sum).unwrap()).unwrap();
}

#[test]
fn report_recovers_the_macroscopic_friction_and_its_saturation() {
    let base = std::env::temp_dir().join(format!("cdlab-report-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&base);
    // mu_macro = 0.9 - 0.7 exp(-3 mu) at the peak, 0.6 - 0.4 exp(-2 mu) at the residual.
    let mus: [f64; 5] = [0.1, 0.3, 0.6, 1.0, 3.0];
    for &mu in &mus {
        let (m, mr) = (0.9 - 0.7 * (-3.0 * mu).exp(), 0.6 - 0.4 * (-2.0 * mu).exp());
        for sigma3 in [0.5, 2.0, 8.0] {
            let dir = base.join(format!("mu{mu}_s{sigma3}"));
            write(&dir, mu, sigma3, m.atan().sin(), mr.atan().sin());
        }
    }
    // A half-finished run is reported missing, not fatal.
    std::fs::create_dir_all(base.join("broken")).unwrap();
    std::fs::write(base.join("broken/run.mcap"), b"x").unwrap();
    let (points, missing) = collect(std::slice::from_ref(&base));
    assert_eq!(points.len(), 15);
    assert_eq!(missing.len(), 1);
    let rep = analyse(&points, missing);
    for (row, &mu) in rep.frictions.iter().zip(&mus) {
        let expected = 0.9 - 0.7 * (-3.0 * mu).exp();
        assert!(
            (row.mu_macro - expected).abs() < 1e-9,
            "mu {mu}: {} vs {expected}",
            row.mu_macro
        );
        // Exact Mohr-Coulomb data through the origin: the free line's cohesion is 0.
        assert!(
            row.peak_fit_free.intercept.abs() < 1e-9,
            "cohesion {}",
            row.peak_fit_free.intercept
        );
    }
    let f = rep.mu_macro_fit.expect("saturation fit");
    assert!(
        (f.a - 0.9).abs() < 1e-5 && (f.b - 0.7).abs() < 1e-5 && (f.c - 3.0).abs() < 1e-3,
        "{f:?}"
    );
    let fr = rep.mu_macro_res_fit.expect("residual fit");
    assert!((fr.a - 0.6).abs() < 1e-5 && (fr.c - 2.0).abs() < 1e-3, "{fr:?}");
    assert!(rep.csv().lines().count() == 6);
    let _ = std::fs::remove_dir_all(&base);
}

/// The 1000-disk campaign's report shipped in `assets/results/` (README, "Measured
/// results") reads back as a report of the current format, with the paper's 13 frictions
/// of 5 pressures each and both saturation fits.
#[test]
fn shipped_campaign_report_reads_back() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/results/campaign1000_report.json");
    let rep: cdlab::analysis::report::Report =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    assert_eq!(rep.frictions.len(), 13);
    assert!(rep.frictions.iter().all(|r| r.tests == 5 && !r.dt_ms.is_empty()));
    let fit = rep.mu_macro_fit.expect("peak saturation fit");
    // The README's plateau: 0.474 at the peak.
    assert!((fit.a - 0.474).abs() < 5e-4, "{}", fit.a);
    assert!(rep.mu_macro_res_fit.is_some());
    // The campaign file's time steps: 0.25 ms from friction 3, 0.125 ms at 12.
    assert_eq!(rep.frictions[12].dt_ms, vec![0.125]);
    // Its tests' wall times, summed over the frictions, make the campaign's total.
    let sum: f64 = rep.frictions.iter().map(|r| r.wall_time_h).sum();
    assert!(
        rep.wall_time_h > 0.0 && (sum - rep.wall_time_h).abs() < 1e-9,
        "{sum} h"
    );
}
