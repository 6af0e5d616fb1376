//! The campaign report on synthetic test summaries with known Mohr-Coulomb parameters.

use std::path::PathBuf;

use cdlab::analysis::report::analyse;
use cdlab::campaign::collect;
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

/// The 5000-disk campaign's report shipped beside its archive
/// (`assets/results/campaign5000_report.json`, docs/results.md) is what `cdlab
/// report` makes of that archive now: a stale copy, or an archive changed without its
/// report, fails here. Its fits are those of docs/results.md: plateaus 0.491 at the peak and 0.291 at
/// the residual.
#[test]
fn shipped_5000_disk_report_is_the_report_of_the_shipped_archive() {
    let results = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/results");
    let shipped: cdlab::analysis::report::Report =
        serde_json::from_str(&std::fs::read_to_string(results.join("campaign5000_report.json")).unwrap())
            .unwrap();
    let (points, missing) = cdlab::campaign::collect(&[results.join("campaign5000")]);
    let now = cdlab::analysis::report::analyse(&points, missing);
    // The paper's grid, whole: 13 frictions of 5 pressures, nothing missing.
    assert_eq!(shipped.tests.len(), 65);
    assert!(shipped.frictions.len() == 13 && shipped.frictions.iter().all(|r| r.tests == 5));
    assert!(
        shipped.missing.is_empty() && now.missing.is_empty(),
        "{:?}",
        now.missing
    );
    assert_eq!(now.frictions.len(), shipped.frictions.len());
    for (n, s) in now.frictions.iter().zip(&shipped.frictions) {
        assert_eq!(n.mu, s.mu);
        assert_eq!(n.tests, s.tests, "friction {}", s.mu);
        for (x, y) in [
            (n.mu_macro, s.mu_macro),
            (n.mu_macro_res, s.mu_macro_res),
            (n.wall_time_h, s.wall_time_h),
        ] {
            assert!(
                (x - y).abs() <= 1e-12 * y.abs().max(1.0),
                "friction {}: {x} from the archive, {y} shipped; regenerate with `cdlab report \
                 assets/results/campaign5000 --out DIR` and copy its report.json, report.csv \
                 and tests.csv to assets/results/campaign5000_*",
                s.mu
            );
        }
    }
    let (fit, fit_res) = (now.mu_macro_fit.unwrap(), now.mu_macro_res_fit.unwrap());
    let shipped_fit = shipped.mu_macro_fit.unwrap();
    assert!((fit.a - shipped_fit.a).abs() < 1e-9 && (fit.c - shipped_fit.c).abs() < 1e-6);
    // docs/results.md: mu_macro = 0.491 - 0.367 exp(-6.0 mu), mu_macro_res = 0.291 - 0.217 exp(-9.7 mu).
    assert!(
        (fit.a - 0.491).abs() < 5e-4 && (fit.b - 0.367).abs() < 5e-4,
        "{fit:?}"
    );
    assert!(
        (fit_res.a - 0.291).abs() < 5e-4 && (fit_res.c - 9.7).abs() < 0.05,
        "{fit_res:?}"
    );
}

/// The 5000-disk table (contact friction, mu_macro, mu_macro_res with their standard
/// errors) of the README and of docs/results.md prints the shipped report's values to three
/// decimals, row for row, in both.
#[test]
fn readme_5000_disk_table_is_the_shipped_report() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let shipped: cdlab::analysis::report::Report = serde_json::from_str(
        &std::fs::read_to_string(root.join("assets/results/campaign5000_report.json")).unwrap(),
    )
    .unwrap();
    for file in ["README.md", "docs/results.md"] {
        let text = std::fs::read_to_string(root.join(file)).unwrap();
        let head = "| contact friction | mu_macro, 5000 disks | mu_macro_res, 5000 disks |";
        let start = text
            .find(head)
            .unwrap_or_else(|| panic!("{file}: no 5000-disk table (a row starting {head:?})"));
        let rows: Vec<Vec<&str>> = text[start..]
            .lines()
            .skip(2)
            .take_while(|l| l.starts_with('|'))
            .map(|l| l.split('|').map(str::trim).collect())
            .collect();
        assert_eq!(rows.len(), shipped.frictions.len(), "{file}");
        for (cells, f) in rows.iter().zip(&shipped.frictions) {
            let mu: f64 = cells[1].split_whitespace().next().unwrap().parse().unwrap();
            assert_eq!(mu, f.mu, "{file}");
            assert_eq!(
                cells[2],
                format!("{:.3} ± {:.3}", f.mu_macro, f.mu_macro_se),
                "{file}, friction {}",
                f.mu
            );
            assert_eq!(
                cells[3],
                format!("{:.3} ± {:.3}", f.mu_macro_res, f.mu_macro_res_se),
                "{file}, friction {}",
                f.mu
            );
        }
    }
}

/// The 1000-disk campaign's report shipped in `assets/results/` (docs/results.md, "The
/// 1000-disk campaign") reads back as a report of the current format, with the paper's 13 frictions
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
    // The plateau of docs/results.md: 0.474 at the peak.
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
