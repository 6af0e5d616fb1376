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
    let mut peak = MovingPeak::new(window);
    for r in rows {
        peak.push(r.strain_axial, r.sigma1_pa);
    }
    peak.result()
}

/// [`moving_peak`] fed one point at a time, in increasing strain, so that a run can keep
/// it as it goes ([`DerivedCurve`]): a window is closed as soon as a point beyond it
/// arrives, with the same additions and subtractions in the same order as over the whole
/// list, so both give the same bits. Holds only the points of the open windows.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct MovingPeak {
    /// Width of the window (strain).
    window: f64,
    /// The points (strain, value) of the windows not yet closed.
    open: std::collections::VecDeque<(f64, f64)>,
    /// Sum of the values in `open`.
    sum: f64,
    /// The largest window mean so far and its window centre.
    best: Option<(f64, f64)>,
}

impl MovingPeak {
    /// No point yet, windows `window` wide.
    pub fn new(window: f64) -> Self {
        MovingPeak {
            window,
            ..Default::default()
        }
    }

    /// Adds the next point: every window it lies beyond is closed first.
    pub fn push(&mut self, strain: f64, value: f64) {
        while let Some(&(start, _)) = self.open.front() {
            if strain <= start + self.window {
                break;
            }
            self.close_front();
        }
        self.sum += value;
        self.open.push_back((strain, value));
    }

    /// Closes the window that starts at the oldest open point: its mean over every open
    /// point (all lie within it).
    fn close_front(&mut self) {
        let (Some(&(start, first)), Some(&(end, _))) = (self.open.front(), self.open.back()) else {
            return;
        };
        let mean = self.sum / self.open.len() as f64;
        if self.best.is_none_or(|(b, _)| b.is_nan() || mean > b) {
            self.best = Some((mean, 0.5 * (start + end)));
        }
        self.sum -= first;
        self.open.pop_front();
    }

    /// The largest window mean and its window centre, the windows still open (cut by the
    /// end of the points) included; NaN without points.
    pub fn result(&self) -> (f64, f64) {
        let mut rest = self.clone();
        while !rest.open.is_empty() {
            rest.close_front();
        }
        rest.best.unwrap_or((f64::NAN, f64::NAN))
    }
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
    let (peak, at) = moving_peak(&comp, PEAK_WINDOW);
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
    let mut finder = DropFinder::new(min_drop, bin);
    for r in rows.iter().filter(|r| r.phase == "compression") {
        finder.push(r.strain_axial, r.sigma1_pa, r.volumetric_strain);
    }
    finder.result()
}

/// The sums of one bin of [`DropFinder`]: its index, points, and sums of strain, sigma_1
/// and volumetric strain.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
struct Bin {
    /// `floor(strain / bin)`; none without bins (every point a bin of its own).
    index: Option<f64>,
    n: u64,
    sums: (f64, f64, f64),
}

impl Bin {
    fn mean(&self) -> (f64, f64, f64) {
        let n = self.n as f64;
        (self.sums.0 / n, self.sums.1 / n, self.sums.2 / n)
    }
}

/// [`stress_drops`] fed one point at a time, in increasing strain ([`DerivedCurve`]): the
/// bin being filled, the fall in progress and the events found. Points of a non-finite
/// strain are left out.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DropFinder {
    min_drop: f64,
    bin: f64,
    /// The bin being filled (a point of its own when `bin` is 0).
    current: Option<Bin>,
    /// The last finished bin's means, and the first of the fall that ends there, if any.
    last: Option<(f64, f64, f64)>,
    fall_from: Option<(f64, f64, f64)>,
    events: Vec<StressDrop>,
}

impl DropFinder {
    /// No point yet; events of at least `min_drop` (Pa) over bins `bin` of strain wide.
    pub fn new(min_drop: f64, bin: f64) -> Self {
        DropFinder {
            min_drop,
            bin,
            ..Default::default()
        }
    }

    /// Adds the next point.
    pub fn push(&mut self, strain: f64, sigma1: f64, volumetric: f64) {
        if !strain.is_finite() {
            return;
        }
        let index = (self.bin > 0.0).then(|| (strain / self.bin).floor());
        match &mut self.current {
            Some(b) if index.is_some() && b.index == index => {
                b.n += 1;
                b.sums.0 += strain;
                b.sums.1 += sigma1;
                b.sums.2 += volumetric;
            }
            _ => {
                if let Some(b) = self.current.take() {
                    self.point(b.mean());
                }
                // Sums from +0.0: f64's `sum` starts at -0.0, which a bin of zero strains keeps.
                self.current = Some(Bin {
                    index,
                    n: 1,
                    sums: (0.0 + strain, 0.0 + sigma1, 0.0 + volumetric),
                });
            }
        }
    }

    /// A finished bin's means: extends or ends the fall in progress.
    fn point(&mut self, p: (f64, f64, f64)) {
        if let Some(last) = self.last {
            if p.1 < last.1 {
                self.fall_from.get_or_insert(last);
            } else {
                self.end_fall(last);
            }
        }
        self.last = Some(p);
    }

    /// Ends the fall in progress at `b`: an event if large enough with a contraction.
    fn end_fall(&mut self, b: (f64, f64, f64)) {
        let Some(a) = self.fall_from.take() else {
            return;
        };
        let drop = a.1 - b.1;
        let dv = b.2 - a.2;
        if drop >= self.min_drop && dv < 0.0 {
            self.events.push(StressDrop {
                strain_start: a.0,
                strain_end: b.0,
                drop_pa: drop,
                volumetric_change: dv,
            });
        }
    }

    /// The events, the bin being filled and a fall in progress at the last point included.
    pub fn result(&self) -> Vec<StressDrop> {
        let mut rest = self.clone();
        if let Some(b) = rest.current.take() {
            rest.point(b.mean());
        }
        if let Some(last) = rest.last {
            rest.end_fall(last);
        }
        rest.events
    }
}

/// The compression's derived results (peak, residual, stress drops, largest kinetic
/// ratio), kept by the protocol as it runs from a point every
/// [`QUASI_STATIC_CHECK_EVERY`](crate::protocol::biaxial::QUASI_STATIC_CHECK_EVERY) steps
/// (sigma_1 averaged over those steps, strains at their end), so that they do not depend on
/// how often rows are written (`output.series_every`). Small: only the open peak windows,
/// the bin being filled and the events are kept; it goes into checkpoints with the
/// protocol's state. Points whose strain or sigma_1 is not finite are left out.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DerivedCurve {
    /// Points received.
    pub points: u64,
    peak: MovingPeak,
    drops: DropFinder,
    /// Sum and count of sigma_1 over [`RESIDUAL_RANGE`].
    residual: (f64, u64),
    /// Strain of the last point.
    last_strain: f64,
    /// Largest kinetic ratio `K / (sigma3 h w)` of the points.
    kinetic_ratio_max: f64,
}

/// Width of the moving window of the peak (strain; docs/protocol.md, "Derived results").
pub const PEAK_WINDOW: f64 = 0.002;

/// The smallest stress drop counted, as a fraction of sigma3.
pub const STRESS_DROP_MIN_REL: f64 = 0.05;

impl DerivedCurve {
    /// A compression at confining stress `sigma3` (Pa), no point yet.
    pub fn new(sigma3: f64) -> Self {
        DerivedCurve {
            peak: MovingPeak::new(PEAK_WINDOW),
            drops: DropFinder::new(STRESS_DROP_MIN_REL * sigma3, STRESS_DROP_BIN),
            ..Default::default()
        }
    }

    /// Adds the point of a block of steps, as a row of the series built from them.
    pub fn push(&mut self, row: &SeriesRow) {
        let (e, s) = (row.strain_axial, row.sigma1_pa);
        if !(e.is_finite() && s.is_finite()) {
            return;
        }
        self.points += 1;
        self.peak.push(e, s);
        if row.volumetric_strain.is_finite() {
            self.drops.push(e, s, row.volumetric_strain);
        }
        if e >= RESIDUAL_RANGE.0 && e <= RESIDUAL_RANGE.1 {
            self.residual.0 += s;
            self.residual.1 += 1;
        }
        self.last_strain = e;
        let k = row.kinetic_ratio();
        if k > self.kinetic_ratio_max {
            self.kinetic_ratio_max = k;
        }
    }

    /// The peak (Pa) over windows [`PEAK_WINDOW`] wide and its strain.
    pub fn peak(&self) -> (f64, f64) {
        self.peak.result()
    }

    /// The residual (Pa) as [`residual`] defines it: NaN when the points stop more than
    /// [`RESIDUAL_END_SLACK`] before the end of the range, or none lies in it.
    pub fn residual(&self) -> f64 {
        if self.points == 0 || self.last_strain < RESIDUAL_MIN_END || self.residual.1 == 0 {
            return f64::NAN;
        }
        self.residual.0 / self.residual.1 as f64
    }

    /// The stress-drop events (as [`stress_drops`] over bins [`STRESS_DROP_BIN`] wide).
    pub fn stress_drops(&self) -> Vec<StressDrop> {
        self.drops.result()
    }

    /// The largest kinetic ratio of the points (0 without points).
    pub fn kinetic_ratio_max(&self) -> f64 {
        self.kinetic_ratio_max
    }
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

    /// The curve a run keeps point by point, saved to JSON and read back halfway (as a
    /// checkpoint and a resume do), gives the same bits as the functions over the whole
    /// list: peak, residual and stress drops of a noisy curve with falls and contractions.
    #[test]
    fn the_curve_kept_point_by_point_equals_the_whole_list_bit_for_bit() {
        let sigma3 = 1e6;
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut noise = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let rows: Vec<SeriesRow> = (0..4000)
            .map(|k| {
                let e = 2.7e-5 * k as f64;
                let mut r = rows(&[(e, 2e6 + 1e6 * (e / 0.01).min(1.0) + 2e5 * noise())]).remove(0);
                r.volumetric_strain = 1e-3 * noise() + 0.1 * e;
                r
            })
            .collect();
        let mut curve = DerivedCurve::new(sigma3);
        for (k, r) in rows.iter().enumerate() {
            if k == 1234 {
                let json = serde_json::to_string(&curve).unwrap();
                curve = serde_json::from_str(&json).unwrap();
            }
            curve.push(r);
        }
        assert_eq!(curve.points, 4000);
        let (peak, at) = moving_peak(&rows, PEAK_WINDOW);
        let (p2, a2) = curve.peak();
        assert_eq!((peak.to_bits(), at.to_bits()), (p2.to_bits(), a2.to_bits()));
        // Against the definition, window by window.
        let naive = (0..rows.len())
            .map(|i| {
                let w: Vec<f64> = rows[i..]
                    .iter()
                    .take_while(|r| r.strain_axial <= rows[i].strain_axial + PEAK_WINDOW)
                    .map(|r| r.sigma1_pa)
                    .collect();
                w.iter().sum::<f64>() / w.len() as f64
            })
            .fold(f64::NEG_INFINITY, f64::max);
        assert!((naive - peak).abs() < 1e-9 * peak, "{naive} {peak}");
        assert!(rows.last().unwrap().strain_axial > RESIDUAL_MIN_END);
        assert_eq!(residual(&rows).to_bits(), curve.residual().to_bits());
        let drops = stress_drops(&rows, STRESS_DROP_MIN_REL * sigma3, STRESS_DROP_BIN);
        assert!(!drops.is_empty());
        assert_eq!(drops, curve.stress_drops());
        assert_eq!(
            drops,
            whole_list_drops(&rows, STRESS_DROP_MIN_REL * sigma3, STRESS_DROP_BIN)
        );
        // Without bins, row by row.
        let by_rows = stress_drops(&rows, 1e5, 0.0);
        assert_eq!(by_rows, whole_list_drops(&rows, 1e5, 0.0));
        assert!(by_rows.len() > drops.len());
    }

    /// Stress drops over the whole list at once (binned, then the maximal falls): the
    /// reference for [`DropFinder`].
    fn whole_list_drops(rows: &[SeriesRow], min_drop: f64, bin: f64) -> Vec<StressDrop> {
        let same = |a: &&SeriesRow, b: &&SeriesRow| {
            bin > 0.0 && (a.strain_axial / bin).floor() == (b.strain_axial / bin).floor()
        };
        let all: Vec<&SeriesRow> = rows.iter().collect();
        let points: Vec<(f64, f64, f64)> = all
            .chunk_by(same)
            .map(|c| {
                let n = c.len() as f64;
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
            if a.1 - b.1 >= min_drop && b.2 - a.2 < 0.0 {
                events.push(StressDrop {
                    strain_start: a.0,
                    strain_end: b.0,
                    drop_pa: a.1 - b.1,
                    volumetric_change: b.2 - a.2,
                });
            }
        }
        events
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
