//! The sweep file and the grid of tests it describes.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::config::units::{Dimension, parse_with_unit};
use crate::config::{Config, Duration, Pressure};
use crate::error::{Error, Result, RunFault};

/// The sweep file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(crate) struct SweepFile {
    /// Base configuration file, relative to the sweep file (default: the built-in one).
    base: Option<PathBuf>,
    /// Campaign directory.
    out: PathBuf,
    /// Contact frictions (default: the paper's 13).
    #[serde(default = "paper_mu")]
    mu: Vec<f64>,
    /// Confining stresses with units (default: the paper's 0.5, 1, 2, 4, 8 MPa).
    #[serde(default = "paper_sigma3")]
    sigma3: Vec<toml::Value>,
    /// Sample seeds (one compacted sample each; default [1]).
    #[serde(default = "one_seed")]
    seeds: Vec<u64>,
    /// Time steps by contact friction: a test runs at the `dt` of the entry with the
    /// largest `mu_from` at or below its friction, else at the base configuration's.
    #[serde(default)]
    dt_by_friction: Vec<FrictionDt>,
}

/// One `[[dt_by_friction]]` entry of a sweep file.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FrictionDt {
    /// Lowest contact friction that runs at `dt`.
    mu_from: f64,
    /// The time step.
    dt: Duration,
}

impl SweepFile {
    /// The time step of a test at contact friction `mu` (s), `base` where no entry applies.
    fn dt(&self, mu: f64, base: f64) -> f64 {
        self.dt_by_friction
            .iter()
            .filter(|e| e.mu_from <= mu)
            .max_by(|a, b| a.mu_from.total_cmp(&b.mu_from))
            .map_or(base, |e| e.dt.si())
    }

    /// Refuses entries that cannot mean anything (the time step itself is checked with the
    /// rest of each test's configuration).
    fn check_dt_entries(&self, file: &Path) -> Result<()> {
        for (k, e) in self.dt_by_friction.iter().enumerate() {
            if !(e.mu_from.is_finite() && e.mu_from >= 0.0) {
                return Err(Error::invalid(
                    "dt_by_friction.mu_from",
                    e.mu_from,
                    "a friction >= 0",
                ));
            }
            if self.dt_by_friction[..k].iter().any(|o| o.mu_from == e.mu_from) {
                return Err(campaign_error(
                    file,
                    format!("two dt_by_friction entries start at friction {}", e.mu_from),
                ));
            }
        }
        Ok(())
    }
}

fn paper_mu() -> Vec<f64> {
    vec![0.01, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.2, 3.0, 6.0, 12.0]
}
fn paper_sigma3() -> Vec<toml::Value> {
    ["0.5 MPa", "1 MPa", "2 MPa", "4 MPa", "8 MPa"]
        .iter()
        .map(|s| toml::Value::String(s.to_string()))
        .collect()
}
fn one_seed() -> Vec<u64> {
    vec![1]
}

/// One test of the grid.
#[derive(Clone, Debug)]
pub struct Point {
    /// Contact friction.
    pub mu: f64,
    /// Confining stress (Pa).
    pub sigma3: f64,
    /// Sample seed.
    pub seed: u64,
    /// Time step (s).
    pub dt: f64,
    /// The test's directory.
    pub dir: PathBuf,
}

/// A campaign read from its sweep file: the base configuration, the output directory and
/// every test of the grid, each test's configuration checked.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// The sweep file.
    pub file: PathBuf,
    /// The base configuration (the sweep file's `base`, or the built-in default).
    pub base: Config,
    /// The campaign directory.
    pub out: PathBuf,
    /// The tests, seed by seed, friction by friction, pressure by pressure.
    pub grid: Vec<Point>,
}

/// An [`Error::Campaign`] about the sweep file `file`.
fn campaign_error(file: &Path, message: impl std::fmt::Display) -> Error {
    Error::Campaign {
        path: file.to_path_buf(),
        tests: Vec::new(),
        message: format!("{}: {message}", file.display()),
    }
}

impl Sweep {
    /// Reads and checks a sweep file: its pressures with their units, its frictions, its
    /// time steps by friction, and every test's configuration, before anything is run.
    pub fn load(file: &Path) -> Result<Sweep> {
        let text = crate::config::read_capped(file, crate::config::MAX_CONFIG_BYTES, "a sweep file")?;
        let sweep: SweepFile =
            toml::from_str(&text).map_err(|e| crate::config::toml_error(&text, &e, file))?;
        let here = file.parent().unwrap_or(Path::new("."));
        let base = match &sweep.base {
            Some(p) => Config::load(here.join(p))?,
            None => Config::default(),
        };
        let sigma3: Vec<f64> = sweep
            .sigma3
            .iter()
            .map(|v| match v {
                // A unit is required: `sigma3 = [8]` would be 8 Pa.
                toml::Value::String(s) => {
                    let pa = parse_with_unit(s, Dimension::Pressure)
                        .map_err(|e| Error::invalid("sigma3", format!("\"{s}\""), &e.0))?;
                    crate::config::validate::check_pressure("sigma3", pa)?;
                    Ok(pa)
                }
                other => Err(Error::invalid(
                    "sigma3",
                    other,
                    "a pressure with its unit, as a string such as \"8 MPa\"",
                )),
            })
            .collect::<Result<_>>()
            .map_err(|e| campaign_error(file, e))?;
        // Every friction a test can run at, before anything is run or a dry run says it would.
        if let Some(mu) = sweep.mu.iter().find(|m| !(m.is_finite() && **m >= 0.0)) {
            return Err(campaign_error(
                file,
                Error::invalid("mu", mu, "every friction must be a finite number >= 0"),
            ));
        }
        if sweep.mu.is_empty() || sigma3.is_empty() || sweep.seeds.is_empty() {
            return Err(campaign_error(
                file,
                "the grid is empty (mu, sigma3 and seeds need values)",
            ));
        }
        sweep.check_dt_entries(file)?;
        let mut grid = Vec::new();
        for &seed in &sweep.seeds {
            for &mu in &sweep.mu {
                for &s3 in &sigma3 {
                    let name = format!("seed{seed}_mu{mu}_s{}MPa", s3 / 1e6);
                    // Filesystems name a file in at most 255 bytes: a friction or pressure
                    // written out in hundreds of digits (mu = 1e300) passed the dry run and
                    // failed when its test started.
                    if name.len() > 255 {
                        return Err(campaign_error(
                            file,
                            format!(
                                "mu {mu}, sigma3 {s3} Pa: the test's directory name would be {} \
                                 bytes, beyond the 255 a file name may have",
                                name.len()
                            ),
                        ));
                    }
                    let dir = sweep.out.join(name);
                    // By value too: -0.0 equals 0.0 but is written "-0".
                    if grid
                        .iter()
                        .any(|p: &Point| p.dir == dir || (p.mu == mu && p.sigma3 == s3 && p.seed == seed))
                    {
                        return Err(Error::Campaign {
                            path: file.to_path_buf(),
                            tests: Vec::new(),
                            message: format!("duplicate point mu {mu}, sigma3 {s3} Pa, seed {seed}"),
                        });
                    }
                    grid.push(Point {
                        mu,
                        sigma3: s3,
                        seed,
                        dt: sweep.dt(mu, base.solver.dt.si()),
                        dir,
                    });
                }
            }
        }
        // Each test's configuration (its friction, pressure and time step in the base one) is
        // checked before anything is written or a dry run says it would start.
        for p in &grid {
            point_config(&base, p)
                .validate()
                .map_err(|e| campaign_error(file, format!("the test {}: {e}", p.dir.display())))?;
        }
        Ok(Sweep {
            file: file.to_path_buf(),
            base,
            out: sweep.out,
            grid,
        })
    }

    /// The names of the grid's test directories.
    pub fn names(&self) -> Vec<String> {
        self.grid
            .iter()
            .filter_map(|p| p.dir.file_name().map(|n| n.to_string_lossy().into_owned()))
            .collect()
    }
}

/// What the sweep does with one test, found from its directory.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum State {
    /// Finished (a summary): skipped.
    Finished,
    /// A record with a checkpoint: resumed.
    Resumable,
    /// A record without a checkpoint (killed in its first minutes): started again.
    Restart,
    /// Nothing yet: started.
    New,
}

impl State {
    /// The line `--dry-run` prints.
    pub fn dry_run(self) -> &'static str {
        match self {
            State::Finished => "already finished, would be skipped",
            State::Resumable => "would resume from its last checkpoint",
            State::Restart => "would restart (its record holds no checkpoint yet)",
            State::New => "would start",
        }
    }
}

/// The test's configuration in this sweep.
pub fn point_config(base: &Config, p: &Point) -> Config {
    let mut config = base.clone();
    config.sample.seed = p.seed;
    config.test.mu = p.mu;
    config.test.sigma3 = Pressure(p.sigma3);
    config.solver.dt = Duration(p.dt);
    config.output.dir = p.dir.clone();
    config
}

/// Finds what state test `p` is in and checks that a test found in its directory (finished
/// or to resume) has this sweep's settings (`config`, from [`point_config`]).
pub fn check_point(config: &Config, p: &Point) -> Result<State> {
    // A finished test is skipped and a half-finished one resumes with its own settings, so
    // both must be this sweep's tests. A record without a checkpoint (a test killed in its
    // first minutes) has nothing to resume: the test starts again. An unreadable record is
    // an error, never overwritten.
    let started = p.dir.join(crate::record::MCAP_FILE).exists();
    // A summary that does not stand (damaged, or another record's: `cdlab report` does not
    // count it either) does not make the test finished, or the sweep would skip it forever.
    // With a record the test resumes, which writes the summary again from a complete
    // record; without one (an archived test) nothing can repair it here: an error naming
    // the file.
    let finished = p.dir.join(crate::run::SUMMARY_FILE).exists()
        && match crate::run::read_checked_summary(&p.dir) {
            Ok(_) => true,
            Err(_) if started => false,
            Err(e) => return Err(e),
        };
    let (recorded, resume) = if finished {
        (Some(crate::record::read_config(&p.dir)?), false)
    } else if started {
        let record = crate::record::read_run(&p.dir)?;
        match record.last_checkpoint {
            Some(_) => (Some(record.config()?), true),
            None => (None, false),
        }
    } else {
        (None, false)
    };
    if let Some(recorded) = recorded {
        let differ = point_differences(config, &recorded);
        if !differ.is_empty() {
            return Err(Error::Run {
                path: p.dir.clone(),
                fault: RunFault::OtherSettings,
                message: format!(
                    "{} holds a test of other settings than this sweep's ({}): move it away or \
                     use another output directory",
                    p.dir.display(),
                    differ.join("; ")
                ),
                remedy: None,
            });
        }
    }
    Ok(match (finished, started, resume) {
        (true, _, _) => State::Finished,
        (_, _, true) => State::Resumable,
        (_, true, false) => State::Restart,
        _ => State::New,
    })
}

/// Whether the setting `key` makes a test found in its directory another test than the
/// sweep's when it differs. Not: where it was run (`output.dir`: a campaign may move), how
/// often it checkpointed (checkpoints change nothing in the run), and the solver's
/// numerical settings but the time step (tolerances, iteration schemes, thread count,
/// backend: how closely each step is solved and on what, which versions tune and a sweep
/// sets per machine; the campaign archived in `assets/results/campaign5000` ran under
/// older ones).
fn compared(key: &str) -> bool {
    let numerics = key.starts_with("solver.") && key != "solver.dt";
    !(numerics || key == "output.dir" || key == "output.checkpoint_every")
}

/// The units of the configuration's quantities (held in SI), for the messages.
const UNITS: [(&str, &str); 9] = [
    ("sample.r_min", " m"),
    ("sample.r_max", " m"),
    ("sample.density", " kg/m3"),
    ("solver.dt", " s"),
    ("compaction.sigma_c", " Pa"),
    ("test.sigma3", " Pa"),
    ("test.strip_thickness", " m"),
    ("test.axial_velocity", " m/s"),
    ("equilibrium.max_time", " s"),
];

/// The settings on which `recorded` (a test found in its directory) differs from `ours`
/// (the sweep's for that test), one phrase each naming the key and both values. Every
/// setting counts ([`compared`]): a finished test of other settings (another disk
/// count after the base changed) would enter the report as one of this campaign's, mixed
/// with the others without a word, and a half-finished one would resume with its own.
fn point_differences(ours: &Config, recorded: &Config) -> Vec<String> {
    let (ours, theirs) = (dotted(ours), dotted(recorded));
    let keys: std::collections::BTreeSet<&String> = ours.keys().chain(theirs.keys()).collect();
    let show = |v: Option<&serde_json::Value>, unit: &str| match v {
        None | Some(serde_json::Value::Null) => "none".to_string(),
        Some(serde_json::Value::String(s)) => format!("\"{s}\""),
        Some(serde_json::Value::Number(n)) => match (n.as_u64(), n.as_f64()) {
            (Some(k), _) => format!("{k}{unit}"),
            (None, Some(x)) => format!("{x}{unit}"),
            _ => format!("{n}{unit}"),
        },
        Some(other) => other.to_string(),
    };
    keys.into_iter()
        .filter(|k| compared(k))
        .filter(|k| ours.get(*k) != theirs.get(*k))
        .map(|k| {
            let unit = UNITS
                .iter()
                .find(|(key, _)| *key == k.as_str())
                .map_or("", |(_, u)| *u);
            format!(
                "{k}: {} here, {} in the test",
                show(ours.get(k), unit),
                show(theirs.get(k), unit)
            )
        })
        .collect()
}

/// The configuration's settings by dotted key (`sample.disks`), as serialized (SI).
fn dotted(config: &Config) -> std::collections::BTreeMap<String, serde_json::Value> {
    let mut out = std::collections::BTreeMap::new();
    let Ok(serde_json::Value::Object(sections)) = serde_json::to_value(config) else {
        return out;
    };
    for (section, keys) in sections {
        match keys {
            serde_json::Value::Object(keys) => {
                for (key, v) in keys {
                    out.insert(format!("{section}.{key}"), v);
                }
            }
            other => {
                out.insert(section, other);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A test runs at the entry with the largest `mu_from` at or below its friction; an
    /// entry repeated or below zero is refused.
    #[test]
    fn time_step_follows_the_friction_entries() {
        let sweep: SweepFile = toml::from_str(
            "out = \"x\"\n[[dt_by_friction]]\nmu_from = 6\ndt = \"0.1 ms\"\n\
             [[dt_by_friction]]\nmu_from = 3\ndt = \"0.25 ms\"\n",
        )
        .unwrap();
        sweep.check_dt_entries(Path::new("x.toml")).unwrap();
        let base = 5e-4;
        // Expected: below 3 the base step, from 3 up to 6 the 3 entry, from 6 the 6 entry.
        let got: Vec<f64> = [0.01, 2.99, 3.0, 5.0, 6.0, 12.0]
            .iter()
            .map(|&mu| sweep.dt(mu, base))
            .collect();
        assert_eq!(got, [5e-4, 5e-4, 2.5e-4, 2.5e-4, 1e-4, 1e-4]);
        for bad in [
            "out = \"x\"\n[[dt_by_friction]]\nmu_from = 3\ndt = \"0.25 ms\"\n[[dt_by_friction]]\nmu_from = 3\ndt = \"0.1 ms\"\n",
            "out = \"x\"\n[[dt_by_friction]]\nmu_from = -1\ndt = \"0.25 ms\"\n",
        ] {
            let sweep: SweepFile = toml::from_str(bad).unwrap();
            let e = sweep
                .check_dt_entries(Path::new("x.toml"))
                .unwrap_err()
                .to_string();
            assert!(e.contains("dt_by_friction"), "{e}");
        }
        // A duration without a time unit is a parse error, not a silent number.
        assert!(
            toml::from_str::<SweepFile>("out = \"x\"\n[[dt_by_friction]]\nmu_from = 3\ndt = \"0.25 MPa\"\n")
                .is_err()
        );
    }

    /// A point given twice is refused, also when its two spellings differ (-0.0 and 0.0), and
    /// so is a friction whose test directory could not be named (issue 36, item 12).
    #[test]
    fn a_point_given_twice_or_unnameable_is_refused() {
        let dir = std::env::temp_dir().join(format!("cdlab-sweep-points-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (text, expect) in [
            ("mu = [0.0, -0.0]\nsigma3 = [\"8 MPa\"]\n", "duplicate point"),
            ("mu = [1e300]\nsigma3 = [\"8 MPa\"]\n", "255"),
        ] {
            let file = dir.join("sweep.toml");
            std::fs::write(&file, format!("out = \"{}\"\n{text}", dir.join("out").display())).unwrap();
            let e = Sweep::load(&file).map(|_| ()).unwrap_err().to_string();
            assert!(e.contains(expect), "{text}: {e}");
        }
        // One spelling each is a grid of two points.
        let file = dir.join("sweep.toml");
        std::fs::write(
            &file,
            format!(
                "out = \"{}\"\nmu = [0.0, 0.3]\nsigma3 = [\"8 MPa\"]\n",
                dir.join("out").display()
            ),
        )
        .unwrap();
        assert_eq!(Sweep::load(&file).unwrap().grid.len(), 2);
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// The campaign files shipped in `assets/` parse, cover the paper's 13 x 5 grid, and
    /// their base configurations load with the sample size their names promise.
    #[test]
    fn shipped_campaign_files_parse() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets");
        // (file, disks, iteration after which relaxation and the velocity test apply, time
        // step at friction 12)
        for (file, disks, after, dt12) in [
            ("campaign1000.toml", 1000, 100, 1.25e-4),
            ("campaign5000.toml", 5000, 100, 6.25e-5),
            ("campaign5000_fast.toml", 5000, 30, 1.25e-4),
        ] {
            let text = std::fs::read_to_string(dir.join(file)).unwrap();
            let sweep: SweepFile = toml::from_str(&text).unwrap();
            assert_eq!((sweep.mu.len(), sweep.sigma3.len()), (13, 5), "{file}");
            let base = Config::load(dir.join(sweep.base.as_ref().expect("a base file"))).unwrap();
            assert_eq!(base.sample.disks, disks, "{file}");
            assert_eq!(base.solver.threads, 1, "{file}: one thread per test");
            assert_eq!(base.solver.gs_relax_after, after, "{file}");
            // All run friction 1.2 at the base's 0.5 ms and 3 at 0.25 ms; 12 at 0.125 ms,
            // or 0.0625 ms in the 5000-disk reference campaign (docs/results.md, "Overlaps at
            // high friction").
            let base_dt = base.solver.dt.si();
            assert_eq!(base_dt, 5e-4, "{file}");
            let steps = [1.2, 3.0, 12.0].map(|mu| sweep.dt(mu, base_dt));
            assert_eq!(steps, [5e-4, 2.5e-4, dt12], "{file}");
        }
    }
}
