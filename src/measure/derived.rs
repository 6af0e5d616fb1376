//! Results derived from a test's stress-strain curve (docs/protocol.md, "Derived results").

use super::SeriesRow;

/// The strength figures of one test.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Strength {
    /// Peak of sigma_1 averaged over a moving strain window (Pa).
    pub sigma1_peak_pa: f64,
    /// Axial strain at the centre of the peak window.
    pub strain_peak: f64,
    /// Mean sigma_1 over the residual strain range (Pa); NaN if the test stopped before the
    /// end of that range (see [`residual`]).
    pub sigma1_residual_pa: f64,
    /// Confining stress (Pa).
    pub sigma3_pa: f64,
    /// Mohr-Coulomb friction angle at the peak, through the origin (degrees):
    /// `sin(phi) = (s1 - s3) / (s1 + s3)`.
    pub phi_peak_deg: f64,
    /// The same at the residual (degrees).
    pub phi_residual_deg: f64,
    /// Volumetric strain at the end (positive = dilation).
    pub volumetric_strain_final: f64,
}

/// Mean of `sigma1` over every strain window `[e, e + window]` of the compression rows, and
/// the largest such mean with its window centre. Rows must be in increasing strain.
pub fn moving_peak(rows: &[SeriesRow], window: f64) -> (f64, f64) {
    let mut best = (f64::NAN, f64::NAN);
    let mut end = 0;
    let mut sum = 0.0;
    for start in 0..rows.len() {
        while end < rows.len() && rows[end].strain_axial <= rows[start].strain_axial + window {
            sum += rows[end].sigma1_pa;
            end += 1;
        }
        let n = (end - start) as f64;
        let mean = sum / n;
        if best.0.is_nan() || mean > best.0 {
            best = (
                mean,
                0.5 * (rows[start].strain_axial + rows[end - 1].strain_axial),
            );
        }
        sum -= rows[start].sigma1_pa;
    }
    best
}

/// Mean sigma_1 over rows with strain in `[lo, hi]` (NaN when none).
pub fn mean_in(rows: &[SeriesRow], lo: f64, hi: f64) -> f64 {
    let sel: Vec<f64> = rows
        .iter()
        .filter(|r| r.strain_axial >= lo && r.strain_axial <= hi)
        .map(|r| r.sigma1_pa)
        .collect();
    if sel.is_empty() {
        f64::NAN
    } else {
        sel.iter().sum::<f64>() / sel.len() as f64
    }
}

/// The residual strain range (docs/protocol.md, "Derived results").
pub const RESIDUAL_RANGE: (f64, f64) = (0.05, 0.10);

/// How far short of the end of [`RESIDUAL_RANGE`] a test may stop and still have a
/// residual: the width of the peak's moving window, so that a test stopped a few rows
/// early keeps its residual.
pub const RESIDUAL_END_SLACK: f64 = 0.002;

/// The smallest final strain of a test with a residual.
pub const RESIDUAL_MIN_END: f64 = RESIDUAL_RANGE.1 - RESIDUAL_END_SLACK;

/// Mean sigma_1 over [`RESIDUAL_RANGE`] of the compression rows `comp` (in increasing
/// strain), or NaN when they stop more than [`RESIDUAL_END_SLACK`] before its end: a test
/// stopped at strain 0.05 would otherwise report one row, and one stopped at 0.06 the
/// strength just after the peak, as its residual.
pub fn residual(comp: &[SeriesRow]) -> f64 {
    let (lo, hi) = RESIDUAL_RANGE;
    match comp.last() {
        Some(last) if last.strain_axial >= RESIDUAL_MIN_END => mean_in(comp, lo, hi),
        _ => f64::NAN,
    }
}

/// Mohr-Coulomb angle through the origin for principal stresses s1 >= s3 (degrees).
pub fn friction_angle_deg(s1: f64, s3: f64) -> f64 {
    ((s1 - s3) / (s1 + s3)).asin().to_degrees()
}

/// Derives the strength of a test from its compression rows (docs/protocol.md: peak over a
/// moving window of 0.002 strain; residual as the mean over strain 0.05-0.10).
pub fn strength(rows: &[SeriesRow], sigma3: f64) -> Strength {
    let comp: Vec<SeriesRow> = rows
        .iter()
        .filter(|r| r.phase == "compression")
        .cloned()
        .collect();
    let (peak, at) = moving_peak(&comp, 0.002);
    let residual = residual(&comp);
    Strength {
        sigma1_peak_pa: peak,
        strain_peak: at,
        sigma1_residual_pa: residual,
        sigma3_pa: sigma3,
        phi_peak_deg: friction_angle_deg(peak, sigma3),
        phi_residual_deg: friction_angle_deg(residual, sigma3),
        volumetric_strain_final: comp.last().map_or(f64::NAN, |r| r.volumetric_strain),
    }
}

/// A stress-drop event: a fall of sigma_1 over consecutive rows with a concurrent
/// contraction (docs/protocol.md, "Stress-drop events").
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StressDrop {
    /// Axial strain where the fall starts.
    pub strain_start: f64,
    /// Axial strain where it ends.
    pub strain_end: f64,
    /// Size of the fall of sigma_1 (Pa, positive).
    pub drop_pa: f64,
    /// Volumetric strain change over the fall (negative: contraction).
    pub volumetric_change: f64,
}

/// Increment of axial strain over which the compression rows are averaged before stress
/// drops are looked for. A row covers `series_every` steps, so by rows the events would
/// follow the time step: at friction 12 and 0.0625 ms a row spans 3e-6 of strain, and the
/// row-to-row noise of rigid contact forces would count as events (docs/protocol.md,
/// "Stress-drop events").
pub const STRESS_DROP_BIN: f64 = 1e-4;

/// The stress-drop events of the compression: the rows are averaged (strain, sigma_1 and
/// volumetric strain) over consecutive increments `bin` of axial strain (0: each row on its
/// own), then the events are the maximal runs of those averages along which sigma_1
/// decreases at every one, whose total fall is at least `min_drop` (Pa), and over which the
/// volumetric strain decreases (contraction).
pub fn stress_drops(rows: &[SeriesRow], min_drop: f64, bin: f64) -> Vec<StressDrop> {
    let comp: Vec<&SeriesRow> = rows
        .iter()
        .filter(|r| r.phase == "compression" && r.strain_axial.is_finite())
        .collect();
    let same_bin = |a: &&SeriesRow, b: &&SeriesRow| {
        bin > 0.0 && (a.strain_axial / bin).floor() == (b.strain_axial / bin).floor()
    };
    // (strain, sigma_1, volumetric strain) per bin.
    let points: Vec<(f64, f64, f64)> = comp
        .chunk_by(same_bin)
        .map(|c| {
            let n = c.len() as f64;
            // A fold from +0.0: f64's `sum` starts at -0.0, which a bin of zero strains keeps.
            let mean = |f: fn(&SeriesRow) -> f64| c.iter().fold(0.0, |a, r| a + f(r)) / n;
            (
                mean(|r| r.strain_axial),
                mean(|r| r.sigma1_pa),
                mean(|r| r.volumetric_strain),
            )
        })
        .collect();
    let mut events = Vec::new();
    let mut k = 0;
    while k + 1 < points.len() {
        if points[k + 1].1 >= points[k].1 {
            k += 1;
            continue;
        }
        let start = k;
        while k + 1 < points.len() && points[k + 1].1 < points[k].1 {
            k += 1;
        }
        let (a, b) = (points[start], points[k]);
        let drop = a.1 - b.1;
        let dv = b.2 - a.2;
        if drop >= min_drop && dv < 0.0 {
            events.push(StressDrop {
                strain_start: a.0,
                strain_end: b.0,
                drop_pa: drop,
                volumetric_change: dv,
            });
        }
    }
    events
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rows(points: &[(f64, f64)]) -> Vec<SeriesRow> {
        points
            .iter()
            .map(|&(e, s)| SeriesRow {
                strain_axial: e,
                sigma1_pa: s,
                phase: "compression".into(),
                ..Default::default()
            })
            .collect()
    }

    #[test]
    fn moving_window_peak_averages_over_the_window() {
        // A spike of one row is averaged with its neighbours inside 0.002 strain.
        let r = rows(&[
            (0.0, 1.0),
            (0.001, 1.0),
            (0.002, 10.0),
            (0.003, 1.0),
            (0.004, 1.0),
            (0.005, 1.0),
        ]);
        let (peak, at) = moving_peak(&r, 0.002);
        // Windows of three rows contain the spike: (1 + 1 + 10) / 3 = 4.
        assert!((peak - 4.0).abs() < 1e-12, "{peak}");
        assert!((at - 0.001).abs() < 1e-12, "{at}");
    }

    #[test]
    fn stress_drops_need_a_large_enough_fall_with_contraction() {
        let mut r = rows(&[
            (0.0, 10.0),
            (0.001, 12.0),
            (0.002, 11.0),
            (0.003, 9.0),
            (0.004, 10.0),
            (0.005, 9.5),
        ]);
        for (row, v) in r.iter_mut().zip([0.0, 0.001, 0.0005, 0.0, 0.001, 0.002]) {
            row.volumetric_strain = v;
        }
        // 12 -> 9 over strain 0.001-0.003 with dV -0.001: one event of 3; the fall 10 -> 9.5
        // comes with dilation and is not an event.
        let e = stress_drops(&r, 1.0, 0.0);
        assert_eq!(e.len(), 1);
        assert!((e[0].drop_pa - 3.0).abs() < 1e-12 && (e[0].volumetric_change + 0.001).abs() < 1e-12);
        assert!(stress_drops(&r, 3.5, 0.0).is_empty());
        // Bins narrower than the rows' spacing leave each row on its own.
        assert_eq!(stress_drops(&r, 1.0, 1e-4), e);
    }

    /// One real drop (sigma_1 falls linearly from 12 to 9 over strain 0.010-0.011 while the
    /// sample contracts by 1e-4), under a noise of +-0.5 alternating from row to row, sampled
    /// every 1e-5 and every 1.25e-6 of strain (the rows of 0.5 ms and 0.0625 ms steps). By
    /// rows every fall of the noise with a contraction is an event, the more so the finer
    /// the sampling; over bins of 1e-4 both samplings find the one drop.
    #[test]
    fn binned_stress_drops_do_not_depend_on_the_sampling() {
        let sample = |de: f64| -> Vec<SeriesRow> {
            let n = (0.02 / de).round() as usize;
            (0..n)
                .map(|k| {
                    let e = k as f64 * de;
                    let ramp = ((e - 0.010) / 0.001).clamp(0.0, 1.0);
                    let noise = if k % 2 == 0 { 0.5 } else { -0.5 };
                    let mut r = rows(&[(e, 12.0 - 3.0 * ramp + noise)]).remove(0);
                    // Contraction along the drop, and a slight one with the noise's falls.
                    r.volumetric_strain = -1e-4 * ramp - if k % 2 == 0 { 0.0 } else { 1e-7 };
                    r
                })
                .collect()
        };
        let (coarse, fine) = (sample(1e-5), sample(1.25e-6));
        let by_rows = stress_drops(&fine, 0.4, 0.0).len();
        assert!(by_rows > 1000, "{by_rows}");
        for rows in [&coarse, &fine] {
            let e = stress_drops(rows, 0.4, STRESS_DROP_BIN);
            assert_eq!(e.len(), 1, "{e:?}");
            // Bins of 1e-4 averaging the ramp: the fall between the bins before and after it
            // is the whole 3 (within the noise's residue over an odd row count per bin).
            assert!((e[0].drop_pa - 3.0).abs() < 0.06, "{e:?}");
            assert!(e[0].strain_start > 0.0095 && e[0].strain_end < 0.0115, "{e:?}");
        }
    }

    #[test]
    fn friction_angle_of_a_known_stress_ratio() {
        // s1 = 3 s3 gives sin(phi) = 1/2, phi = 30 degrees.
        assert!((friction_angle_deg(3.0, 1.0) - 30.0).abs() < 1e-12);
    }

    #[test]
    fn residual_is_the_mean_over_the_range() {
        let r = rows(&[(0.04, 100.0), (0.05, 2.0), (0.07, 4.0), (0.1, 6.0), (0.11, 100.0)]);
        assert!((mean_in(&r, 0.05, 0.10) - 4.0).abs() < 1e-12);
        // Rows past the range do not count: 0.11 is left out.
        assert!((residual(&r) - 4.0).abs() < 1e-12);
    }

    #[test]
    fn residual_needs_the_test_to_reach_the_end_of_its_range() {
        // Stopped at 0.05: a single row would be the residual; at 0.07, the strength just
        // after the peak. Neither is the residual of docs/protocol.md.
        for end in [0.05, 0.07, 0.0979] {
            let r = rows(&[(0.03, 9.0), (0.05, 2.0), (end, 4.0)]);
            assert!(residual(&r).is_nan(), "stopped at {end}");
        }
        // Stopped a row short of 0.10 (within the 0.002 slack): the mean of the three rows.
        let r = rows(&[(0.03, 9.0), (0.05, 2.0), (0.07, 4.0), (0.0985, 6.0)]);
        assert!((residual(&r) - 4.0).abs() < 1e-12);
    }
}
