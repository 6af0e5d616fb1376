//! The campaign report: for each contact friction, the peak and residual points in the
//! (p, q) plane, the Mohr-Coulomb fits, the macroscopic friction, and the fit of the
//! macroscopic friction against the contact friction.

use std::path::{Path, PathBuf};

use super::fit::{Line, Saturation, saturation, through_origin, unconstrained};
use crate::error::{Error, Result};
use crate::measure::summary::QUASI_STATIC_KINETIC_RATIO;

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
    #[serde(deserialize_with = "super::fit::nan_as_null::number")]
    pub mu_macro: f64,
    /// See `mu_macro`.
    #[serde(deserialize_with = "super::fit::nan_as_null::number")]
    pub mu_macro_se: f64,
    /// `q = p sin(phi)` through the origin at the residual (NaN slope when no residual).
    pub residual_fit: Line,
    /// Residual macroscopic friction and its standard error.
    #[serde(deserialize_with = "super::fit::nan_as_null::number")]
    pub mu_macro_res: f64,
    /// See `mu_macro_res`.
    #[serde(deserialize_with = "super::fit::nan_as_null::number")]
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

/// `tan(asin(s))` and its standard error from that of `s`.
fn macro_friction(l: &Line) -> (f64, f64) {
    let s = l.slope;
    let t = s / (1.0 - s * s).sqrt();
    (t, l.slope_se / (1.0 - s * s).powf(1.5))
}

fn distinct(values: impl Iterator<Item = f64>) -> usize {
    let mut v: Vec<f64> = values.collect();
    v.sort_by(f64::total_cmp);
    v.dedup();
    v.len()
}

/// The tests' wall-clock times summed, in hours (a summary without one adds nothing).
fn wall_time_h<'a>(tests: impl IntoIterator<Item = &'a TestPoint>) -> f64 {
    // A fold from +0: an empty f64 sum is -0, which the table would print as "-0.00".
    tests
        .into_iter()
        .filter_map(|t| t.wall_time_s)
        .fold(0.0, |a, b| a + b)
        / 3600.0
}

/// File, in a campaign's output directory, naming the test directories of its grid (JSON:
/// `{"tests": [...]}`): written by `cdlab sweep`, kept by `cdlab archive`, read by
/// `cdlab report` to name the tests that were never run (a shard that did not run, a sweep
/// stopped before them). It names the tests of every sweep run into the directory.
pub const GRID_FILE: &str = "campaign_grid.json";

/// The reason [`collect`] gives a test of a [`GRID_FILE`] that has no record.
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
    let grid: GridFile =
        serde_json::from_str(&text).map_err(|e| Error::Other(format!("{}: {e}", path.display())))?;
    if let Some(bad) = grid
        .tests
        .iter()
        .find(|t| Path::new(t).file_name() != Some(t.as_ref()))
    {
        return Err(Error::Other(format!(
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

/// An error when the summary `v` (read from `path`) names another record than the
/// `run.mcap` beside it: the record was replaced by a later run (one that was stopped
/// before its summary, say) and the summary is an earlier test's. A summary or record
/// without an identity (written before they had one) and an archived test (no record)
/// pass.
fn check_record_id(dir: &Path, path: &Path, v: &serde_json::Value) -> Result<()> {
    let Some(theirs) = v.get("record_id").and_then(serde_json::Value::as_str) else {
        return Ok(());
    };
    if !dir.join(crate::record::MCAP_FILE).is_file() {
        return Ok(());
    }
    match crate::record::read_run_id(dir) {
        Ok(Some(ours)) if ours != theirs => Err(Error::Other(format!(
            "{} belongs to another record (record_id {theirs}) than the run.mcap beside it \
             (run_id {ours}): a stale summary of an earlier run, not counted (`cdlab \
             summarize {}` writes it again from the record once that run is complete)",
            path.display(),
            dir.display()
        ))),
        _ => Ok(()),
    }
}

fn read_point(dir: &Path, path: &Path) -> Result<TestPoint> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    // Only the four figures the analysis needs are read, so a summary with other fields
    // null (NaN has no JSON form) or from another version still counts.
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| Error::Other(format!("{}: {e}", path.display())))?;
    check_record_id(dir, path, &v)?;
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
        _ => Err(Error::Other(format!(
            "{}: not a cdlab test summary (needs mu, sigma3_mpa, sigma1_peak_mpa)",
            path.display()
        ))),
    }
}

/// Analyses the tests (grouped by contact friction).
pub fn analyse(points: &[TestPoint], missing: Vec<(PathBuf, String)>) -> Report {
    let mut frictions = Vec::new();
    let mut i = 0;
    while i < points.len() {
        let mu = points[i].mu;
        let group: Vec<&TestPoint> = points[i..].iter().take_while(|p| p.mu == mu).collect();
        i += group.len();
        let pq = |s1: f64, s3: f64| [(s1 + s3) / 2.0, (s1 - s3) / 2.0];
        let peak: Vec<[f64; 2]> = group
            .iter()
            .map(|t| pq(t.sigma1_peak_mpa, t.sigma3_mpa))
            .collect();
        let res: Vec<[f64; 2]> = group
            .iter()
            .filter_map(|t| t.sigma1_residual_mpa.map(|s1| pq(s1, t.sigma3_mpa)))
            .collect();
        let split = |v: &[[f64; 2]]| -> (Vec<f64>, Vec<f64>) { v.iter().map(|a| (a[0], a[1])).unzip() };
        let (px, py) = split(&peak);
        let (rx, ry) = split(&res);
        let peak_fit = through_origin(&px, &py);
        let residual_fit = through_origin(&rx, &ry);
        let (m, m_se) = macro_friction(&peak_fit);
        let (mr, mr_se) = macro_friction(&residual_fit);
        frictions.push(FrictionRow {
            mu,
            tests: group.len(),
            peak_pq_mpa: peak,
            residual_pq_mpa: res,
            peak_fit,
            // One confining stress puts every point on q = p - sigma3: the free line then
            // says nothing about cohesion.
            peak_fit_free: if distinct(group.iter().map(|t| t.sigma3_mpa)) >= 2 {
                unconstrained(&px, &py)
            } else {
                Line {
                    slope: f64::NAN,
                    slope_se: f64::NAN,
                    intercept: f64::NAN,
                    intercept_se: f64::NAN,
                    n: px.len(),
                }
            },
            mu_macro: m,
            mu_macro_se: m_se,
            residual_fit,
            mu_macro_res: mr,
            mu_macro_res_se: mr_se,
            dt_ms: {
                let mut v: Vec<f64> = group.iter().filter_map(|t| t.dt_s.map(|d| d * 1e3)).collect();
                v.sort_by(f64::total_cmp);
                v.dedup();
                v
            },
            wall_time_h: wall_time_h(group.iter().copied()),
        });
    }
    let fit_of = |f: &dyn Fn(&FrictionRow) -> f64| {
        let (x, y): (Vec<f64>, Vec<f64>) = frictions
            .iter()
            .filter(|r| f(r).is_finite())
            .map(|r| (r.mu, f(r)))
            .unzip();
        saturation(&x, &y)
    };
    let above = |figure: fn(&TestPoint) -> Option<f64>, bound: f64| {
        points
            .iter()
            .filter_map(|t| {
                let k = figure(t)?;
                (k > bound).then(|| (t.dir.clone(), k))
            })
            .collect()
    };
    let suspect = above(|t| t.kinetic_ratio_max, QUASI_STATIC_KINETIC_RATIO);
    let overlapping = above(|t| t.overlap_max_rel, OVERLAP_BOUND_REL);
    Report {
        wall_time_h: wall_time_h(points),
        mu_macro_fit: fit_of(&|r| r.mu_macro),
        mu_macro_res_fit: fit_of(&|r| r.mu_macro_res),
        frictions,
        missing,
        suspect,
        overlapping,
        tests: points.to_vec(),
    }
}

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
                Self::dt_text(r),
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

    /// The time steps of a friction's tests for the CSV and the table (ms, `;` between
    /// several), "n/a" when no summary recorded one.
    fn dt_text(r: &FrictionRow) -> String {
        if r.dt_ms.is_empty() {
            "n/a".into()
        } else {
            r.dt_ms
                .iter()
                .map(|d| d.to_string())
                .collect::<Vec<_>>()
                .join(";")
        }
    }

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
                Self::dt_text(r),
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
    use super::*;

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

    /// A friction tested at one pressure only: q/p = 0.5.
    fn one_pressure_point() -> TestPoint {
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

    /// The wall times of the tests are summed per friction and over the campaign, in
    /// hours (1800 s + 5400 s = 2 h at friction 0.3; 3600 s more at friction 0.5 makes 3 h);
    /// a summary without one adds nothing.
    #[test]
    fn wall_times_are_summed_in_hours() {
        let at = |mu: f64, s3: f64, wall: Option<f64>| TestPoint {
            mu,
            sigma3_mpa: s3,
            wall_time_s: wall,
            ..one_pressure_point()
        };
        let rep = analyse(
            &[
                at(0.3, 1.0, Some(1800.0)),
                at(0.3, 2.0, Some(5400.0)),
                at(0.5, 1.0, Some(3600.0)),
                at(0.5, 2.0, None),
            ],
            Vec::new(),
        );
        assert_eq!(rep.frictions[0].wall_time_h, 2.0);
        assert_eq!(rep.frictions[1].wall_time_h, 1.0);
        assert_eq!(rep.wall_time_h, 3.0);
        assert!(
            rep.table().contains("3.00 h summed over 4 tests"),
            "{}",
            rep.table()
        );
        assert!(rep.csv().lines().nth(1).unwrap().ends_with(",2"), "{}", rep.csv());
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
