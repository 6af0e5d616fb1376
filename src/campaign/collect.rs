//! A campaign read back: the finished tests below a set of directories, as the report's
//! points, with the tests that are unfinished, unreadable, or listed in a grid file and
//! run nowhere.

use std::path::{Path, PathBuf};

use super::grid::{GRID_FILE, NOT_RUN, natural_order, read_grid};
use crate::analysis::report::TestPoint;
use crate::error::{Error, Result, RunFault};

/// Finds every `summary.json` below `roots` (a run directory or a directory of runs). The
/// second list holds the runs that are not finished, and the tests a [`GRID_FILE`] lists
/// that have no directory below any root, each with the reason.
pub fn collect(roots: &[PathBuf]) -> (Vec<TestPoint>, Vec<(PathBuf, String)>) {
    let mut found = Vec::new();
    let mut missing = Vec::new();
    // Every directory named in a grid file, where the file is, and the test directories
    // seen, by name: a sharded campaign's tests are spread over several roots.
    let mut listed: Vec<(PathBuf, String)> = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    // Walked in the roots' order (a stack: the first root on top).
    let mut stack: Vec<PathBuf> = roots.iter().rev().cloned().collect();
    while let Some(dir) = stack.pop() {
        match read_grid(&dir) {
            Ok(names) => listed.extend(names.into_iter().map(|n| (dir.clone(), n))),
            Err(e) => missing.push((dir.join(GRID_FILE), e.to_string())),
        }
        let summary = dir.join("summary.json");
        let (finished, recorded) = (summary.exists(), dir.join("run.mcap").exists());
        if let (true, Some(name)) = (finished || recorded, dir.file_name()) {
            seen.insert(name.to_os_string());
        }
        if finished {
            match read_point(&dir, &summary) {
                Ok(p) => found.push(p),
                Err(e) => missing.push((dir.clone(), e.to_string())),
            }
            continue;
        }
        if recorded {
            missing.push((dir.clone(), "unfinished run (no summary.json)".into()));
            continue;
        }
        if let Ok(entries) = std::fs::read_dir(&dir) {
            let mut subs: Vec<PathBuf> = entries
                .flatten()
                .map(|e| e.path())
                .filter(|p| p.is_dir())
                .collect();
            subs.sort();
            stack.extend(subs.into_iter().rev());
        }
    }
    let mut named = std::collections::BTreeSet::new();
    // Grid files written before they were kept in natural order were sorted as text.
    listed.sort_by(|(_, a), (_, b)| natural_order(a, b));
    for (dir, name) in listed {
        if !seen.contains(std::ffi::OsStr::new(&name)) && named.insert(name.clone()) {
            missing.push((dir.join(&name), NOT_RUN.to_string()));
        }
    }
    found.sort_by(|a, b| {
        (a.mu, a.sigma3_mpa)
            .partial_cmp(&(b.mu, b.sigma3_mpa))
            .expect("finite")
    });
    (found, missing)
}

fn read_point(dir: &Path, path: &Path) -> Result<TestPoint> {
    // Only the four figures the analysis needs are read, so a summary with other fields
    // null (NaN has no JSON form) or from another version still counts. It is checked as
    // the sweep checks it: its checksum, and that it names the record beside it.
    let damaged = |message: String| Error::Run {
        path: path.to_path_buf(),
        fault: RunFault::Damaged,
        message,
        remedy: None,
    };
    let v = crate::run::read_checked_summary(dir)?;
    let num = |k: &str| v.get(k).and_then(serde_json::Value::as_f64);
    // Events counted from row to row follow the time step: not comparable, left out.
    let binned = num("stress_drop_bin_strain").and_then(|_| v.get("stress_drops")?.as_array());
    match (num("mu"), num("sigma3_mpa"), num("sigma1_peak_mpa")) {
        (Some(mu), Some(s3), Some(s1)) if mu >= 0.0 && s3 > 0.0 && s1.is_finite() => Ok(TestPoint {
            dir: dir.to_path_buf(),
            mu,
            sigma3_mpa: s3,
            sigma1_peak_mpa: s1,
            sigma1_residual_mpa: num("sigma1_residual_mpa"),
            kinetic_ratio_max: num("kinetic_ratio_max"),
            overlap_max_rel: num("overlap_max_rel"),
            // Summaries written before the time step was in them: the record has it.
            dt_s: num("dt_s").or_else(|| crate::record::read_config(dir).ok().map(|c| c.solver.dt.si())),
            wall_time_s: num("wall_time_s"),
            strain_peak: num("strain_peak"),
            volumetric_strain_final: num("volumetric_strain_final"),
            bands: v.get("shear_bands").and_then(|b| b.get("bands")).and_then(|b| {
                b.as_array()?
                    .iter()
                    .map(|band| {
                        Some([
                            band.get("angle_deg")?.as_f64()?,
                            band.get("width_diameters")?.as_f64()?,
                        ])
                    })
                    .collect()
            }),
            stress_drops: binned.map(|d| d.len()),
            deep_overlap_rel: v
                .get("deep_contacts")
                .and_then(|d| d.get("overlap_rel"))
                .and_then(serde_json::Value::as_f64),
            stress_drop_max_mpa: binned.and_then(|d| {
                d.iter()
                    .filter_map(|e| e.get("drop_pa")?.as_f64())
                    .reduce(f64::max)
                    .map(|p| p / 1e6)
            }),
        }),
        _ => Err(damaged(format!(
            "{}: not a cdlab test summary (needs mu, sigma3_mpa, sigma1_peak_mpa)",
            path.display()
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::analysis::report::analyse;
    use crate::campaign::grid::add_to_grid;

    /// A summary's bands, stress drops and dilatancy reach the per-test table: the band
    /// rising towards +x in the `band_pos` columns whatever its place in the list, Coulomb's
    /// angle at the residual beside them (s1 = 3 s3: sin(phi) = 1/2, phi = 30 deg, so
    /// 45 - 15 = 30 deg), the events counted and the largest in MPa. Events listed from row
    /// to row (no bin in the summary) are left out rather than counted. The threshold of
    /// local updates of deep contacts is there for the test that used them only.
    #[test]
    fn the_per_test_table_holds_bands_and_stress_drops() {
        let base = std::env::temp_dir().join(format!("cdlab-tests-csv-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        let summary = |dir: &str, bin: bool| {
            let d = base.join(dir);
            std::fs::create_dir_all(&d).unwrap();
            let mut v = serde_json::json!({
                "mu": 0.3, "sigma3_mpa": 1.0, "sigma1_peak_mpa": 3.5, "sigma1_residual_mpa": 3.0,
                "strain_peak": 0.012, "volumetric_strain_final": 0.02,
                "stress_drops": [{"drop_pa": 2e5}, {"drop_pa": 7e5}],
                "shear_bands": {"bands": [
                    {"angle_deg": -38.0, "width_diameters": 6.5},
                    {"angle_deg": 41.0, "width_diameters": 9.0}
                ]}
            });
            if bin {
                v["stress_drop_bin_strain"] = serde_json::json!(1e-4);
                v["deep_contacts"] =
                    serde_json::json!({"overlap_rel": 0.005, "sweeps": 5, "per_step_compression": 2.2});
            }
            std::fs::write(d.join("summary.json"), v.to_string()).unwrap();
        };
        summary("binned", true);
        summary("by_rows", false);
        let (points, missing) = collect(std::slice::from_ref(&base));
        assert!(missing.is_empty(), "{missing:?}");
        let report = analyse(&points, missing);
        let csv = report.tests_csv();
        let rows: Vec<Vec<&str>> = csv.lines().map(|l| l.split(',').collect()).collect();
        let col = |name: &str| rows[0].iter().position(|h| *h == name).unwrap();
        assert_eq!(rows.len(), 3, "{csv}");
        let binned = rows.iter().find(|r| r[0].contains("binned")).unwrap();
        let by_rows = rows.iter().find(|r| r[0].contains("by_rows")).unwrap();
        assert_eq!(binned[col("band_pos_angle_deg")], "41");
        assert_eq!(binned[col("band_pos_width_diameters")], "9");
        assert_eq!(binned[col("band_neg_angle_deg")], "-38");
        let coulomb: f64 = binned[col("coulomb_band_angle_deg")].parse().unwrap();
        assert!((coulomb - 30.0).abs() < 1e-9, "{coulomb}");
        assert_eq!(binned[col("stress_drops")], "2");
        assert_eq!(binned[col("stress_drop_max_mpa")], "0.7");
        assert_eq!(binned[col("volumetric_strain_final")], "0.02");
        assert_eq!(by_rows[col("stress_drops")], "");
        assert_eq!(by_rows[col("stress_drop_max_mpa")], "");
        assert_eq!(by_rows[col("band_neg_width_diameters")], "6.5");
        assert_eq!(binned[col("deep_overlap_rel")], "0.005");
        assert_eq!(by_rows[col("deep_overlap_rel")], "");
        let _ = std::fs::remove_dir_all(&base);
    }

    /// The tests a grid file lists are looked for below every root (a sharded campaign's
    /// tests spread over several): a listed test without a record anywhere is named once as
    /// not run, one found in another root is not; a damaged grid file is named, not skipped.
    #[test]
    fn tests_listed_in_a_grid_file_but_run_nowhere_are_named_as_not_run() {
        let base = std::env::temp_dir().join(format!("cdlab-grid-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&base);
        let (a, b) = (base.join("shard0"), base.join("shard1"));
        for dir in [a.join("t1"), b.join("t2")] {
            std::fs::create_dir_all(&dir).unwrap();
            // An unfinished run: a record, no summary.
            std::fs::write(dir.join("run.mcap"), b"").unwrap();
        }
        // Both shards list the whole grid; an empty directory is not a run.
        std::fs::create_dir_all(a.join("t4")).unwrap();
        let grid: Vec<String> = ["t1", "t2", "t3", "t4"].map(String::from).to_vec();
        add_to_grid(&a, &grid[..2]).unwrap();
        add_to_grid(&a, &grid).unwrap();
        add_to_grid(&b, &grid[2..]).unwrap();
        assert_eq!(
            read_grid(&a).unwrap(),
            grid,
            "the union, sorted, without duplicates"
        );
        let (found, missing) = collect(&[a.clone(), b.clone()]);
        assert!(found.is_empty());
        let not_run: Vec<&PathBuf> = missing
            .iter()
            .filter(|(_, why)| why.starts_with("not run"))
            .map(|(d, _)| d)
            .collect();
        assert_eq!(not_run, [&a.join("t3"), &a.join("t4")], "{missing:?}");
        assert_eq!(
            missing.len(),
            4,
            "t1 and t2 unfinished, t3 and t4 not run: {missing:?}"
        );

        std::fs::write(b.join(GRID_FILE), "{\"tests\": [\"../t5\"]}").unwrap();
        assert!(
            read_grid(&b)
                .unwrap_err()
                .to_string()
                .contains("not a directory name")
        );
        std::fs::write(b.join(GRID_FILE), "{\"tests\": [").unwrap();
        // Not overwritten: it may list tests the new grid does not.
        assert!(add_to_grid(&b, &grid).is_err());
        let (_, missing) = collect(std::slice::from_ref(&b));
        assert!(
            missing.iter().any(|(d, _)| d == &b.join(GRID_FILE)),
            "{missing:?}"
        );
        let _ = std::fs::remove_dir_all(&base);
    }
}
