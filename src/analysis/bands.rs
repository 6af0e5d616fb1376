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

/// One band (or the best candidate of one side of the axis, when it is not a band).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Band {
    /// Angle between the band and the axial (vertical) direction (degrees), in (-90, 90):
    /// positive when the band rises towards +x, negative towards -x.
    pub angle_deg: f64,
    /// Full width at half maximum of the shear-strain profile across the band, in mean
    /// diameters.
    pub width_diameters: f64,
    /// `(peak - background) / (peak + background)` of that profile, in [0, 1]: 0 for a
    /// uniform field, 1 for a band in an undeformed sample.
    pub contrast: f64,
    /// The band's strength `(peak - background) x width` over the chance level
    /// `null_strength_m` of the report: above 1 for a band; capped at 1e6.
    pub significance: f64,
    /// Local shear strain of the profile's peak bin (over the interval).
    pub peak_shear: f64,
    /// Median of the profile: the shear strain outside the band (over the interval).
    pub background_shear: f64,
    /// A point on the band's axis (m): the mean centre of the disks of the peak bin.
    pub centre_x_m: f64,
    /// See `centre_x_m`.
    pub centre_y_m: f64,
}

/// The shear-band report of one interval of a run.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ShearBands {
    /// Axial strain of the interval's first snapshot.
    pub strain_from: f64,
    /// Axial strain of the interval's last snapshot.
    pub strain_to: f64,
    /// Number-mean disk diameter (m), the unit of the widths.
    pub mean_diameter_m: f64,
    /// Disks in the snapshots.
    pub disks: usize,
    /// Disks with a local strain value (the others have too few or collinear neighbours).
    pub disks_with_value: usize,
    /// Mean local shear strain over the disks with a value (over the interval).
    pub shear_mean: f64,
    /// Contrast below which a side reports no band.
    pub min_contrast: f64,
    /// The chance level of a band's strength `(peak - background) x width` (m): the largest
    /// one found when the same local strain values are shuffled among the disks (no spatial
    /// order). Each band's `significance` is its strength over this.
    pub null_strength_m: f64,
    /// The bands found: none, one, or two conjugate bands (one per side of the axis).
    pub bands: Vec<Band>,
    /// The best candidate of each side that is not a band (contrast below `min_contrast`
    /// or significance at most 1, or angle at the end of the scan), so a reader can judge
    /// how close it came.
    pub rejected: Vec<Band>,
}

/// The indices of the interval's snapshots in `snaps`: the last two by default; with a
/// window, the snapshot nearest in strain to each given end (the start defaults to the
/// first snapshot, the end to the last).
pub fn select(snaps: &[Snapshot], from: Option<f64>, to: Option<f64>) -> Result<(usize, usize)> {
    let n = snaps.len();
    if n < 2 {
        return Err(Error::Other(format!(
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
        return Err(Error::Other(format!(
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
        .ok_or_else(|| Error::Other("no disk with a finite positive radius in the snapshot".into()))?;
    let points: Vec<(glam::DVec2, f64)> = local
        .iter()
        .zip(&a.disks)
        .filter_map(|(s, d)| s.map(|s| (glam::DVec2::new(d.x, d.y), s.shear)))
        .collect();
    if points.len() < 10 {
        return Err(Error::Other(format!(
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

impl ShearBands {
    /// A human-readable table (every number with its unit).
    pub fn table(&self) -> String {
        let mut s = format!(
            "  interval: axial strain {:.4} -> {:.4}; mean diameter {:.3} m; {} of {} disks \
             with a local strain; mean local shear strain {:.4}\n",
            self.strain_from,
            self.strain_to,
            self.mean_diameter_m,
            self.disks_with_value,
            self.disks,
            self.shear_mean
        );
        s.push_str(&format!(
            "  {:<10} {:>12} {:>18} {:>9} {:>13} {:>12} {:>12} {:>20}\n",
            "",
            "angle (deg)",
            "width (diameters)",
            "contrast",
            "significance",
            "peak shear",
            "background",
            "centre (m)"
        ));
        let mut row = |what: &str, b: &Band| {
            s.push_str(&format!(
                "  {what:<10} {:>+12.1} {:>18.2} {:>9.3} {:>13.2} {:>12.4} {:>12.4} {:>20}\n",
                b.angle_deg,
                b.width_diameters,
                b.contrast,
                b.significance,
                b.peak_shear,
                b.background_shear,
                format!("({:.2}, {:.2})", b.centre_x_m, b.centre_y_m)
            ));
        };
        for b in &self.bands {
            row("band", b);
        }
        for b in &self.rejected {
            row("no band", b);
        }
        s.push_str(&format!(
            "  angle from the axial (vertical) direction, + rising towards +x; contrast = \
             (peak - background) / (peak + background), needs >= {:.2}; significance = \
             (peak - background) x width over its chance level {:.3e} m (shuffled values), \
             needs > 1; {}\n",
            self.min_contrast,
            self.null_strength_m,
            match self.bands.len() {
                0 => "no band found".to_string(),
                1 => "one band".to_string(),
                n => format!("{n} conjugate bands"),
            }
        ));
        s
    }
}
