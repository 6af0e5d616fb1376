//! Grain size distribution: radii uniform by area (weight) between r_min and r_max.
//!
//! The area-weighted CDF is linear in r, so the number density is proportional to 1/r^2
//! and the inverse CDF is `r = 1 / (1/r_min - u (1/r_min - 1/r_max))` (docs/protocol.md, "Grain sizes").

use super::rng::SplitMix64;
use crate::error::{Error, Result, check_positive};

/// Draws `n` radii uniform by area in [r_min, r_max] from `seed`.
pub fn sample_radii(n: usize, r_min: f64, r_max: f64, seed: u64) -> Result<Vec<f64>> {
    if n == 0 {
        return Err(Error::invalid("sample.disks", n, "must be >= 1"));
    }
    check_positive("sample.r_min", r_min)?;
    if !(r_max.is_finite() && r_max >= r_min) {
        return Err(Error::invalid(
            "sample.r_max",
            r_max,
            &format!("must be finite and >= sample.r_min = {r_min}"),
        ));
    }
    let mut rng = SplitMix64::new(seed);
    let (a, b) = (1.0 / r_min, 1.0 / r_min - 1.0 / r_max);
    Ok((0..n).map(|_| 1.0 / (a - rng.uniform() * b)).collect())
}

/// Diameters D10 and D60 by area of a set of radii (m): the diameters below which 10% and
/// 60% of the total disk area lies.
pub fn d10_d60(radii: &[f64]) -> (f64, f64) {
    let mut r: Vec<f64> = radii.to_vec();
    r.sort_by(f64::total_cmp);
    let total: f64 = r.iter().map(|x| x * x).sum();
    let mut acc = 0.0;
    let (mut d10, mut d60) = (f64::NAN, f64::NAN);
    for x in &r {
        acc += x * x;
        if d10.is_nan() && acc >= 0.1 * total {
            d10 = 2.0 * x;
        }
        if d60.is_nan() && acc >= 0.6 * total {
            d60 = 2.0 * x;
            break;
        }
    }
    (d10, d60)
}

/// Exact D_p by area of the distribution (m): the area CDF `(r - r_min) / (r_max - r_min)`
/// reaches `p` at `r = r_min + p (r_max - r_min)`.
pub fn d_by_area(p: f64, r_min: f64, r_max: f64) -> f64 {
    2.0 * (r_min + p * (r_max - r_min))
}

/// Mean disk area of the distribution (m^2): `pi E[r^2] = pi r_min r_max` for a number
/// density proportional to 1/r^2.
pub fn mean_area(r_min: f64, r_max: f64) -> f64 {
    std::f64::consts::PI * r_min * r_max
}
