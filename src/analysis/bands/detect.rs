//! Band detection from a field of local shear strain: orientation and width.
//!
//! For each candidate angle theta from the axial (y) direction, disk centres are projected
//! on the normal of the direction `t = (sin theta, cos theta)` and binned (bins of
//! `bin_diameters` mean diameters); the profile is the mean shear strain per bin. A band
//! along t shows as a peak of that profile: aligned bins lie inside or outside the band,
//! while at a wrong angle every bin crosses the band and the profile flattens. The band
//! angle is the one whose profile peak stands highest above the background (the median of
//! the profile), scanned separately on each side of the axis so that conjugate bands are
//! both found. Its width is the full width at half maximum of that peak above the
//! background. Its contrast, `(peak - background) / (peak + background)`, is 0 for a
//! uniform field and 1 for a band in an undeformed sample. Noise alone makes peaks too (the
//! scan keeps the best of many angles and bins), so each candidate's strength, its peak
//! area `(peak - background) x width`, is compared with the largest one found in the same
//! values shuffled among the disks ([`null_strength`]): a side reports a band only when it
//! stands above that chance level and its contrast reaches `min_contrast`. The area, not
//! the contrast, is compared: a chance spike is one bin wide, and where the background is
//! exactly 0 (synthetic fields) any spike has contrast 1.

use glam::DVec2;

/// Settings of the detection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DetectOptions {
    /// Angle step of the scan (degrees).
    pub angle_step_deg: f64,
    /// Bin width of the profiles, in mean diameters.
    pub bin_diameters: f64,
    /// Fewest disks in a bin of the profile.
    pub min_bin_count: usize,
    /// Bins with fewer disks than this fraction of the fullest bin are left out: they cut
    /// a corner of the sample and average too few disks.
    pub min_bin_fraction: f64,
    /// Smallest contrast reported as a band.
    pub min_contrast: f64,
    /// Shuffles of the values for [`null_strength`] (0: no chance level).
    pub null_shuffles: usize,
}

impl Default for DetectOptions {
    fn default() -> Self {
        DetectOptions {
            angle_step_deg: 1.0,
            bin_diameters: 1.0,
            min_bin_count: 3,
            min_bin_fraction: 0.5,
            min_contrast: 0.3,
            null_shuffles: 20,
        }
    }
}

/// The strongest band candidate of one side of the axis.
#[derive(Clone, Debug, PartialEq)]
pub struct Candidate {
    /// Angle of the band direction from the axial (y) direction (degrees), in (-90, 90):
    /// positive when the band rises towards +x.
    pub angle_deg: f64,
    /// Full width at half maximum of the profile peak (m).
    pub width_m: f64,
    /// `(peak - background) / (peak + background)`, in [0, 1].
    pub contrast: f64,
    /// Local shear strain of the profile's peak bin.
    pub peak_shear: f64,
    /// Median of the profile (the shear strain outside the band).
    pub background_shear: f64,
    /// `(peak - background) x width_m` (m): what is compared with the chance level.
    pub strength_m: f64,
    /// Mean centre of the disks of the peak bin (m): a point on the band's axis.
    pub centre_m: DVec2,
    /// The profile falls to half maximum on both sides of the peak (a band across the
    /// sample, not a layer along its edge).
    pub closed: bool,
}

/// One profile bin kept: centre along the normal, shear, mean disk centre.
struct Bin {
    p: f64,
    mean: f64,
    centre: DVec2,
}

/// The binned profile of `points` (centre, shear) across direction `theta_deg`: the median
/// shear of each bin, smoothed over neighbouring bins with weights (1/4, 1/2, 1/4).
///
/// The median, not the mean: a rattler or a disk at the free edge of the strips gets a
/// local strain many times the band's, and one of them would make a single-bin spike of
/// a bin mean. The smoothing removes what is left of single-bin spikes; a symmetric kernel
/// narrower than the band leaves its full width at half maximum unchanged.
fn profile(points: &[(DVec2, f64)], theta_deg: f64, bin: f64, opts: &DetectOptions) -> Vec<Bin> {
    let th = theta_deg.to_radians();
    let n = DVec2::new(th.cos(), -th.sin());
    let proj: Vec<f64> = points.iter().map(|(x, _)| n.dot(*x)).collect();
    let lo = proj.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = proj.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let nb = (((hi - lo) / bin).ceil() as usize).clamp(1, 1_000_000);
    let mut values: Vec<Vec<f64>> = vec![Vec::new(); nb];
    let mut pos = vec![DVec2::ZERO; nb];
    for (k, &p) in proj.iter().enumerate() {
        let b = (((p - lo) / bin) as usize).min(nb - 1);
        values[b].push(points[k].1);
        pos[b] += points[k].0;
    }
    let full = values.iter().map(Vec::len).max().unwrap_or(0) as f64;
    let need = (opts.min_bin_count.max(1) as f64).max(opts.min_bin_fraction * full);
    let kept: Vec<Bin> = values
        .iter_mut()
        .zip(&pos)
        .enumerate()
        .filter(|(_, (v, _))| v.len() as f64 >= need)
        .map(|(b, (v, c))| Bin {
            p: lo + (b as f64 + 0.5) * bin,
            centre: *c / v.len() as f64,
            mean: median(v),
        })
        .collect();
    (0..kept.len())
        .map(|k| {
            let (mut sum, mut weight) = (0.5 * kept[k].mean, 0.5);
            for j in [k.wrapping_sub(1), k + 1] {
                if let Some(b) = kept.get(j) {
                    sum += 0.25 * b.mean;
                    weight += 0.25;
                }
            }
            Bin {
                p: kept[k].p,
                mean: sum / weight,
                centre: kept[k].centre,
            }
        })
        .collect()
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let m = v.len() / 2;
    if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    }
}

/// The candidate of one profile, and its score (the peak's excess over the background).
/// `scale` is the largest shear of the field.
fn candidate(bins: &[Bin], theta_deg: f64, scale: f64) -> Option<(f64, Candidate)> {
    if bins.len() < 3 {
        return None;
    }
    let background = median(&mut bins.iter().map(|b| b.mean).collect::<Vec<_>>());
    let (k, peak) = bins
        .iter()
        .enumerate()
        .map(|(k, b)| (k, b.mean))
        .max_by(|a, b| a.1.total_cmp(&b.1))?;
    let half = background + 0.5 * (peak - background);
    // The half-maximum crossing between bins k0 (below) and k1 (above), linearly.
    let cross = |k0: usize, k1: usize| {
        let (a, b) = (&bins[k0], &bins[k1]);
        a.p + (half - a.mean) / (b.mean - a.mean) * (b.p - a.p)
    };
    let left = (0..k)
        .rev()
        .find(|&j| bins[j].mean < half)
        .map(|j| cross(j, j + 1));
    let right = (k + 1..bins.len())
        .find(|&j| bins[j].mean < half)
        .map(|j| cross(j, j - 1));
    let closed = left.is_some() && right.is_some();
    let width_m = right.unwrap_or(bins[bins.len() - 1].p) - left.unwrap_or(bins[0].p);
    // A peak within round-off of the background (a rigid region's 1e-16 strains next to
    // exact zeros) is no contrast at all, however small the background.
    let contrast = if peak - background > 1e-9 * scale {
        ((peak - background) / (peak + background)).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let c = Candidate {
        angle_deg: theta_deg,
        width_m,
        contrast,
        peak_shear: peak,
        background_shear: background,
        strength_m: (peak - background) * width_m,
        centre_m: bins[k].centre,
        closed,
    };
    [width_m, contrast, peak, background]
        .iter()
        .all(|v| v.is_finite())
        .then_some((peak - background, c))
}

/// The strongest candidate on each side of the axis: `[rising towards +x, towards -x]`.
/// Only profiles whose peak is closed on both sides compete; a side without any has `None`.
/// `points` are (disk centre, local shear strain); `d_mean` is the mean diameter (m).
pub fn scan(points: &[(DVec2, f64)], d_mean: f64, opts: &DetectOptions) -> [Option<Candidate>; 2] {
    let bin = opts.bin_diameters * d_mean;
    if points.len() < 3 || !(bin > 0.0 && bin.is_finite()) {
        return [None, None];
    }
    let step = opts.angle_step_deg.clamp(0.01, 45.0);
    let n = (90.0 / step).ceil() as usize;
    let scale = points.iter().map(|p| p.1.abs()).fold(0.0, f64::max);
    let side = |sign: f64| {
        (1..n)
            .map(|k| sign * k as f64 * step)
            .filter_map(|th| candidate(&profile(points, th, bin, opts), th, scale))
            .filter(|(_, c)| c.closed)
            .max_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, c)| c)
    };
    [side(1.0), side(-1.0)]
}

/// The significance of a candidate: its strength over the chance level `null`
/// ([`null_strength`]); capped at 1e6 (a chance level of 0, e.g. a uniform field).
pub fn significance(c: &Candidate, null: f64) -> f64 {
    if c.strength_m <= 0.0 {
        0.0
    } else if c.strength_m >= 1e6 * null {
        1e6
    } else {
        c.strength_m / null
    }
}

/// Whether a candidate counts as a band: contrast at least `min_contrast`, significance
/// above 1, and an angle inside the scan (a best angle at the first or last step is the
/// tail of a band lying outside that side's range, e.g. a conjugate's reflection near the
/// axis).
pub fn is_band(c: &Candidate, opts: &DetectOptions, null: f64) -> bool {
    let step = opts.angle_step_deg.clamp(0.01, 45.0);
    let a = c.angle_deg.abs();
    c.contrast >= opts.min_contrast && significance(c, null) > 1.0 && a > 1.5 * step && a < 90.0 - 1.5 * step
}

/// The strength a field without bands reaches by chance: the largest strength of the best
/// candidates found in `opts.null_shuffles` copies of `points` whose shear values are
/// randomly permuted among the disk centres (same values, same positions, no spatial
/// order). Deterministic (fixed seed).
pub fn null_strength(points: &[(DVec2, f64)], d_mean: f64, opts: &DetectOptions) -> f64 {
    let mut state: u64 = 0x5EED_BA4D_5EED_BA4D;
    let mut next = move || {
        // SplitMix64: enough to decorrelate values from positions.
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let mut shuffled = points.to_vec();
    let mut worst: f64 = 0.0;
    for _ in 0..opts.null_shuffles {
        for k in (1..shuffled.len()).rev() {
            let j = (next() % (k as u64 + 1)) as usize;
            let v = shuffled[k].1;
            shuffled[k].1 = shuffled[j].1;
            shuffled[j].1 = v;
        }
        for c in scan(&shuffled, d_mean, opts).into_iter().flatten() {
            worst = worst.max(c.strength_m);
        }
    }
    worst
}
