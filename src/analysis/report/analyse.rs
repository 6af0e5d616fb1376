//! The report's analysis: the tests grouped by contact friction, the Mohr-Coulomb fits of
//! their peak and residual points, and the saturation fits across frictions.

use std::path::PathBuf;

use super::{FrictionRow, OVERLAP_BOUND_REL, Report, TestPoint};
use crate::analysis::fit::{Line, saturation, through_origin, unconstrained};
use crate::measure::summary::QUASI_STATIC_KINETIC_RATIO;

/// `tan(asin(s))` and its standard error from that of `s`.
fn macro_friction(l: &Line) -> (f64, f64) {
    let s = l.slope;
    let t = s / (1.0 - s * s).sqrt();
    (t, l.slope_se / (1.0 - s * s).powf(1.5))
}

fn distinct(values: impl Iterator<Item = f64>) -> usize {
    let mut v: Vec<f64> = values.collect();
    v.sort_by(f64::total_cmp);
    v.dedup();
    v.len()
}

/// The tests' wall-clock times summed, in hours (a summary without one adds nothing).
fn wall_time_h<'a>(tests: impl IntoIterator<Item = &'a TestPoint>) -> f64 {
    // A fold from +0: an empty f64 sum is -0, which the table would print as "-0.00".
    tests
        .into_iter()
        .filter_map(|t| t.wall_time_s)
        .fold(0.0, |a, b| a + b)
        / 3600.0
}

/// Analyses the tests (grouped by contact friction).
pub fn analyse(points: &[TestPoint], missing: Vec<(PathBuf, String)>) -> Report {
    let mut frictions = Vec::new();
    let mut i = 0;
    while i < points.len() {
        let mu = points[i].mu;
        let group: Vec<&TestPoint> = points[i..].iter().take_while(|p| p.mu == mu).collect();
        i += group.len();
        let pq = |s1: f64, s3: f64| [(s1 + s3) / 2.0, (s1 - s3) / 2.0];
        let peak: Vec<[f64; 2]> = group
            .iter()
            .map(|t| pq(t.sigma1_peak_mpa, t.sigma3_mpa))
            .collect();
        let res: Vec<[f64; 2]> = group
            .iter()
            .filter_map(|t| t.sigma1_residual_mpa.map(|s1| pq(s1, t.sigma3_mpa)))
            .collect();
        let split = |v: &[[f64; 2]]| -> (Vec<f64>, Vec<f64>) { v.iter().map(|a| (a[0], a[1])).unzip() };
        let (px, py) = split(&peak);
        let (rx, ry) = split(&res);
        let peak_fit = through_origin(&px, &py);
        let residual_fit = through_origin(&rx, &ry);
        let (m, m_se) = macro_friction(&peak_fit);
        let (mr, mr_se) = macro_friction(&residual_fit);
        frictions.push(FrictionRow {
            mu,
            tests: group.len(),
            peak_pq_mpa: peak,
            residual_pq_mpa: res,
            peak_fit,
            // One confining stress puts every point on q = p - sigma3: the free line then
            // says nothing about cohesion.
            peak_fit_free: if distinct(group.iter().map(|t| t.sigma3_mpa)) >= 2 {
                unconstrained(&px, &py)
            } else {
                Line {
                    slope: f64::NAN,
                    slope_se: f64::NAN,
                    intercept: f64::NAN,
                    intercept_se: f64::NAN,
                    n: px.len(),
                }
            },
            mu_macro: m,
            mu_macro_se: m_se,
            residual_fit,
            mu_macro_res: mr,
            mu_macro_res_se: mr_se,
            dt_ms: {
                let mut v: Vec<f64> = group.iter().filter_map(|t| t.dt_s.map(|d| d * 1e3)).collect();
                v.sort_by(f64::total_cmp);
                v.dedup();
                v
            },
            wall_time_h: wall_time_h(group.iter().copied()),
        });
    }
    let fit_of = |f: &dyn Fn(&FrictionRow) -> f64| {
        let (x, y): (Vec<f64>, Vec<f64>) = frictions
            .iter()
            .filter(|r| f(r).is_finite())
            .map(|r| (r.mu, f(r)))
            .unzip();
        saturation(&x, &y)
    };
    let above = |figure: fn(&TestPoint) -> Option<f64>, bound: f64| {
        points
            .iter()
            .filter_map(|t| {
                let k = figure(t)?;
                (k > bound).then(|| (t.dir.clone(), k))
            })
            .collect()
    };
    let suspect = above(|t| t.kinetic_ratio_max, QUASI_STATIC_KINETIC_RATIO);
    let overlapping = above(|t| t.overlap_max_rel, OVERLAP_BOUND_REL);
    Report {
        wall_time_h: wall_time_h(points),
        mu_macro_fit: fit_of(&|r| r.mu_macro),
        mu_macro_res_fit: fit_of(&|r| r.mu_macro_res),
        frictions,
        missing,
        suspect,
        overlapping,
        tests: points.to_vec(),
    }
}

#[cfg(test)]
mod tests {
    use crate::analysis::report::tests::wall_time_report;

    /// The wall times of the tests are summed per friction and over the campaign, in
    /// hours (1800 s + 5400 s = 2 h at friction 0.3; 3600 s more at friction 0.5 makes 3 h);
    /// a summary without one adds nothing.
    #[test]
    fn wall_times_are_summed_in_hours() {
        let rep = wall_time_report();
        assert_eq!(rep.frictions[0].wall_time_h, 2.0);
        assert_eq!(rep.frictions[1].wall_time_h, 1.0);
        assert_eq!(rep.wall_time_h, 3.0);
        assert!(rep.csv().lines().nth(1).unwrap().ends_with(",2"), "{}", rep.csv());
    }
}
