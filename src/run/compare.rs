//! Several runs' curves on common axes (`cdlab compare`): the stress ratio and the
//! volumetric strain against axial strain, each run labelled by what sets it apart from
//! the others. Runs may be archived tests (drawn from their thinned series), so a
//! campaign's archive compares without its records.

use std::path::{Path, PathBuf};

use crate::config::Config;
use crate::error::{Error, Result};
use crate::figures::{self, CompareFigure, Format};
use crate::record::{SeriesRow, read_series};

/// One run to draw: its configuration, where it is, its rows.
struct Run {
    config: Config,
    dir: PathBuf,
    rows: Vec<SeriesRow>,
}

/// The settings a label or the title names, as their text for a run: friction, confining
/// stress, size, time step.
fn parts(c: &Config) -> [String; 4] {
    [
        format!("μ = {}", c.test.mu),
        format!("σ₃ = {} MPa", c.test.sigma3.0 / 1e6),
        format!("{} disks", c.sample.disks),
        format!("dt = {} ms", c.solver.dt.si() * 1e3),
    ]
}

/// The shortest tail of `dir`'s path (its name, then its parent's name and its name, ...)
/// that none of `others` shares, so that twin runs in directories of the same name
/// (`a/biaxial`, `b/biaxial`) get different labels; the whole path when no tail differs.
fn distinct_name(dir: &Path, others: &[&Path]) -> String {
    let parts = |p: &Path| -> Vec<String> {
        p.components()
            .map(|c| c.as_os_str().to_string_lossy().into_owned())
            .collect()
    };
    let tail = |v: &[String], n: usize| v[v.len().saturating_sub(n)..].join("/");
    let mine = parts(dir);
    let theirs: Vec<Vec<String>> = others.iter().map(|p| parts(p)).collect();
    for n in 1..=mine.len() {
        let t = tail(&mine, n);
        if theirs.iter().all(|o| tail(o, n) != t) {
            return t;
        }
    }
    dir.display().to_string()
}

/// Legend labels naming what differs between the runs (the directory's name where that
/// leaves two alike), and a title naming what they share.
fn labels_and_title(runs: &[Run]) -> (Vec<String>, String) {
    let all: Vec<[String; 4]> = runs.iter().map(|r| parts(&r.config)).collect();
    let differs: Vec<bool> = (0..4).map(|k| all.iter().any(|p| p[k] != all[0][k])).collect();
    let mut labels: Vec<String> = all
        .iter()
        .map(|p| {
            (0..4)
                .filter(|&k| differs[k])
                .map(|k| p[k].as_str())
                .collect::<Vec<_>>()
                .join(", ")
        })
        .collect();
    // Twins are found among the labels as first made, before any is renamed.
    let first = labels.clone();
    for (k, label) in labels.iter_mut().enumerate() {
        let twins: Vec<&Path> = (0..runs.len())
            .filter(|&j| j != k && first[j] == first[k])
            .map(|j| runs[j].dir.as_path())
            .collect();
        if !twins.is_empty() || label.is_empty() {
            let name = distinct_name(&runs[k].dir, &twins);
            *label = if label.is_empty() {
                name
            } else {
                format!("{label} ({name})")
            };
        }
    }
    let mut shared: Vec<String> = (0..4)
        .filter(|&k| !differs[k])
        .map(|k| all[0][k].clone())
        .collect();
    shared.push(format!("{} runs", runs.len()));
    (labels, shared.join(", "))
}

/// Draws the runs (run directories or archived tests) into the figure `out` (.png or
/// .svg), in order of contact friction, then confining stress, then directory; `title`
/// replaces the one naming what the runs share (e.g. "σ₃ = 8 MPa, 5000 disks, 13 runs").
/// Returns the number of runs drawn. The output's format is checked before any run is
/// read; a figure error names `compare`.
pub fn write_comparison(dirs: &[PathBuf], title: Option<&str>, out: &Path) -> Result<usize> {
    Format::from_path(out)?;
    let mut runs = Vec::with_capacity(dirs.len());
    for dir in dirs {
        let (rows, config) = read_series(dir)?;
        runs.push(Run {
            config: config?,
            dir: dir.clone(),
            rows,
        });
    }
    runs.sort_by(|a, b| {
        let (ta, tb) = (&a.config.test, &b.config.test);
        ta.mu
            .total_cmp(&tb.mu)
            .then(ta.sigma3.0.total_cmp(&tb.sigma3.0))
            .then_with(|| a.dir.cmp(&b.dir))
    });
    let (labels, shared) = labels_and_title(&runs);
    let fig = CompareFigure {
        runs: labels
            .into_iter()
            .zip(runs.iter().map(|r| r.rows.as_slice()))
            .collect(),
        title: title.map_or(shared, str::to_string),
    };
    figures::save(&fig, out).map_err(|e| match e {
        Error::Other(m) => Error::Other(format!("compare: {m}")),
        Error::NothingToDraw(m) => Error::NothingToDraw(format!("compare: {m}")),
        Error::Drawing(m) => Error::Drawing(format!("compare: {m}")),
        e => e,
    })?;
    Ok(runs.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(mu: f64, sigma3_mpa: f64, dir: &str) -> Run {
        let mut config = Config::default();
        config.test.mu = mu;
        config.test.sigma3.0 = sigma3_mpa * 1e6;
        Run {
            config,
            dir: dir.into(),
            rows: Vec::new(),
        }
    }

    /// Labels name what differs, the title what is shared; two runs alike in every named
    /// setting are told apart by their directories.
    #[test]
    fn labels_name_what_differs_and_the_title_what_is_shared() {
        let runs = [run(0.3, 8.0, "a"), run(3.0, 8.0, "b")];
        let (labels, title) = labels_and_title(&runs);
        assert_eq!(labels, ["μ = 0.3", "μ = 3"]);
        let d = Config::default();
        assert_eq!(
            title,
            format!(
                "σ₃ = 8 MPa, {} disks, dt = {} ms, 2 runs",
                d.sample.disks,
                d.solver.dt.si() * 1e3
            )
        );
        let runs = [
            run(0.3, 8.0, "x/seed1"),
            run(0.3, 8.0, "x/seed2"),
            run(0.3, 4.0, "y"),
        ];
        let (labels, _) = labels_and_title(&runs);
        assert_eq!(labels, ["σ₃ = 8 MPa (seed1)", "σ₃ = 8 MPa (seed2)", "σ₃ = 4 MPa"]);
        // Alike in everything the labels name, in directories of the same name: the
        // parents tell them apart (issue 36, item 18: two runs labelled alike).
        let runs = [
            run(0.3, 8.0, "a/biaxial"),
            run(0.3, 8.0, "b/biaxial"),
            run(0.3, 8.0, "c"),
        ];
        let (labels, _) = labels_and_title(&runs);
        assert_eq!(labels, ["a/biaxial", "b/biaxial", "c"]);
        let runs = [
            run(0.3, 8.0, "x/a/run"),
            run(0.3, 8.0, "y/a/run"),
            run(0.3, 4.0, "z"),
        ];
        let (labels, _) = labels_and_title(&runs);
        assert_eq!(
            labels,
            ["σ₃ = 8 MPa (x/a/run)", "σ₃ = 8 MPa (y/a/run)", "σ₃ = 4 MPa"]
        );
        let (labels, title) = labels_and_title(&[run(1.0, 1.0, "p/only")]);
        assert_eq!(labels, ["only"]);
        assert!(
            title.starts_with("μ = 1, σ₃ = 1 MPa") && title.ends_with("1 runs"),
            "{title}"
        );
    }
}
