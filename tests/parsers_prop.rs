//! Property tests of the input parsers (issue 23): the configuration, quantities with
//! units, fc2d problem files and prepared-sample files, fed arbitrary and mutated inputs.
//! None may panic or allocate without bound; a configuration error names a key; every
//! damage to a sample file is detected. Case counts keep the file to a few seconds.

use std::path::Path;

use cdlab::config::units::{Dimension, parse_quantity, parse_with_unit};
use cdlab::config::{Config, Duration, Length, Pressure};
use cdlab::model::Scene;
use cdlab::protocol::LabState;
use cdlab::protocol::sample_file::{HEADER_LEN, decode_sample, encode_sample};
use glam::DVec2;
use proptest::prelude::*;
use proptest::test_runner::Config as Cases;

/// `cases` cases, and no regression files written into the source tree.
fn cases(cases: u32) -> Cases {
    Cases {
        cases,
        failure_persistence: None,
        ..Cases::default()
    }
}

/// Every `section.key` of the default configuration, read from its commented TOML (so a key
/// added later is covered without editing this list).
fn config_keys() -> Vec<(String, String)> {
    let table: toml::Table = toml::from_str(Config::default_toml()).unwrap();
    let mut keys = Vec::new();
    for (section, v) in &table {
        if let Some(t) = v.as_table() {
            keys.extend(t.keys().map(|k| (section.clone(), k.clone())));
        }
    }
    assert!(keys.len() > 20, "{keys:?}");
    keys
}

/// A TOML value of any kind, plausible or absurd for any key.
fn any_value() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<i64>().prop_map(|v| v.to_string()),
        any::<f64>().prop_map(|v| format!("{v:?}")),
        (-1e3f64..1e3).prop_map(|v| format!("{v}")),
        Just("nan".to_string()),
        Just("-inf".to_string()),
        Just("true".to_string()),
        Just("[]".to_string()),
        Just("{ a = 1 }".to_string()),
        (
            any::<f64>(),
            prop::sample::select(vec![
                "", "Pa", "MPa", "GPa", "m", "mm", "km", "s", "ms", "us", "µs", "m/s", "kg/m3", "MPa MPa",
                "x",
            ])
        )
            .prop_map(|(v, u)| format!("\"{v} {u}\"")),
        "\"[ -~]{0,12}\"",
    ]
}

/// Strings made of the characters of quantities, and some others.
fn quantity_text() -> impl Strategy<Value = String> {
    prop_oneof![
        "[0-9eE+\\-. ]{0,12}(Pa|kPa|MPa|GPa|m|mm|km|s|ms|us|µs|μs|m/s|kg/m3)?",
        "\\PC{0,16}",
        (any::<f64>(), "[ ]?(Pa|MPa|s|us|m|km)?").prop_map(|(v, u)| format!("{v:e}{u}")),
    ]
}

/// A small fc2d problem in the layout of `src/fc2d/parse.rs`.
fn fc2d_text(nc: usize) -> String {
    let n = 2 * nc;
    let mut t = format!("2\n{nc}\n2\n{n}\n{n}\n2\nCSparse p\n{n}-by-{n}, nzmax: {n} nnz: {n}, 1-norm: 2\n");
    for j in 0..n {
        t += &format!("    col {j} : locations {j} to {j}\n      {j} : 2.5\n");
    }
    let q: Vec<String> = (0..n).map(|k| format!("-{}.25", k + 1)).collect();
    let mu: Vec<String> = (0..nc).map(|_| "0.3".to_string()).collect();
    t + &q.join(" ") + "\n" + &mu.join(" ") + "\n"
}

/// The bytes of a 64-disk sample file: enough disks for the checkpoint inside to decode,
/// few enough to mutate quickly.
fn sample_bytes() -> Vec<u8> {
    let mut params = Config::default().protocol();
    params.disks = 64;
    let mut scene = Scene::default();
    for k in 0..64 {
        let pos = DVec2::new(2.5 * (k % 8) as f64, 2.5 * (k / 8) as f64);
        scene.disks.push(pos, 1.0, 2600.0).unwrap();
    }
    let state = LabState::new(params, Default::default(), Default::default(), 0.0);
    encode_sample(&state, &scene)
}

proptest! {
    #![proptest_config(cases(1024))]

    /// Arbitrary text never panics the configuration parser; an error names the file.
    #[test]
    fn config_text_never_panics(text in "(\\[[a-z]{1,10}\\]\n|[a-z_]{1,14} = [ -~]{0,16}\n|\\PC{0,20}\n){0,8}") {
        if let Err(e) = Config::from_toml_str(&text) {
            prop_assert!(!e.to_string().is_empty());
        }
    }

    /// Any value for any key: the configuration loads, or the error names a key (the one
    /// set, or the one it must agree with, as `sample.r_max` with `sample.r_min`).
    #[test]
    fn config_value_error_names_a_key(key in prop::sample::select(config_keys()), value in any_value()) {
        let (section, name) = key;
        let text = format!("[{section}]\n{name} = {value}\n");
        if let Err(e) = Config::from_toml_str(&text) {
            let msg = e.to_string();
            let dotted = format!("{section}.{name}");
            let names_any = config_keys()
                .iter()
                .any(|(s, k)| msg.contains(&format!("{s}.{k}")));
            if toml::from_str::<toml::Table>(&format!("x = {value}")).is_ok() {
                prop_assert!(msg.contains(&dotted) || names_any, "{text}: {msg}");
            } else {
                // Not TOML at all (an unclosed string): the error gives the line.
                prop_assert!(matches!(e, cdlab::Error::Parse { line: 2.., .. }), "{text}: {msg}");
            }
        }
    }

    /// Quantities: never a panic, never a non-finite value, and a flag's value has a unit.
    #[test]
    fn quantities_are_finite_or_refused(text in quantity_text()) {
        for dim in [Dimension::Pressure, Dimension::Length, Dimension::Duration, Dimension::Velocity, Dimension::Density] {
            if let Ok(v) = parse_quantity(&text, dim) {
                prop_assert!(v.is_finite(), "{text} -> {v}");
            }
            if parse_with_unit(&text, dim).is_ok() {
                let unit: String = text
                    .chars()
                    .filter(|c| !(c.is_ascii_digit() || c.is_whitespace() || "eE+-.".contains(*c)))
                    .collect();
                prop_assert!(!unit.is_empty(), "`{}` accepted without a unit", text);
            }
        }
    }

    /// A finite value written with a unit reads back as the SI value, to rounding.
    #[test]
    fn quantities_round_trip(v in -1e12f64..1e12) {
        let p: Pressure = format!("{v} MPa").parse().unwrap();
        prop_assert!((p.0 - v * 1e6).abs() <= 1e-15 * (v * 1e6).abs());
        let l: Length = format!("{v}mm").parse().unwrap();
        prop_assert!((l.0 - v / 1e3).abs() <= 1e-15 * (v / 1e3).abs());
        let d: Duration = format!("+{}us", v.abs()).parse().unwrap();
        prop_assert!((d.0 - v.abs() / 1e6).abs() <= 1e-15 * (v / 1e6).abs());
    }

    /// Arbitrary bytes never panic the fc2d parser, and its messages stay short.
    #[test]
    fn fc2d_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..400)) {
        let text = String::from_utf8_lossy(&bytes);
        if let Err(e) = cdlab::fc2d::parse(&text, Path::new("x.dat")) {
            // A damaged line is quoted, cut short: a message does not repeat megabytes.
            prop_assert!(e.to_string().len() < 400, "{e}");
        }
    }

    /// Mutations of a valid file (a byte replaced, inserted or removed, a number in the
    /// header replaced by any integer, a cut): never a panic or an allocation beyond the
    /// file; what parses has at most one contact per 6 bytes.
    #[test]
    fn fc2d_mutations(nc in 1usize..5, at in any::<prop::sample::Index>(), byte in any::<u8>(),
                      op in 0u8..5, huge in any::<u64>()) {
        let good = fc2d_text(nc);
        let mut b = good.clone().into_bytes();
        let k = at.index(b.len());
        match op {
            0 => b[k] = byte,
            1 => b.insert(k, byte),
            2 => { b.remove(k); }
            3 => b.truncate(k),
            _ => {
                let line = good.lines().nth(k % 6).unwrap();
                let mut lines: Vec<String> = good.lines().map(String::from).collect();
                lines[k % 6] = line.replace(line, &huge.to_string());
                b = (lines.join("\n") + "\n").into_bytes();
            }
        }
        let text = String::from_utf8_lossy(&b);
        if let Ok(p) = cdlab::fc2d::parse(&text, Path::new("m.dat")) {
            prop_assert!(p.nc <= text.len() / 6);
            prop_assert_eq!(p.q.len(), 2 * p.nc);
            prop_assert_eq!(p.mu.len(), p.nc);
        }
        if op == 3 {
            prop_assert!(cdlab::fc2d::parse(&text, Path::new("m.dat")).is_err(), "a cut at {k} was read");
        }
    }

    /// Arbitrary bytes, with or without the sample magic in front, are refused.
    #[test]
    fn sample_arbitrary_bytes(bytes in prop::collection::vec(any::<u8>(), 0..600), magic in any::<bool>()) {
        let mut b = if magic { b"CDLABSP2".to_vec() } else { Vec::new() };
        b.extend(bytes);
        prop_assert!(decode_sample(&b, Path::new("s.bin")).is_err());
    }
}

proptest! {
    #![proptest_config(cases(4096))]

    /// Any damage to a sample file is detected before use: a flipped bit anywhere, any
    /// burst of up to 4 overwritten bytes (CRC-32 detects every burst up to 32 bits), a cut
    /// anywhere, bytes appended.
    #[test]
    fn sample_damage_is_always_detected(at in any::<prop::sample::Index>(), bit in 0u8..8,
                                        burst in prop::collection::vec(any::<u8>(), 1..=4),
                                        op in 0u8..4, extra in prop::collection::vec(any::<u8>(), 1..16)) {
        let good = sample_bytes();
        let path = Path::new("damaged.bin");
        let mut b = good.clone();
        let k = at.index(b.len());
        match op {
            0 => b[k] ^= 1 << bit,
            1 => {
                let end = (k + burst.len()).min(b.len());
                b[k..end].copy_from_slice(&burst[..end - k]);
            }
            2 => b.truncate(k),
            _ => b.extend(extra),
        }
        if b == good {
            return Ok(()); // a burst that wrote the same bytes damages nothing
        }
        let e = decode_sample(&b, path);
        prop_assert!(e.is_err(), "damage {op} at byte {k} (of {}, header {HEADER_LEN}) not detected", good.len());
        prop_assert!(e.unwrap_err().to_string().contains("damaged.bin"));
    }
}

/// The undamaged file reads back (the property above would pass on a reader that refuses
/// everything).
#[test]
fn the_undamaged_sample_reads_back() {
    let s = decode_sample(&sample_bytes(), Path::new("s.bin")).unwrap();
    assert_eq!(s.scene.disks.len(), 64);
    assert_eq!(s.params.disks, 64);
}
