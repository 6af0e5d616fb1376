//! Local strain per disk between two snapshots: the best-fit affine map of the displacement
//! increments of a disk and its neighbours.
//!
//! For disk i with neighbours j (positions X in the first snapshot, displacements u between
//! the snapshots), the displacement gradient G minimises
//! `sum_j |(u_j - u_i) - G (X_j - X_i)|^2`, so `G = (sum du dX^T) (sum dX dX^T)^-1`
//! (Falk and Langer's construction). The strain is then the Green-Lagrange tensor of
//! `F = I + G`, `E = (G + G^T + G^T G) / 2`, rather than the small-strain `sym(G)`: the
//! increments between snapshots carry finite rotations (a band's disks roll), and only the
//! finite measure gives exactly zero for a rigid rotation.
//!
//! Neighbours are chosen geometrically in the first snapshot, not from its contact list:
//! every disk whose surface gap to disk i is at most `gap_diameters` mean diameters (default
//! 0.5, i.e. centres within 1.5 mean diameters for two disks of mean size). The contact list
//! only holds the few touching disks (coordination about 4 in 2D), which leaves the fit
//! barely overdetermined, and it changes with contact status; a size-aware gap keeps the
//! first shell of a large disk as well as of a small one.

use glam::{DMat2, DVec2};

use crate::error::{Error, Result};
use crate::record::{DiskRecord, Snapshot};

/// The local deformation of one disk over an interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LocalStrain {
    /// Maximum (engineering) shear strain of the Green-Lagrange tensor E,
    /// `sqrt((E_xx - E_yy)^2 + 4 E_xy^2)`: equals gamma for a small simple shear gamma.
    pub shear: f64,
    /// Relative area change of the affine map, `det(I + G) - 1` (positive = dilation).
    pub volumetric: f64,
    /// Non-affine residual D2min: the mean squared misfit per neighbour, divided by the
    /// squared mean diameter (dimensionless).
    pub d2min: f64,
    /// Number of neighbours in the fit.
    pub neighbours: usize,
}

/// How neighbourhoods are chosen and when a fit is refused.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StrainOptions {
    /// Largest surface gap of a neighbour, in mean diameters.
    pub gap_diameters: f64,
    /// Fewest neighbours for a fit (a 2x2 gradient needs 2; 3 leaves a residual).
    pub min_neighbours: usize,
    /// Smallest ratio of the eigenvalues of `sum dX dX^T`: below it the neighbours are
    /// nearly collinear and the fit is unreliable across them.
    pub min_spread: f64,
}

impl Default for StrainOptions {
    fn default() -> Self {
        StrainOptions {
            gap_diameters: 0.5,
            min_neighbours: 3,
            min_spread: 0.01,
        }
    }
}

/// Number-mean diameter (m) of the disks with a finite positive radius; `None` if none.
pub fn mean_diameter(disks: &[DiskRecord]) -> Option<f64> {
    let (sum, n) = disks
        .iter()
        .filter(|d| d.r.is_finite() && d.r > 0.0)
        .fold((0.0, 0usize), |(s, n), d| (s + 2.0 * d.r, n + 1));
    (n > 0).then(|| sum / n as f64)
}

fn usable(d: &DiskRecord) -> bool {
    d.x.is_finite() && d.y.is_finite() && d.r.is_finite() && d.r > 0.0
}

/// Checks that two snapshots describe the same disks (count and radii), as the displacement
/// increment of disk k is only meaningful then.
pub fn check_pair(a: &Snapshot, b: &Snapshot) -> Result<()> {
    if a.disks.len() != b.disks.len() {
        return Err(Error::BandAnalysis(format!(
            "snapshots at strain {:.4} and {:.4} hold {} and {} disks: not the same sample",
            a.strain,
            b.strain,
            a.disks.len(),
            b.disks.len()
        )));
    }
    if let Some(k) = (0..a.disks.len()).find(|&k| a.disks[k].r != b.disks[k].r) {
        return Err(Error::BandAnalysis(format!(
            "disk {k} has radius {} m at strain {:.4} and {} m at strain {:.4}: not the same sample",
            a.disks[k].r, a.strain, b.disks[k].r, b.strain
        )));
    }
    Ok(())
}

/// Neighbour lists of the usable disks: surface gap at most `gap` (m). A cell grid keeps it
/// linear in the number of disks.
pub fn neighbours(disks: &[DiskRecord], gap: f64) -> Vec<Vec<usize>> {
    let n = disks.len();
    let mut out = vec![Vec::new(); n];
    let ok: Vec<usize> = (0..n).filter(|&k| usable(&disks[k])).collect();
    if ok.is_empty() {
        return out;
    }
    let r_max = ok.iter().map(|&k| disks[k].r).fold(0.0, f64::max);
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for &k in &ok {
        let p = DVec2::new(disks[k].x, disks[k].y);
        lo = lo.min(p);
        hi = hi.max(p);
    }
    // Any neighbour pair is within one cell of each other; a sparse cloud over a huge box
    // gets larger cells rather than a grid with more cells than disks.
    let span = (hi - lo).max(DVec2::splat(1e-12));
    let mut cell = (2.0 * r_max + gap).max(1e-12);
    while (span.x / cell + 1.0) * (span.y / cell + 1.0) > 4.0 * ok.len() as f64 + 16.0 {
        cell *= 2.0;
    }
    let nx = (span.x / cell) as usize + 1;
    let ny = (span.y / cell) as usize + 1;
    let index = |p: DVec2| {
        let c = ((p - lo) / cell).floor();
        ((c.x as usize).min(nx - 1), (c.y as usize).min(ny - 1))
    };
    let mut cells: Vec<Vec<usize>> = vec![Vec::new(); nx * ny];
    for &k in &ok {
        let (cx, cy) = index(DVec2::new(disks[k].x, disks[k].y));
        cells[cy * nx + cx].push(k);
    }
    for &i in &ok {
        let pi = DVec2::new(disks[i].x, disks[i].y);
        let (cx, cy) = index(pi);
        for gy in cy.saturating_sub(1)..=(cy + 1).min(ny - 1) {
            for gx in cx.saturating_sub(1)..=(cx + 1).min(nx - 1) {
                for &j in &cells[gy * nx + gx] {
                    if j == i {
                        continue;
                    }
                    let pj = DVec2::new(disks[j].x, disks[j].y);
                    if pi.distance(pj) - disks[i].r - disks[j].r <= gap {
                        out[i].push(j);
                    }
                }
            }
        }
        out[i].sort_unstable();
    }
    out
}

/// Strain measures of a displacement gradient G: (shear, volumetric).
pub fn strain_of_gradient(g: DMat2) -> (f64, f64) {
    let e = 0.5 * (g + g.transpose() + g.transpose() * g);
    let (exx, eyy, exy) = (e.x_axis.x, e.y_axis.y, e.y_axis.x);
    let shear = ((exx - eyy).powi(2) + 4.0 * exy * exy).sqrt();
    let volumetric = (DMat2::IDENTITY + g).determinant() - 1.0;
    (shear, volumetric)
}

/// The local strain of every disk between snapshots `a` and `b` (same disks, `a` first).
/// Disks with a non-finite state, too few neighbours or collinear neighbours get `None`.
/// Errors when the snapshots do not hold the same disks or no disk has a valid radius.
pub fn local_strain(a: &Snapshot, b: &Snapshot, opts: &StrainOptions) -> Result<Vec<Option<LocalStrain>>> {
    check_pair(a, b)?;
    let d_mean = mean_diameter(&a.disks)
        .ok_or_else(|| Error::BandAnalysis("no disk with a finite positive radius in the snapshot".into()))?;
    let nbrs = neighbours(&a.disks, opts.gap_diameters * d_mean);
    let pos = |d: &DiskRecord| DVec2::new(d.x, d.y);
    // The increment is the change of position, which during the compression is exactly the
    // change of the recorded displacement (dx, dy) and needs no reference state.
    let disp: Vec<Option<DVec2>> = (0..a.disks.len())
        .map(|k| {
            let u = pos(&b.disks[k]) - pos(&a.disks[k]);
            (usable(&a.disks[k]) && u.is_finite()).then_some(u)
        })
        .collect();
    Ok((0..a.disks.len())
        .map(|i| {
            let ui = disp[i]?;
            let xi = pos(&a.disks[i]);
            let pairs: Vec<(DVec2, DVec2)> = nbrs[i]
                .iter()
                .filter_map(|&j| Some((pos(&a.disks[j]) - xi, disp[j]? - ui)))
                .collect();
            fit(&pairs, opts, d_mean)
        })
        .collect())
}

/// Least-squares gradient of `pairs` (relative position, relative displacement).
fn fit(pairs: &[(DVec2, DVec2)], opts: &StrainOptions, d_mean: f64) -> Option<LocalStrain> {
    if pairs.len() < opts.min_neighbours.max(2) {
        return None;
    }
    let (mut xx, mut ux) = (DMat2::ZERO, DMat2::ZERO);
    for &(dx, du) in pairs {
        xx += outer(dx, dx);
        ux += outer(du, dx);
    }
    // Eigenvalues of the symmetric 2x2 spread matrix, for the collinearity test.
    let (a, b, c) = (xx.x_axis.x, xx.y_axis.y, xx.y_axis.x);
    let mid = 0.5 * (a + b);
    let rad = (0.25 * (a - b).powi(2) + c * c).sqrt();
    let (l_min, l_max) = (mid - rad, mid + rad);
    if !(l_max > 0.0 && l_min > opts.min_spread * l_max) {
        return None;
    }
    let g = ux * xx.inverse();
    let misfit: f64 = pairs.iter().map(|&(dx, du)| (du - g * dx).length_squared()).sum();
    let (shear, volumetric) = strain_of_gradient(g);
    let d2min = misfit / pairs.len() as f64 / (d_mean * d_mean);
    [shear, volumetric, d2min]
        .iter()
        .all(|v| v.is_finite())
        .then_some(LocalStrain {
            shear,
            volumetric,
            d2min,
            neighbours: pairs.len(),
        })
}

/// The matrix `u v^T`.
fn outer(u: DVec2, v: DVec2) -> DMat2 {
    // glam matrices are column-major: column k is u * v[k].
    DMat2::from_cols(u * v.x, u * v.y)
}

/// The local shear strain of every disk between `a` and `b` with the default options
/// (`None` where there is no value), e.g. to colour disks in a rendering.
pub fn local_shear(a: &Snapshot, b: &Snapshot) -> Result<Vec<Option<f64>>> {
    Ok(local_strain(a, b, &StrainOptions::default())?
        .into_iter()
        .map(|s| s.map(|s| s.shear))
        .collect())
}
