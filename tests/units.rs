//! Quantities with units through the public API (`cdlab::config`): the SI definitions of
//! the prefixes are the outside truth (micro 1e-6, milli 1e-3, kilo 1e3, mega 1e6), and a
//! value that is not a finite number of its unit is refused with the field named.

mod common;

use cdlab::config::{Config, Duration, Length, Pressure};

/// `got` equals the exact SI value `want` to within one rounding of the product number x
/// factor (half an ulp each for the number, the factor and the product: 2 ulps).
fn assert_si(text: &str, got: f64, want: f64) {
    assert!(
        (got - want).abs() <= 2.0 * f64::EPSILON * want.abs(),
        "{text:?} gave {got:e}, expected {want:e} (SI)"
    );
}

#[test]
fn micro_seconds_take_both_spellings() {
    // 1 µs = 1e-6 s (SI prefix micro); "us" is the ASCII spelling of the same unit.
    for text in ["5 us", "5us", "5 µs", "5µs", " 5 µs "] {
        let d: Duration = text.parse().unwrap_or_else(|e| panic!("{text:?}: {e}"));
        assert_si(text, d.si(), 5e-6);
    }
    let d: Duration = "5 ms".parse().unwrap();
    assert_si("5 ms", d.si(), 5e-3);
}

#[test]
fn millimetres_and_kilometres() {
    for (text, want) in [
        ("7.5 mm", 7.5e-3),
        ("7.5mm", 7.5e-3),
        ("2 km", 2e3),
        ("2km", 2e3),
        ("3 cm", 3e-2),
        ("7.5 m", 7.5),
        ("7.5", 7.5),
    ] {
        let l: Length = text.parse().unwrap_or_else(|e| panic!("{text:?}: {e}"));
        assert_si(text, l.si(), want);
    }
    // Case matters: "MM" and "Km" are not units (a typo must not pass as another unit).
    for text in ["7.5 MM", "2 Km"] {
        assert!(text.parse::<Length>().is_err(), "{text:?} was accepted");
    }
}

#[test]
fn a_leading_plus_sign_is_a_number() {
    for (text, want) in [("+8 MPa", 8e6), ("+8MPa", 8e6), ("+500 kPa", 5e5), ("+1e6", 1e6)] {
        let p: Pressure = text.parse().unwrap_or_else(|e| panic!("{text:?}: {e}"));
        assert_si(text, p.si(), want);
    }
    let l: Length = "+7.5 mm".parse().unwrap();
    assert_si("+7.5 mm", l.si(), 7.5e-3);
}

#[test]
fn a_unit_of_another_dimension_is_refused_with_the_accepted_ones() {
    let e = "8 m".parse::<Pressure>().expect_err("a length is not a pressure");
    let text = e.to_string();
    assert!(
        text.contains("8 m") && text.contains("MPa") && text.contains("pressure"),
        "{text}"
    );
    assert!("8 mpa".parse::<Pressure>().is_err(), "mpa is not MPa");
}

#[test]
fn a_pressure_beyond_f64_is_refused_naming_the_field() {
    // 1e400 MPa is beyond the largest f64 (about 1.8e308): it must not become an infinite
    // confining stress. Whether the parser or the validation refuses it, the configuration
    // is refused and the message names the field.
    if let Ok(p) = "1e400 MPa".parse::<Pressure>() {
        assert!(
            !p.si().is_finite(),
            "1e400 MPa read as the finite {:e} Pa",
            p.si()
        );
    }
    let e = Config::from_toml_str("[test]\nsigma3 = \"1e400 MPa\"\n")
        .expect_err("an infinite sigma3 must be refused");
    assert!(e.to_string().contains("sigma3"), "{e}");
    // The same through a bare number.
    let e = Config::from_toml_str("[test]\nsigma3 = \"1e400\"\n").expect_err("infinite sigma3");
    assert!(e.to_string().contains("sigma3"), "{e}");
}

#[test]
fn a_time_step_below_f64_range_is_refused_naming_it() {
    // 1e-320 s is a subnormal f64: no time step can be that small (the run would take
    // 1e320 steps per second of simulated time). The error names solver.dt itself.
    let e = Config::from_toml_str("[solver]\ndt = \"1e-320 s\"\n")
        .expect_err("a subnormal time step must be refused");
    let text = e.to_string();
    assert!(
        text.contains("solver.dt"),
        "the error does not name solver.dt: {text}"
    );
}

/// A unit in the wrong case is refused, and the message states the rule as it applies
/// (issue 36, item 17: `--sigma3 8mpa` was told "a number (Pa) or a string with one of the
/// units", while the command line refuses a bare number): on the command line a number
/// with a unit, in a file also a bare SI number; units are case-sensitive, and the unit
/// meant is named.
#[test]
fn a_unit_in_the_wrong_case_is_refused_with_the_rule_and_the_unit_meant() {
    use cdlab::config::units::{Dimension, parse_with_unit};
    let e = parse_with_unit("8mpa", Dimension::Pressure)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("a number with one of the units Pa, kPa, MPa, GPa (case-sensitive)")
            && e.contains("did you mean `MPa`?")
            && !e.contains("a number (Pa)"),
        "{e}"
    );
    let e = "8 mpa".parse::<Pressure>().unwrap_err().to_string();
    assert!(
        e.contains("a number (Pa) or") && e.contains("did you mean `MPa`?"),
        "{e}"
    );
    // No hint where no unit is meant.
    let e = parse_with_unit("8 furlongs", Dimension::Length)
        .unwrap_err()
        .to_string();
    assert!(!e.contains("did you mean"), "{e}");
    let (ok, text) = common::cdlab(&["biaxial", "--sigma3", "8mpa", "--out", "/nonexistent-cdlab/x"]);
    assert!(
        !ok && text.contains("did you mean `MPa`?") && !text.contains("a number (Pa)"),
        "{text}"
    );
}
