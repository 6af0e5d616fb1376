//! Physical quantities with unit suffixes, for configuration files and the command line.
//!
//! In a configuration file a quantity is written either as a bare number (SI: Pa, m, s, m/s,
//! kg/m^3) or as a string with a unit suffix, with or without a space: `"8MPa"`, `"8 MPa"`,
//! `"0.5 m/s"`, `"7.5 m"`, `"+8 MPa"`. On the command line ([`parse_with_unit`]) the unit is
//! required: `--sigma3 8` read as 8 Pa confined a sample at a millionth of the intended
//! stress. A value that overflows (`"1e400 MPa"`) is an error, never infinity. Microseconds
//! are `us`, `µs` (micro sign) or `μs` (Greek mu), which look alike.
//! Units are case-sensitive on purpose: `mPa` (millipascal) and `MPa` differ by 1e9, and a
//! silent case-folding would turn a typo into a wrong experiment.
//!
//! Each dimension has its own newtype, so a length can never be read where a pressure is
//! expected; a unit of the wrong dimension ("8 m" for a pressure) is an error that lists the
//! units accepted. Values serialize as plain SI numbers: Rust prints `f64` in its shortest
//! round-trip form, so writing and reading a configuration gives back the same bits.

use std::fmt;
use std::str::FromStr;

use serde::de::{self, Visitor};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// A physical dimension and its accepted units (symbol, factor to SI).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dimension {
    /// Stress or pressure (Pa).
    Pressure,
    /// Length (m).
    Length,
    /// Time (s).
    Duration,
    /// Velocity (m/s).
    Velocity,
    /// Mass density (kg/m^3).
    Density,
}

impl Dimension {
    /// The accepted unit symbols with their factor to SI; the first one is the SI unit.
    pub fn units(self) -> &'static [(&'static str, f64)] {
        match self {
            Dimension::Pressure => &[("Pa", 1.0), ("kPa", 1e3), ("MPa", 1e6), ("GPa", 1e9)],
            Dimension::Length => &[("m", 1.0), ("mm", 1e-3), ("cm", 1e-2), ("km", 1e3)],
            Dimension::Duration => &[
                ("s", 1.0),
                ("ms", 1e-3),
                ("us", 1e-6),
                ("\u{b5}s", 1e-6),
                ("\u{3bc}s", 1e-6),
            ],
            Dimension::Velocity => &[("m/s", 1.0), ("mm/s", 1e-3), ("cm/s", 1e-2)],
            Dimension::Density => &[("kg/m3", 1.0), ("kg/m^3", 1.0)],
        }
    }

    /// Human name of the dimension, for messages.
    pub fn name(self) -> &'static str {
        match self {
            Dimension::Pressure => "pressure",
            Dimension::Length => "length",
            Dimension::Duration => "duration",
            Dimension::Velocity => "velocity",
            Dimension::Density => "density",
        }
    }

    /// The SI unit symbol.
    pub fn si(self) -> &'static str {
        self.units()[0].0
    }

    /// "a pressure: a number (Pa) or a string with one of Pa, kPa, MPa, GPa".
    pub fn expected(self) -> String {
        let list: Vec<&str> = self.units().iter().map(|(u, _)| *u).collect();
        format!(
            "a {}: a number ({}) or a string with one of the units {}",
            self.name(),
            self.si(),
            list.join(", ")
        )
    }
}

/// A quantity that could not be parsed; the message says what was expected.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct UnitError(pub String);

/// Parses `text` as a quantity of dimension `dim` and returns its value in SI units.
///
/// The number part is the longest prefix made of digits, `.`, `e`, `E`, `+`, `-`; the rest,
/// trimmed, is the unit (empty = SI). A value beyond the range of `f64` (`1e400`, or
/// `1e308 GPa` once converted) is an error; range checks of finite values belong to
/// `Config::validate`, which names the field.
pub fn parse_quantity(text: &str, dim: Dimension) -> Result<f64, UnitError> {
    let (value, _) = split_quantity(text, dim, false)?;
    Ok(value)
}

/// Parses `text` as [`parse_quantity`] does but requires a unit: for command-line flags,
/// where a bare number is more likely a forgotten unit than a value in SI units. The error
/// gives an example with a unit.
pub fn parse_with_unit(text: &str, dim: Dimension) -> Result<f64, UnitError> {
    let (value, unit) = split_quantity(text, dim, true)?;
    if !unit {
        let example = match dim {
            Dimension::Pressure => "8MPa or 500kPa",
            Dimension::Length => "7.5m or 30cm",
            Dimension::Duration => "0.5ms or 5e-4s",
            Dimension::Velocity => "0.5m/s or 20mm/s",
            Dimension::Density => "2600kg/m3",
        };
        let list: Vec<&str> = dim.units().iter().map(|(u, _)| *u).collect();
        return Err(UnitError(format!(
            "needs a unit, e.g. {example} (one of {}); a bare number is not taken as {} here",
            list.join(", "),
            dim.si()
        )));
    }
    Ok(value)
}

/// What a quantity that could not be read must be: with `need_unit` (the command line) a
/// number with one of the units; otherwise also a bare number in SI units. A unit that
/// differs from an accepted one only in case is named: units are case-sensitive (`mPa`,
/// millipascal, and `MPa` differ by 1e9).
fn not_a_quantity(text: &str, unit: &str, dim: Dimension, need_unit: bool) -> UnitError {
    let list: Vec<&str> = dim.units().iter().map(|(u, _)| *u).collect();
    let rule = if need_unit {
        format!(
            "a {}: a number with one of the units {} (case-sensitive)",
            dim.name(),
            list.join(", ")
        )
    } else {
        format!("{} (case-sensitive)", dim.expected())
    };
    let hint = list
        .iter()
        .find(|u| u.eq_ignore_ascii_case(unit))
        .map_or(String::new(), |u| format!(": did you mean `{u}`?"));
    UnitError(format!("`{text}` is not {rule}{hint}"))
}

/// The value in SI units, and whether a unit was written (`need_unit`: the error says that
/// a unit is required).
fn split_quantity(text: &str, dim: Dimension, need_unit: bool) -> Result<(f64, bool), UnitError> {
    let s = text.trim();
    let split = s
        .find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | 'e' | 'E' | '+' | '-')))
        .unwrap_or(s.len());
    // "5e-4s" must split as 5e-4 / s, but a trailing 'e' with no exponent belongs to nothing:
    // f64 parsing rejects it below with the full text in the message.
    let (num, unit) = s.split_at(split);
    let unit = unit.trim();
    let bad = || not_a_quantity(text, unit, dim, need_unit);
    let value: f64 = num.parse().map_err(|_| bad())?;
    let (value, has_unit) = if unit.is_empty() {
        (value, false)
    } else {
        let factor = dim
            .units()
            .iter()
            .find(|(u, _)| *u == unit)
            .map(|(_, f)| *f)
            .ok_or_else(bad)?;
        // A sub-unit divides by its exact power of ten, so that "5 us" gives the same bits
        // as "5e-6 s" (5 * 1e-6 does not: 1e-6 is not exact in binary).
        let si = if factor < 1.0 {
            value / (1.0 / factor).round()
        } else {
            value * factor
        };
        (si, true)
    };
    // "inf" and "nan" are not made of the number characters above, so only an overflow
    // gets here non-finite.
    if !value.is_finite() {
        return Err(UnitError(format!(
            "`{text}` is too large: beyond the range of numbers ({:e} {} at most)",
            f64::MAX,
            dim.si()
        )));
    }
    Ok((value, has_unit))
}

/// Defines one newtype per dimension with serde, `FromStr` and `Display` (SI value + unit).
macro_rules! quantity {
    ($(#[$doc:meta])* $name:ident, $dim:expr) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq, PartialOrd, Default)]
        pub struct $name(pub f64);

        impl $name {
            /// The dimension of this quantity.
            pub const DIMENSION: Dimension = $dim;

            /// The value in SI units.
            pub fn si(self) -> f64 {
                self.0
            }
        }

        impl FromStr for $name {
            type Err = UnitError;
            fn from_str(s: &str) -> Result<Self, UnitError> {
                parse_quantity(s, $dim).map($name)
            }
        }

        impl fmt::Display for $name {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                write!(f, "{} {}", self.0, $dim.si())
            }
        }

        impl Serialize for $name {
            fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_f64(self.0)
            }
        }

        impl<'de> Deserialize<'de> for $name {
            fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                d.deserialize_any(QuantityVisitor($dim)).map($name)
            }
        }
    };
}

quantity!(
    /// A pressure or stress in Pa.
    Pressure,
    Dimension::Pressure
);
quantity!(
    /// A length in m.
    Length,
    Dimension::Length
);
quantity!(
    /// A time span in s.
    Duration,
    Dimension::Duration
);
quantity!(
    /// A velocity in m/s.
    Velocity,
    Dimension::Velocity
);
quantity!(
    /// A mass density in kg/m^3.
    Density,
    Dimension::Density
);

/// Accepts a number (SI) or a string with a unit of the given dimension.
struct QuantityVisitor(Dimension);

impl Visitor<'_> for QuantityVisitor {
    type Value = f64;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0.expected())
    }

    fn visit_f64<E: de::Error>(self, v: f64) -> Result<f64, E> {
        Ok(v)
    }

    fn visit_i64<E: de::Error>(self, v: i64) -> Result<f64, E> {
        Ok(v as f64)
    }

    fn visit_u64<E: de::Error>(self, v: u64) -> Result<f64, E> {
        Ok(v as f64)
    }

    fn visit_str<E: de::Error>(self, v: &str) -> Result<f64, E> {
        parse_quantity(v, self.0).map_err(|e| E::custom(e.0))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_units_with_and_without_space() {
        assert_eq!("8MPa".parse::<Pressure>().unwrap().0, 8e6);
        assert_eq!("8 MPa".parse::<Pressure>().unwrap().0, 8e6);
        assert_eq!("500 kPa".parse::<Pressure>().unwrap().0, 5e5);
        assert_eq!("1 GPa".parse::<Pressure>().unwrap().0, 1e9);
        assert_eq!("0.5 m/s".parse::<Velocity>().unwrap().0, 0.5);
        assert_eq!("7.5 m".parse::<Length>().unwrap().0, 7.5);
        assert_eq!("500mm".parse::<Length>().unwrap().0, 0.5);
        assert_eq!("5e-4s".parse::<Duration>().unwrap().0, 5e-4);
        assert_eq!("0.5 ms".parse::<Duration>().unwrap().0, 5e-4);
        assert_eq!("2600 kg/m3".parse::<Density>().unwrap().0, 2600.0);
        assert_eq!("2600 kg/m^3".parse::<Density>().unwrap().0, 2600.0);
        assert_eq!("-3".parse::<Length>().unwrap().0, -3.0);
        assert_eq!(" 42 ".parse::<Pressure>().unwrap().0, 42.0);
    }

    #[test]
    fn rejects_wrong_dimension_and_garbage_naming_the_units() {
        let e = "8 m".parse::<Pressure>().unwrap_err().0;
        assert!(e.contains("pressure") && e.contains("MPa"), "{e}");
        let e = "0.5 m".parse::<Velocity>().unwrap_err().0;
        assert!(e.contains("m/s"), "{e}");
        assert!("8 mpa".parse::<Pressure>().is_err(), "units are case-sensitive");
        assert!("MPa".parse::<Pressure>().is_err());
        assert!("".parse::<Length>().is_err());
        assert!("1e m".parse::<Length>().is_err());
        assert!("nan".parse::<Length>().is_err());
    }

    /// Overflow is an error (it gave infinity); micro, milli and kilo prefixes, both micro
    /// signs and a leading `+` are read with their factors; odd forms are refused.
    #[test]
    fn overflow_prefixes_and_signs() {
        for text in ["1e400 MPa", "1e400", "1e308 GPa", "-1e400 Pa"] {
            let e = text.parse::<Pressure>().unwrap_err().0;
            assert!(e.contains("too large") && e.contains(text), "{text}: {e}");
        }
        assert_eq!("5 us".parse::<Duration>().unwrap().0, 5e-6);
        assert_eq!("5 \u{b5}s".parse::<Duration>().unwrap().0, 5e-6);
        assert_eq!("5\u{3bc}s".parse::<Duration>().unwrap().0, 5e-6);
        assert_eq!("250 mm".parse::<Length>().unwrap().0, 0.25);
        assert_eq!("2 km".parse::<Length>().unwrap().0, 2000.0);
        assert_eq!("+8 MPa".parse::<Pressure>().unwrap().0, 8e6);
        assert_eq!("+5e-4s".parse::<Duration>().unwrap().0, 5e-4);
        for bad in [
            "++8 MPa",
            "8 Mpa",
            "8 M Pa",
            "8 MPa MPa",
            "1.2.3 m",
            "5 Us",
            "inf MPa",
            "8e MPa",
        ] {
            assert!(bad.parse::<Pressure>().is_err(), "{bad} was accepted");
        }
        // Underflow to a subnormal or zero is finite: the range checks refuse it by name.
        assert_eq!("1e-400 s".parse::<Duration>().unwrap().0, 0.0);
    }

    /// A flag's quantity needs its unit: `--sigma3 8` was taken as 8 Pa.
    #[test]
    fn flags_require_a_unit() {
        let e = parse_with_unit("8", Dimension::Pressure).unwrap_err().0;
        assert!(e.contains("needs a unit") && e.contains("8MPa"), "{e}");
        let e = parse_with_unit(" 0.5 ", Dimension::Duration).unwrap_err().0;
        assert!(e.contains("ms"), "{e}");
        assert_eq!(parse_with_unit("8MPa", Dimension::Pressure).unwrap(), 8e6);
        assert_eq!(parse_with_unit("500 kPa", Dimension::Pressure).unwrap(), 5e5);
        assert!(parse_with_unit("8 m", Dimension::Pressure).is_err());
    }

    #[test]
    fn serde_accepts_numbers_and_strings_and_writes_si_numbers() {
        #[derive(Deserialize, Serialize, PartialEq, Debug)]
        struct T {
            p: Pressure,
            l: Length,
        }
        let t: T = toml::from_str("p = \"8 MPa\"\nl = 3").unwrap();
        assert_eq!(
            t,
            T {
                p: Pressure(8e6),
                l: Length(3.0)
            }
        );
        let text = toml::to_string(&t).unwrap();
        assert_eq!(toml::from_str::<T>(&text).unwrap(), t);
        let err = toml::from_str::<T>("p = \"8 m\"\nl = 3").unwrap_err().to_string();
        assert!(err.contains("kPa"), "{err}");
        let j: T = serde_json::from_str(r#"{"p": 1.5e6, "l": "2 cm"}"#).unwrap();
        assert_eq!(
            j,
            T {
                p: Pressure(1.5e6),
                l: Length(0.02)
            }
        );
    }
}
