//! Sample preparation: grain sizes, geometric deposition, and the figures that describe a
//! packing (packing fraction, coordination, D10/D60).

pub mod deposit;
pub mod psd;
pub mod rng;

pub use deposit::{Packing, deposit};
pub use psd::{d_by_area, d10_d60, mean_area, sample_radii};

use crate::error::Result;

/// Packing fraction assumed for a fresh deposit when sizing its box (what deposits of the
/// paper's distribution reach: docs/protocol.md, "Deposition").
pub const DEPOSIT_PACKING: f64 = 0.84;

/// Width of the deposition box (m) such that `n` disks of the distribution fill a sample of
/// height / width `aspect` at the deposit's packing fraction: `W = sqrt(n <A> / (phi aspect))`.
pub fn box_width_for(n: usize, r_min: f64, r_max: f64, aspect: f64) -> f64 {
    (n as f64 * mean_area(r_min, r_max) / (DEPOSIT_PACKING * aspect)).sqrt()
}

/// Deposits `n` disks sampled from `seed` into a box of the given width.
pub fn deposit_sample(n: usize, r_min: f64, r_max: f64, width: f64, seed: u64) -> Result<Packing> {
    deposit(&sample_radii(n, r_min, r_max, seed)?, width)
}

/// Area of the part of a disk of radius `r` whose height relative to its centre is below
/// `h` (circle segment): `r^2 acos(-h/r) + h sqrt(r^2 - h^2)`.
fn below(r: f64, h: f64) -> f64 {
    let h = h.clamp(-r, r);
    r * r * (-h / r).acos() + h * (r * r - h * h).sqrt()
}

/// Packing fraction in the band `y_lo <= y <= y_hi` across the whole box: the exact area of
/// the disks inside the band over the band's area. Choose a band away from the floor and
/// the free surface, where the packing is bulk-like.
pub fn packing_fraction(pk: &Packing, y_lo: f64, y_hi: f64) -> f64 {
    let area: f64 = pk
        .centers
        .iter()
        .zip(&pk.radii)
        .map(|(c, &r)| below(r, y_hi - c.y) - below(r, y_lo - c.y))
        .sum();
    area / (pk.width * (y_hi - y_lo))
}

/// Mean number of disk neighbours touching each disk (gap <= `tol` times the smallest
/// radius), walls and floor not counted.
pub fn geometric_coordination(pk: &Packing, tol: f64) -> f64 {
    let n = pk.centers.len();
    if n == 0 {
        return 0.0;
    }
    let r_min = pk.radii.iter().cloned().fold(f64::INFINITY, f64::min);
    let mut grid = crate::contact::detect::CellGrid::default();
    let r_max = pk.radii.iter().cloned().fold(0.0, f64::max);
    if grid.build(&pk.centers, 2.0 * r_max + tol * r_min).is_err() {
        return f64::NAN;
    }
    let mut pairs = 0usize;
    for p in 0..n {
        grid.for_neighbours(p, |q| {
            if q > p && (pk.centers[p] - pk.centers[q]).length() - pk.radii[p] - pk.radii[q] <= tol * r_min {
                pairs += 1;
            }
        });
    }
    2.0 * pairs as f64 / n as f64
}

/// Largest overlap between two disks of the packing (m; 0 when none).
pub fn max_overlap(pk: &Packing) -> f64 {
    let n = pk.centers.len();
    let r_max = pk.radii.iter().cloned().fold(0.0, f64::max);
    let mut grid = crate::contact::detect::CellGrid::default();
    if grid.build(&pk.centers, 2.0 * r_max).is_err() {
        return f64::NAN;
    }
    let mut worst = 0.0f64;
    for p in 0..n {
        grid.for_neighbours(p, |q| {
            if q > p {
                let gap = (pk.centers[p] - pk.centers[q]).length() - pk.radii[p] - pk.radii[q];
                worst = worst.max(-gap);
            }
        });
    }
    worst
}
