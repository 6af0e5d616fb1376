//! Run configuration: a TOML file whose defaults are the paper's values.
//!
//! The documented default file is `assets/default.toml` ([`Config::default_toml`]); every
//! key may be omitted, unknown keys are errors. Quantities carry units ([`units`]).
//! Reading a file ([`Config::load`], [`Config::from_toml_str`]) or a JSON value that a
//! program built ([`Config::from_json_value`]) also validates it, so a
//! configuration in hand is always in range; command-line [`Overrides`] are applied on top
//! and must be followed by [`Config::validate`].

mod sections;
pub mod units;
pub mod validate;

#[cfg(test)]
mod tests;

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

pub use sections::{Backend, Compaction, Equilibrium, Method, Output, Sample, Solver, Test};
pub use units::{Density, Dimension, Duration, Length, Pressure, UnitError, Velocity};

use crate::error::{Error, Result};

/// The embedded default file, with comments on every key.
const DEFAULT_TOML: &str = include_str!("../../assets/default.toml");

/// A complete run configuration (one biaxial test).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// `[sample]`: disks and sample shape.
    pub sample: Sample,
    /// `[solver]`: time stepping and contact solver.
    pub solver: Solver,
    /// `[compaction]`: the uniaxial compaction.
    pub compaction: Compaction,
    /// `[test]`: confinement and biaxial compression.
    pub test: Test,
    /// `[equilibrium]`: end of the preparation phases.
    pub equilibrium: Equilibrium,
    /// `[output]`: records.
    pub output: Output,
}

/// Command-line values that replace those of the file (`None`: keep the file's value).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Overrides {
    /// `sample.disks`.
    pub disks: Option<usize>,
    /// `test.mu`.
    pub mu: Option<f64>,
    /// `test.sigma3`.
    pub sigma3: Option<Pressure>,
    /// `test.strain_end`.
    pub strain: Option<f64>,
    /// `sample.seed`.
    pub seed: Option<u64>,
    /// `solver.backend`.
    pub backend: Option<Backend>,
    /// `output.dir`.
    pub out: Option<PathBuf>,
}

/// The first line of a configuration file with a checksum ([`with_checksum`]), before the
/// eight hexadecimal digits of the CRC-32.
pub const CHECKSUM_PREFIX: &str = "# checksum: crc32:";

/// `toml` with a first line holding the CRC-32 of the rest, which
/// [`Config::load_archived`] checks: what `cdlab archive` writes as an archived test's
/// configuration, the only copy it keeps. The line is a TOML comment, so the file stays a
/// configuration file for `--config`.
pub fn with_checksum(toml: &str) -> String {
    format!(
        "{CHECKSUM_PREFIX}{:08x} (of the lines below; cdlab refuses this file as an archived \
         test's once they change)\n{toml}",
        crc32fast::hash(toml.as_bytes())
    )
}

/// A TOML error in the file `path` (text `text`) as the user sees the file: the line and
/// the key where the error is, in plain words. The configuration files and the sweep files
/// share it; the sweep's said "line 0" before the real line.
pub(crate) fn toml_error(text: &str, e: &toml::de::Error, path: &Path) -> Error {
    // toml reports a byte span; users want a line number.
    let start = e.span().map(|s| s.start.min(text.len()));
    let line = start.map_or(0, |s| text[..s].matches('\n').count() + 1);
    let message = match start.and_then(|s| key_at(text, s)) {
        Some(key) => format!("`{key}`: {}", plain_words(e.message())),
        None => plain_words(e.message()),
    };
    Error::Parse {
        path: path.to_path_buf(),
        line,
        message,
    }
}

/// The dotted key (`test.sigma3`) of the `key = value` line holding byte `at` of `text`,
/// with the `[section]` above it: toml's messages about a value do not name its key, and a
/// user looks for the key, not the line.
fn key_at(text: &str, at: usize) -> Option<String> {
    let line_start = text[..at].rfind('\n').map_or(0, |k| k + 1);
    let line = text[line_start..].lines().next()?;
    let (key, _) = line.split_once('=')?;
    let key = key.trim().trim_matches('"');
    let plain = |k: &str| !k.is_empty() && k.chars().all(|c| c.is_ascii_alphanumeric() || "_-.".contains(c));
    if !plain(key) {
        return None;
    }
    let section = text[..line_start]
        .lines()
        .rev()
        .map(str::trim)
        .find(|l| l.starts_with('[') && l.ends_with(']') && !l.starts_with("[["))
        .map(|l| l.trim_matches(|c| c == '[' || c == ']').trim().to_string());
    Some(match section {
        Some(s) if plain(&s) => format!("{s}.{key}"),
        _ => key.to_string(),
    })
}

/// A TOML reader's message in a scientist's words: the Rust types a value was expected as
/// (`usize`, `f64`) become what they mean ("a whole number >= 0", "a number").
pub fn plain_words(message: &str) -> String {
    let mut out = message.trim().to_string();
    for (rust, plain) in [
        ("usize", "a whole number >= 0"),
        ("u64", "a whole number >= 0"),
        ("u32", "a whole number >= 0 (below 2^32)"),
        ("u16", "a whole number >= 0 (below 65536)"),
        ("u8", "a whole number >= 0 (below 256)"),
        ("i64", "a whole number"),
        ("i32", "a whole number"),
        ("f64", "a number"),
        ("f32", "a number"),
    ] {
        out = out.replace(&format!("expected {rust}"), &format!("expected {plain}"));
    }
    out
}

/// A deserialiser's message about a value ("invalid value: integer `-5`, expected a whole
/// number >= 0", in [`plain_words`]) as the allowed form of [`Error::Invalid`]: "must be
/// a whole number >= 0, not integer `-5`". Other messages (an unknown key, a unit of the
/// wrong dimension) are kept as they are.
fn allowed_of(message: &str) -> String {
    ["invalid value: ", "invalid type: "]
        .iter()
        .find_map(|p| message.strip_prefix(p))
        .and_then(|m| m.split_once(", expected "))
        .map_or_else(
            || message.to_string(),
            |(got, want)| format!("must be {want}, not {got}"),
        )
}

/// Largest configuration or sweep file read (1 MiB): the default configuration, comments
/// included, is a few kilobytes, so anything larger is the wrong file (or `/dev/zero`), and
/// reading it whole would take all the memory there is.
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;

/// Reads the UTF-8 text of `path`, refusing a file longer than `limit` bytes (`what` names
/// the kind of file in that error) without reading more than `limit + 1` bytes of it: a
/// device or a pipe that never ends is refused as well as a huge file.
pub fn read_capped(path: &Path, limit: u64, what: &str) -> Result<String> {
    use std::io::Read;
    let file = std::fs::File::open(path).map_err(|e| Error::io(path, e))?;
    let mut bytes = Vec::new();
    file.take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    // Errors of the file's content, named by it (the Python package's FileError with its path).
    let bad = |why: String| Error::io(path, std::io::Error::new(std::io::ErrorKind::InvalidData, why));
    if bytes.len() as u64 > limit {
        return Err(bad(format!(
            "longer than {limit} bytes, too long for {what}: is it the right file?"
        )));
    }
    String::from_utf8(bytes).map_err(|e| bad(format!("not UTF-8 text ({e})")))
}

impl Config {
    /// The commented default configuration file (what `cdlab config --print-default` shows).
    pub fn default_toml() -> &'static str {
        DEFAULT_TOML
    }

    /// Parses and validates TOML text. Syntax errors report their line.
    pub fn from_toml_str(text: &str) -> Result<Self> {
        Self::parse(text, Path::new("<config>"))
    }

    /// Reads, parses and validates a TOML file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = read_capped(path, MAX_CONFIG_BYTES, "a configuration file")?;
        Self::parse(&text, path)
    }

    /// Reads the configuration that `cdlab archive` wrote into an archived test
    /// ([`with_checksum`]): its checksum is checked first, so that a changed digit (150
    /// disks read as 250, which the sweep then took as the test's settings) or a cut is an
    /// error naming the file, not another test. A file without the checksum line (archives
    /// written before it existed, such as the shipped `assets/results/campaign5000`) is
    /// read unchecked. Every error names the file: a missing one says what it is, and a
    /// value out of range ("invalid parameter `sample.r_min` = 0") says where it was read.
    pub fn load_archived(path: &Path) -> Result<Self> {
        // An error of the file itself, for every caller (the Python package's `FileError`
        // with its path).
        let damaged = |why: String| Error::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::InvalidData, why),
        };
        let text = read_capped(path, MAX_CONFIG_BYTES, "a configuration file").map_err(|e| match e {
            Error::Io { source, .. } if source.kind() == std::io::ErrorKind::NotFound => damaged(
                "missing: an archived test (no record) keeps its configuration in this file; \
                 archive the test again from its run directory"
                    .into(),
            ),
            e => e,
        })?;
        let checked = text.starts_with(CHECKSUM_PREFIX);
        let in_file = |e: Error| match e {
            // Lines of the file, the checksum line included.
            Error::Parse { path, line, message } if checked && line > 0 => Error::Parse {
                path,
                line: line + 1,
                message,
            },
            Error::Invalid {
                field,
                value,
                allowed,
            } => Error::Invalid {
                field,
                value,
                allowed: format!("{allowed} (read from {})", path.display()),
            },
            e => e,
        };
        let body = match text.strip_prefix(CHECKSUM_PREFIX) {
            Some(rest) => {
                let (line, body) = rest.split_once('\n').unwrap_or((rest, ""));
                let recorded = line.get(..8).and_then(|h| u32::from_str_radix(h, 16).ok());
                let computed = crc32fast::hash(body.as_bytes());
                if recorded != Some(computed) {
                    return Err(damaged(format!(
                        "damaged: the CRC-32 of its content is {computed:08x}, its checksum line \
                         says {}: changed or cut after it was written; archive the test again \
                         from its run directory",
                        line.get(..8).unwrap_or(line)
                    )));
                }
                body
            }
            None => text.as_str(),
        };
        Self::parse(body, path).map_err(in_file)
    }

    fn parse(text: &str, path: &Path) -> Result<Self> {
        let config: Config = toml::from_str(text).map_err(|e| toml_error(text, &e, path))?;
        config.validate()?;
        Ok(config)
    }

    /// Deserialises and validates a configuration given as a JSON value with the sections
    /// and keys of the TOML file (quantities as SI numbers or unit strings, `"8 MPa"`, as in
    /// a file): what a program builds (the Python package's dicts), read with serde
    /// directly. Nobody wrote its lines, so a value of the wrong type or a key that does not
    /// exist is an [`Error::Invalid`] naming the dotted key (`sample.disks`) and the value,
    /// in words rather than Rust types; only what names no key (the value is not an object)
    /// is an [`Error::Parse`] of `source`, without a line.
    pub fn from_json_value(value: serde_json::Value, source: &str) -> Result<Self> {
        // The value is consumed by the deserialiser: a copy gives the offending value for
        // the message, and configurations are a few hundred bytes.
        let copy = value.clone();
        let config: Config = serde_path_to_error::deserialize(value).map_err(|e| {
            let keys: Option<Vec<&str>> = e
                .path()
                .iter()
                .map(|s| match s {
                    serde_path_to_error::Segment::Map { key } => Some(key.as_str()),
                    _ => None,
                })
                .collect();
            let message = plain_words(&e.inner().to_string());
            match keys {
                Some(keys) if !keys.is_empty() => {
                    let at = keys.iter().try_fold(&copy, |v, k| v.get(k));
                    let value = at.map_or_else(String::new, |v| v.to_string());
                    Error::invalid(&keys.join("."), value, &allowed_of(&message))
                }
                _ => Error::Parse {
                    path: source.into(),
                    line: 0,
                    message,
                },
            }
        })?;
        config.validate()?;
        Ok(config)
    }

    /// Writes the configuration as TOML (quantities as SI numbers, no comments).
    pub fn to_toml_string(&self) -> Result<String> {
        toml::to_string_pretty(self)
            .map_err(|e| Error::Other(format!("cannot write the configuration as TOML: {e}")))
    }

    /// Replaces the values given on the command line. Nothing fails here; ranges are
    /// checked by [`Config::validate`], which the caller runs afterwards.
    pub fn apply(&mut self, o: &Overrides) {
        if let Some(d) = o.disks {
            self.sample.disks = d;
        }
        if let Some(mu) = o.mu {
            self.test.mu = mu;
        }
        if let Some(s) = o.sigma3 {
            self.test.sigma3 = s;
        }
        if let Some(e) = o.strain {
            self.test.strain_end = e;
        }
        if let Some(seed) = o.seed {
            self.sample.seed = seed;
        }
        if let Some(b) = o.backend {
            self.solver.backend = b;
        }
        if let Some(dir) = &o.out {
            self.output.dir = dir.clone();
        }
    }
}

impl Config {
    /// The default configuration with `disks` disks: what the benches, `cdlab bench` and
    /// the tests start from.
    pub fn with_disks(disks: usize) -> Config {
        let mut config = Config::default();
        config.sample.disks = disks;
        config
    }

    /// The protocol parameters of this configuration, in SI units.
    pub fn protocol(&self) -> crate::protocol::ProtocolParams {
        use crate::engine::StepParams;
        use crate::protocol::{Equilibrium, ProtocolParams};
        use crate::solver::{AndersonSettings, GaussSeidelSettings, JacobiSettings, SolverParams};
        let (s, v, t, e, o) = (
            &self.sample,
            &self.solver,
            &self.test,
            &self.equilibrium,
            &self.output,
        );
        let r_min = s.r_min.si();
        ProtocolParams {
            disks: s.disks,
            r_min,
            r_max: s.r_max.si(),
            density: s.density.si(),
            seed: s.seed,
            aspect: s.aspect_ratio,
            sigma_c: self.compaction.sigma_c.si(),
            mu_compaction: self.compaction.friction,
            step: StepParams {
                dt: v.dt.si(),
                theta: v.theta,
                alert: v.alert_distance * r_min,
                overlap_limit: v.overlap_limit * r_min,
                solver: SolverParams {
                    method: v.method,
                    tol: v.tol,
                    max_iter: v.max_iter,
                    jacobi: JacobiSettings {
                        relax: v.jacobi_relax,
                    },
                    parallel: true,
                    parallel_min: crate::solver::default_parallel_min(),
                    threads: v.threads,
                    gauss_seidel: GaussSeidelSettings {
                        relax: v.gs_relax,
                        relax_after: v.gs_relax_after,
                    },
                    velocity_tol: v.velocity_tol * r_min / v.dt.si(),
                    open_skip: v.open_skip_gap * r_min / v.dt.si(),
                    deep_gap: v.deep_overlap_rel() * r_min,
                    deep_sweeps: v.deep_sweeps,
                    anderson: AndersonSettings {
                        depth: v.anderson_depth,
                    },
                    check_every: v.check_every,
                },
            },
            mu: t.mu,
            mu_wall: t.wall_friction(),
            e_n: t.e_n,
            e_t: t.e_t,
            sigma3: t.sigma3.si(),
            strip_thickness: t.strip_thickness.si(),
            strip_refresh_every: t.strip_refresh_every.min(u32::MAX as u64) as u32,
            axial_velocity: t.axial_velocity.si(),
            strain_end: t.strain_end,
            equilibrium: Equilibrium {
                kinetic_ratio: e.kinetic_ratio,
                compaction_kinetic_ratio: e.compaction_kinetic_ratio,
                runaway_kinetic_ratio: e.runaway_kinetic_ratio,
                force_imbalance: e.force_imbalance,
                creep_rate: e.creep_rate,
                window: e.hold_steps.clamp(1, u32::MAX as u64) as u32,
                max_time: e.max_time.si(),
            },
            series_every: o.series_every.clamp(1, u32::MAX as u64) as u32,
            snapshot_every: o.snapshot_every,
            checkpoint_every: if o.checkpoint_every == 0 {
                u32::MAX
            } else {
                o.checkpoint_every.min(u32::MAX as u64) as u32
            },
        }
    }
}
