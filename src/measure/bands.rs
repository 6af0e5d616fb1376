//! The shear bands of one interval of a run, as a test's summary reports them
//! (`shear_bands` in `summary.json`); `crate::analysis::bands` finds them in the run's
//! snapshots.

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
