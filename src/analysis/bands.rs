//! Shear bands from a run's snapshots: local strain per disk, band orientation against the
//! axial direction and band width in mean diameters.
//!
//! - [`strain`]: the local strain of each disk between two snapshots (best-fit affine
//!   deformation of a disk and its neighbours; shear, volumetric, D2min);
//! - [`detect`]: the band angle(s) and width from the profiles of that field;
//! - this file: which interval of the run is analysed, and the report (`shear_bands` in
//!   `summary.json`, `cdlab bands RUN`).
//!
//! The interval is, by default, the last two snapshots of the run (snapshots are written
//! during the compression only, every `output.snapshot_every` of axial strain): the bands
//! active at the end of the test. A caller may give a strain window instead; each end then
//! takes the recorded snapshot nearest in strain, and the report gives the strains actually
//! used.

pub mod detect;
pub mod strain;

pub use detect::{Candidate, DetectOptions};
pub use strain::{LocalStrain, StrainOptions, local_shear, local_strain, mean_diameter};

// The report's types are measurements of one run (a test's summary holds them); this
// module computes them from the run's snapshots.
pub use crate::measure::bands::{Band, ShearBands};

use crate::error::{Error, Result};
use crate::record::{RunRecord, Snapshot};

/// Settings of the whole analysis.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BandOptions {
    /// Local strain: neighbourhoods and refused fits.
    pub strain: StrainOptions,
    /// Detection: scan, bins, contrast threshold.
    pub detect: DetectOptions,
}

/// The indices of the interval's snapshots in `snaps`: the last two by default; with a
/// window, the snapshot nearest in strain to each given end (the start defaults to the
/// first snapshot, the end to the last).
pub fn select(snaps: &[Snapshot], from: Option<f64>, to: Option<f64>) -> Result<(usize, usize)> {
    let n = snaps.len();
    if n < 2 {
        return Err(Error::BandAnalysis(format!(
            "the run holds {n} snapshot(s); the shear-band analysis needs two \
             (set output.snapshot_every > 0 and run past one interval)"
        )));
    }
    for (name, v) in [("--from", from), ("--to", to)] {
        match v {
            Some(v) if !v.is_finite() => return Err(Error::invalid(name, v, "a finite axial strain")),
            _ => {}
        }
    }
    if from.is_none() && to.is_none() {
        return Ok((n - 2, n - 1));
    }
    let nearest = |s: f64| {
        (0..n)
            .min_by(|&a, &b| {
                (snaps[a].strain - s)
                    .abs()
                    .total_cmp(&(snaps[b].strain - s).abs())
            })
            .unwrap_or(0)
    };
    let a = from.map_or(0, nearest);
    let b = to.map_or(n - 1, nearest);
    if snaps[a].strain >= snaps[b].strain {
        let have: Vec<String> = snaps.iter().map(|s| format!("{:.4}", s.strain)).collect();
        return Err(Error::BandAnalysis(format!(
            "the strain window selects the snapshots at strain {:.4} and {:.4}: they must be \
             two snapshots in increasing strain (recorded: {})",
            snaps[a].strain,
            snaps[b].strain,
            have.join(", ")
        )));
    }
    Ok((a, b))
}

fn band(c: &Candidate, d_mean: f64, null: f64) -> Band {
    Band {
        angle_deg: c.angle_deg,
        width_diameters: c.width_m / d_mean,
        contrast: c.contrast,
        significance: detect::significance(c, null),
        peak_shear: c.peak_shear,
        background_shear: c.background_shear,
        centre_x_m: c.centre_m.x,
        centre_y_m: c.centre_m.y,
    }
}

/// The shear bands between snapshots `a` and `b` (same disks, `a` first).
pub fn analyse_pair(a: &Snapshot, b: &Snapshot, opts: &BandOptions) -> Result<ShearBands> {
    analyse_strain(a, b, &local_strain(a, b, &opts.strain)?, opts)
}

/// The shear bands of `local`, the local strain of each disk between snapshots `a` and `b`
/// ([`local_strain`]), for a caller that needs that field too.
pub fn analyse_strain(
    a: &Snapshot,
    b: &Snapshot,
    local: &[Option<LocalStrain>],
    opts: &BandOptions,
) -> Result<ShearBands> {
    let d_mean = mean_diameter(&a.disks)
        .ok_or_else(|| Error::BandAnalysis("no disk with a finite positive radius in the snapshot".into()))?;
    let points: Vec<(glam::DVec2, f64)> = local
        .iter()
        .zip(&a.disks)
        .filter_map(|(s, d)| s.map(|s| (glam::DVec2::new(d.x, d.y), s.shear)))
        .collect();
    if points.len() < 10 {
        return Err(Error::BandAnalysis(format!(
            "only {} of {} disks have a local strain value (10 needed for a band profile)",
            points.len(),
            a.disks.len()
        )));
    }
    let shear_mean = points.iter().map(|p| p.1).sum::<f64>() / points.len() as f64;
    let null = detect::null_strength(&points, d_mean, &opts.detect);
    let (mut bands, mut rejected) = (Vec::new(), Vec::new());
    for c in detect::scan(&points, d_mean, &opts.detect).into_iter().flatten() {
        if detect::is_band(&c, &opts.detect, null) {
            bands.push(band(&c, d_mean, null));
        } else {
            rejected.push(band(&c, d_mean, null));
        }
    }
    Ok(ShearBands {
        strain_from: a.strain,
        strain_to: b.strain,
        mean_diameter_m: d_mean,
        disks: a.disks.len(),
        disks_with_value: points.len(),
        shear_mean,
        min_contrast: opts.detect.min_contrast,
        null_strength_m: null,
        bands,
        rejected,
    })
}

/// The shear bands of a recorded run over the interval [`select`] picks.
pub fn analyse_run(
    rec: &RunRecord,
    from: Option<f64>,
    to: Option<f64>,
    opts: &BandOptions,
) -> Result<ShearBands> {
    let (a, b) = select(&rec.snapshots, from, to)?;
    analyse_pair(&rec.snapshots[a], &rec.snapshots[b], opts)
}
