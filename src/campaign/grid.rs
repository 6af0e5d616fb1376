//! A campaign's grid file and the names of its tests: the list of the test directories a
//! campaign holds ([`GRID_FILE`]), written as the sweeps run and read back by the report to
//! name the tests never run, and the natural order of test names in which both list them.

use std::path::Path;

use crate::error::{Error, Result};

/// File, in a campaign's output directory, naming the test directories of its grid (JSON:
/// `{"tests": [...]}`): written by `cdlab sweep`, kept by `cdlab archive`, read by
/// `cdlab report` to name the tests that were never run (a shard that did not run, a sweep
/// stopped before them). It names the tests of every sweep run into the directory.
pub const GRID_FILE: &str = "campaign_grid.json";

/// The reason [`super::collect()`] gives a test of a [`GRID_FILE`] that has no record.
pub const NOT_RUN: &str = "not run: listed in campaign_grid.json, no record of it";

#[derive(serde::Serialize, serde::Deserialize)]
struct GridFile {
    tests: Vec<String>,
}

/// The test directory names listed in `dir`'s [`GRID_FILE`]; none when it has no such file.
pub fn read_grid(dir: &Path) -> Result<Vec<String>> {
    let path = dir.join(GRID_FILE);
    if !path.exists() {
        return Ok(Vec::new());
    }
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    // A damaged list is the campaign's: it names the file, which a caller may repair or
    // remove (the report then no longer names the tests never run).
    let damaged = |message: String| Error::Campaign {
        path: path.clone(),
        tests: Vec::new(),
        message,
    };
    let grid: GridFile =
        serde_json::from_str(&text).map_err(|e| damaged(format!("{}: {e}", path.display())))?;
    if let Some(bad) = grid
        .tests
        .iter()
        .find(|t| Path::new(t).file_name() != Some(t.as_ref()))
    {
        return Err(damaged(format!(
            "{}: {bad:?} is not a directory name",
            path.display()
        )));
    }
    Ok(grid.tests)
}

/// "1 test", "2 tests".
pub fn tests(n: usize) -> String {
    if n == 1 {
        "1 test".into()
    } else {
        format!("{n} tests")
    }
}

/// Adds `tests` to `dir`'s [`GRID_FILE`] (created if absent; adding none writes nothing).
/// The file is replaced in one synced rename ([`crate::fsio::write_file`]), so that a reader
/// never sees half of it. An
/// unreadable file is an error rather than overwritten: it may list tests this grid does
/// not.
pub fn add_to_grid(dir: &Path, tests: &[String]) -> Result<()> {
    if tests.is_empty() {
        return Ok(());
    }
    let mut all = read_grid(dir)?;
    all.extend(tests.iter().cloned());
    all.sort_by(|a, b| natural_order(a, b));
    all.dedup();
    let json = serde_json::to_string_pretty(&GridFile { tests: all }).expect("a list of names serializes");
    // Synced before and after the rename, like every file cdlab writes: a crash must not
    // leave a grid that forgot tests already run.
    crate::fsio::write_file(&dir.join(GRID_FILE), json.as_bytes())
}

/// Orders test names as a reader expects the grid: the numbers in them compared as numbers
/// (`mu0.5` < `mu1.2` < `mu3` < `mu12`, `s0.5MPa` < `s8MPa`), the text between as text.
/// Equal names alone compare equal.
pub fn natural_order(a: &str, b: &str) -> std::cmp::Ordering {
    /// The name as alternating runs of text and decimal numbers (digits, at most one point
    /// followed by a digit).
    fn runs(s: &str) -> Vec<(bool, &str)> {
        let bytes = s.as_bytes();
        let mut out = Vec::new();
        let mut i = 0;
        while i < bytes.len() {
            let start = i;
            let numeric = bytes[i].is_ascii_digit();
            if numeric {
                while i < bytes.len() && bytes[i].is_ascii_digit() {
                    i += 1;
                }
                if i + 1 < bytes.len() && bytes[i] == b'.' && bytes[i + 1].is_ascii_digit() {
                    i += 1;
                    while i < bytes.len() && bytes[i].is_ascii_digit() {
                        i += 1;
                    }
                }
            } else {
                while i < bytes.len() && !bytes[i].is_ascii_digit() {
                    i += 1;
                }
            }
            out.push((numeric, &s[start..i]));
        }
        out
    }
    let (ra, rb) = (runs(a), runs(b));
    for ((na, ta), (nb, tb)) in ra.iter().zip(&rb) {
        let o = match (na, nb) {
            (true, true) => {
                let (x, y): (f64, f64) = (ta.parse().unwrap_or(0.0), tb.parse().unwrap_or(0.0));
                x.total_cmp(&y)
            }
            _ => ta.cmp(tb),
        };
        if o.is_ne() {
            return o;
        }
    }
    // Same numbers written differently ("1.0" and "1") or one name a prefix of the other.
    ra.len().cmp(&rb.len()).then_with(|| a.cmp(b))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The campaign's names in the order of their frictions and pressures, which text order
    /// breaks (`mu1.2` < `mu12` < `mu1_` < `mu3` as text).
    #[test]
    fn test_names_sort_by_their_numbers() {
        let mut names = [
            "seed1_mu3_s0.5MPa",
            "seed1_mu12_s8MPa",
            "seed1_mu1_s8MPa",
            "seed1_mu1.2_s0.5MPa",
            "seed1_mu1_s0.5MPa",
            "seed1_mu0.5_s8MPa",
            "seed1_mu0.5_s1MPa",
            "seed2_mu0.5_s1MPa",
        ];
        names.sort_by(|a, b| natural_order(a, b));
        assert_eq!(
            names,
            [
                "seed1_mu0.5_s1MPa",
                "seed1_mu0.5_s8MPa",
                "seed1_mu1_s0.5MPa",
                "seed1_mu1_s8MPa",
                "seed1_mu1.2_s0.5MPa",
                "seed1_mu3_s0.5MPa",
                "seed1_mu12_s8MPa",
                "seed2_mu0.5_s1MPa",
            ]
        );
        assert!(natural_order("t1", "t1").is_eq());
        assert!(natural_order("mu1", "mu1.0").is_lt() && natural_order("a", "a1").is_lt());
    }

    /// The reason given to a test never run names the grid file by its name (a constant
    /// cannot format another, so the two are checked to agree).
    #[test]
    fn the_not_run_reason_names_the_grid_file() {
        assert!(NOT_RUN.contains(GRID_FILE), "{NOT_RUN}");
    }
}
