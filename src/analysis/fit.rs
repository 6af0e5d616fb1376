//! Least-squares fits of the campaign analysis (docs/protocol.md, "Derived results"): the
//! Mohr-Coulomb line through the origin `q = p sin(phi)`, the unconstrained line
//! `q = c + p s`, and the saturation `mu_macro = a - b exp(-c mu)`, each with standard errors.

/// Reading back figures that JSON wrote as `null`: serde_json writes NaN (a figure the
/// points do not define) as `null`, which a plain `f64` refuses, so a `report.json` could
/// not be reopened. These read `null` as NaN.
pub mod nan_as_null {
    use serde::{Deserialize, Deserializer};

    /// A number, or NaN for `null`.
    pub fn number<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }

    /// Three numbers, each NaN for `null`.
    pub fn three<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 3], D::Error> {
        Ok(<[Option<f64>; 3]>::deserialize(d)?.map(|v| v.unwrap_or(f64::NAN)))
    }
}

/// A straight-line fit with standard errors.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Line {
    /// Slope.
    #[serde(deserialize_with = "nan_as_null::number")]
    pub slope: f64,
    /// Standard error of the slope (NaN with too few points).
    #[serde(deserialize_with = "nan_as_null::number")]
    pub slope_se: f64,
    /// Intercept (0 for a fit through the origin).
    #[serde(deserialize_with = "nan_as_null::number")]
    pub intercept: f64,
    /// Standard error of the intercept (NaN for a fit through the origin or too few points).
    #[serde(deserialize_with = "nan_as_null::number")]
    pub intercept_se: f64,
    /// Number of points.
    pub n: usize,
}

/// Least squares through the origin, `y = s x`: `s = sum xy / sum x^2`, with the standard
/// error `sqrt(RSS / (n - 1) / sum x^2)`.
pub fn through_origin(x: &[f64], y: &[f64]) -> Line {
    let n = x.len();
    let sxx: f64 = x.iter().map(|v| v * v).sum();
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| a * b).sum();
    let s = sxy / sxx;
    let rss: f64 = x.iter().zip(y).map(|(a, b)| (b - s * a).powi(2)).sum();
    let se = if n > 1 {
        (rss / (n - 1) as f64 / sxx).sqrt()
    } else {
        f64::NAN
    };
    Line {
        slope: s,
        slope_se: se,
        intercept: 0.0,
        intercept_se: f64::NAN,
        n,
    }
}

/// Ordinary least squares `y = c + s x`, with the usual standard errors (n - 2 degrees of
/// freedom).
pub fn unconstrained(x: &[f64], y: &[f64]) -> Line {
    let n = x.len();
    let nf = n as f64;
    let mx = x.iter().sum::<f64>() / nf;
    let my = y.iter().sum::<f64>() / nf;
    let sxx: f64 = x.iter().map(|v| (v - mx).powi(2)).sum();
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let s = sxy / sxx;
    let c = my - s * mx;
    let rss: f64 = x.iter().zip(y).map(|(a, b)| (b - c - s * a).powi(2)).sum();
    let (se_s, se_c) = if n > 2 {
        let sigma2 = rss / (nf - 2.0);
        (
            (sigma2 / sxx).sqrt(),
            (sigma2 * (1.0 / nf + mx * mx / sxx)).sqrt(),
        )
    } else {
        (f64::NAN, f64::NAN)
    };
    Line {
        slope: s,
        slope_se: se_s,
        intercept: c,
        intercept_se: se_c,
        n,
    }
}

/// The fit `y = a - b exp(-c x)` with standard errors.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Saturation {
    /// Asymptote `a`.
    #[serde(deserialize_with = "nan_as_null::number")]
    pub a: f64,
    /// Amplitude `b`.
    #[serde(deserialize_with = "nan_as_null::number")]
    pub b: f64,
    /// Rate `c`.
    #[serde(deserialize_with = "nan_as_null::number")]
    pub c: f64,
    /// Standard errors of `a`, `b`, `c` (from the Gauss-Newton covariance; NaN with fewer
    /// than four points).
    #[serde(deserialize_with = "nan_as_null::three")]
    pub se: [f64; 3],
    /// Root-mean-square residual.
    #[serde(deserialize_with = "nan_as_null::number")]
    pub rms: f64,
}

/// Levenberg-Marquardt iterations allowed to [`saturation`] (a dozen suffice on the
/// campaign's data; a fit still moving after this many is reported as not converged).
pub const ITERATIONS: usize = 500;

/// Solves the square system `a x = b` by Gaussian elimination with partial pivoting.
/// `None` when the determinant (the product of the pivots) is not finite or below 1e-300
/// in size: a singular system, or data that were not finite.
pub fn solve_linear(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    assert!(a.len() == n && a.iter().all(|r| r.len() == n), "a square system");
    let mut det = 1.0f64;
    for c in 0..n {
        let p = (c..n).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))?;
        a.swap(c, p);
        b.swap(c, p);
        det *= a[c][c];
        if a[c][c] == 0.0 {
            return None;
        }
        let (top, rest) = a.split_at_mut(c + 1);
        let pivot = &top[c];
        for (r, row) in rest.iter_mut().enumerate() {
            let f = row[c] / pivot[c];
            for (x, p) in row[c..].iter_mut().zip(&pivot[c..]) {
                *x -= f * p;
            }
            b[c + 1 + r] -= f * b[c];
        }
    }
    if !det.is_finite() || det.abs() < 1e-300 {
        return None;
    }
    let mut x = vec![0.0; n];
    for c in (0..n).rev() {
        let s: f64 = (c + 1..n).map(|k| a[c][k] * x[k]).sum();
        x[c] = (b[c] - s) / a[c][c];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// The inverse of the square matrix `a`, column by column through [`solve_linear`]
/// (`None` when it is singular).
pub fn invert(a: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let n = a.len();
    let columns: Option<Vec<Vec<f64>>> = (0..n)
        .map(|j| solve_linear(a.to_vec(), (0..n).map(|i| f64::from(u8::from(i == j))).collect()))
        .collect();
    let columns = columns?;
    Some((0..n).map(|i| (0..n).map(|j| columns[j][i]).collect()).collect())
}

fn rows3(m: [[f64; 3]; 3]) -> Vec<Vec<f64>> {
    m.iter().map(|r| r.to_vec()).collect()
}

/// Fits `y = a - b exp(-c x)` by Levenberg-Marquardt from a start taken from the data
/// (a = largest y, b = a - smallest y, c = 1 / mean x). Returns `None` when the data cannot
/// determine three parameters: fewer than three points, fewer than three distinct x (a
/// curve of three parameters through two abscissae is not unique), a constant y (then b = 0
/// and c is anything), a non-finite value, no convergence within the iteration budget, or
/// a solution where the parameters are not determined (singular normal matrix, as when c
/// runs off to infinity on step-like data).
pub fn saturation(x: &[f64], y: &[f64]) -> Option<Saturation> {
    let n = x.len();
    if n < 3 || x.len() != y.len() || x.iter().chain(y).any(|v| !v.is_finite()) {
        return None;
    }
    let mut distinct = x.to_vec();
    distinct.sort_by(f64::total_cmp);
    distinct.dedup();
    if distinct.len() < 3 {
        return None;
    }
    let ymax = y.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let ymin = y.iter().cloned().fold(f64::INFINITY, f64::min);
    if ymax == ymin {
        return None;
    }
    let mx = x.iter().sum::<f64>() / n as f64;
    let mut p = [ymax, (ymax - ymin).max(1e-6), 1.0 / mx.max(1e-6)];
    let rss = |p: &[f64; 3]| -> f64 {
        x.iter()
            .zip(y)
            .map(|(&xi, &yi)| (yi - (p[0] - p[1] * (-p[2] * xi).exp())).powi(2))
            .sum()
    };
    let mut lambda = 1e-3;
    let mut cur = rss(&p);
    let mut converged = false;
    for _ in 0..ITERATIONS {
        let mut jtj = [[0.0; 3]; 3];
        let mut jtr = [0.0; 3];
        for (&xi, &yi) in x.iter().zip(y) {
            let e = (-p[2] * xi).exp();
            let r = yi - (p[0] - p[1] * e);
            let j = [1.0, -e, p[1] * xi * e];
            for a in 0..3 {
                jtr[a] += j[a] * r;
                for b in 0..3 {
                    jtj[a][b] += j[a] * j[b];
                }
            }
        }
        let mut m = jtj;
        for (a, row) in m.iter_mut().enumerate() {
            row[a] *= 1.0 + lambda;
        }
        let Some(d) = solve_linear(rows3(m), jtr.to_vec()) else {
            lambda *= 10.0;
            continue;
        };
        let trial = [p[0] + d[0], p[1] + d[1], p[2] + d[2]];
        let next = rss(&trial);
        if next.is_finite() && next <= cur {
            let done = (cur - next) <= 1e-15 * cur.max(1e-300);
            p = trial;
            cur = next;
            lambda = (lambda / 10.0).max(1e-12);
            if done {
                converged = true;
                break;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e12 {
                // No step, however short, lowers the residual: a minimum to round-off.
                converged = true;
                break;
            }
        }
    }
    if !converged {
        return None;
    }
    // A rate so large that the curve is a step at the data's x (or so small that it is
    // flat): the data no longer see c, which any larger (smaller) value fits as well.
    let xmax = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let sensitivity = x
        .iter()
        .map(|&xi| (p[1] * xi * (-p[2] * xi).exp()).abs())
        .fold(0.0, f64::max);
    if sensitivity.is_nan() || sensitivity <= 1e-9 * p[1].abs() * xmax {
        return None;
    }
    // Covariance sigma^2 (J^T J)^-1 at the solution.
    let mut jtj = [[0.0; 3]; 3];
    for &xi in x {
        let e = (-p[2] * xi).exp();
        let j = [1.0, -e, p[1] * xi * e];
        for a in 0..3 {
            for b in 0..3 {
                jtj[a][b] += j[a] * j[b];
            }
        }
    }
    let inv = invert(&rows3(jtj))?;
    let se = if n > 3 {
        let s2 = cur / (n - 3) as f64;
        [0, 1, 2].map(|i| (s2 * inv[i][i]).sqrt())
    } else {
        [f64::NAN; 3]
    };
    p.iter().all(|v| v.is_finite()).then_some(Saturation {
        a: p[0],
        b: p[1],
        c: p[2],
        se,
        rms: (cur / n as f64).sqrt(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_through_the_origin_recovers_a_known_slope() {
        // q = p sin(30 deg) exactly: slope 0.5, zero standard error.
        let p = [1.0, 2.0, 4.0, 8.0];
        let q: Vec<f64> = p.iter().map(|v| 0.5 * v).collect();
        let l = through_origin(&p, &q);
        assert!((l.slope - 0.5).abs() < 1e-15 && l.slope_se < 1e-15);
        // With noise +-0.1 alternating the estimate stays within its standard error of 0.5.
        let qn: Vec<f64> = q
            .iter()
            .enumerate()
            .map(|(k, v)| v + if k % 2 == 0 { 0.1 } else { -0.1 })
            .collect();
        let l = through_origin(&p, &qn);
        assert!(
            (l.slope - 0.5).abs() < 2.0 * l.slope_se && l.slope_se > 0.0,
            "{l:?}"
        );
    }

    #[test]
    fn unconstrained_line_recovers_slope_and_intercept() {
        let x = [0.5, 1.0, 2.0, 4.0, 8.0];
        let y: Vec<f64> = x.iter().map(|v| 0.2 + 0.6 * v).collect();
        let l = unconstrained(&x, &y);
        assert!(
            (l.slope - 0.6).abs() < 1e-12 && (l.intercept - 0.2).abs() < 1e-12,
            "{l:?}"
        );
    }

    /// Degenerate data give `None`, never parameters the data do not determine.
    #[test]
    fn saturation_fit_refuses_degenerate_data() {
        let x4 = [1.0, 2.0, 3.0, 4.0];
        let cases: [(&str, Vec<f64>, Vec<f64>); 6] = [
            // Three parameters need three points.
            ("two points", vec![1.0, 2.0], vec![0.5, 0.7]),
            ("no point", vec![], vec![]),
            // All x equal: one abscissa fixes a - b exp(-c x) at one value only.
            ("all x equal", vec![2.0; 5], vec![0.5, 0.6, 0.7, 0.6, 0.5]),
            // Two distinct x: a curve of three parameters through two abscissae is not unique.
            (
                "two distinct x",
                vec![1.0, 1.0, 2.0, 2.0],
                vec![0.5, 0.5, 0.7, 0.7],
            ),
            // Constant y: b = 0 and c is anything.
            ("constant y", x4.to_vec(), vec![0.6; 4]),
            // Step-like data from x = 0: 1 - exp(-c x) fits them better as c grows without
            // bound; no finite c is the fit.
            (
                "step at 0",
                vec![0.0, 1.0, 2.0, 3.0, 4.0],
                vec![0.0, 1.0, 1.0, 1.0, 1.0],
            ),
        ];
        for (what, x, y) in cases {
            assert_eq!(saturation(&x, &y), None, "{what}");
        }
        assert_eq!(saturation(&[1.0, f64::NAN, 3.0], &[0.1, 0.2, 0.3]), None, "NaN");
        assert_eq!(saturation(&x4, &[0.1, 0.2, 0.3]), None, "lengths differ");
    }

    /// Data on a straight line have no best saturation curve: a - b exp(-c x) tends to the
    /// line a - b + b c x only as c -> 0 with a, b -> infinity, so the iterations never
    /// settle, and the fit says so with `None` instead of returning where it stopped.
    #[test]
    fn saturation_fit_that_does_not_converge_is_none() {
        let x = [1.0, 2.0, 3.0, 4.0];
        for y in [[1.0, 2.0, 3.0, 4.0], [4.0, 3.0, 2.0, 1.0]] {
            assert_eq!(saturation(&x, &y), None, "line {y:?}");
        }
        // Three points of a true saturation curve still fit exactly (n = 3 is enough).
        let x3: [f64; 3] = [0.1, 1.0, 5.0];
        let y3: Vec<f64> = x3.iter().map(|m| 0.9 - 0.7 * (-3.0 * m).exp()).collect();
        let f = saturation(&x3, &y3).expect("three points of the curve");
        assert!((f.a - 0.9).abs() < 1e-6 && (f.c - 3.0).abs() < 1e-4, "{f:?}");
        assert!(f.se.iter().all(|s| s.is_nan()), "no standard error from 3 points");
    }

    #[test]
    fn saturation_fit_recovers_known_parameters() {
        // The paper's friction values; y = 0.9 - 0.7 exp(-3 mu) exactly.
        let x: [f64; 13] = [0.01, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0, 1.2, 3.0, 6.0, 12.0];
        let y: Vec<f64> = x.iter().map(|m| 0.9 - 0.7 * (-3.0 * m).exp()).collect();
        let f = saturation(&x, &y).expect("fit");
        assert!(
            (f.a - 0.9).abs() < 1e-6 && (f.b - 0.7).abs() < 1e-6 && (f.c - 3.0).abs() < 1e-4,
            "{f:?}"
        );
        // Noisy data: the truth lies within three standard errors.
        let yn: Vec<f64> = y
            .iter()
            .enumerate()
            .map(|(k, v)| v + 0.01 * ((k as f64 * 2.3).sin()))
            .collect();
        let f = saturation(&x, &yn).expect("fit");
        assert!(
            (f.a - 0.9).abs() < 3.0 * f.se[0] && (f.c - 3.0).abs() < 3.0 * f.se[2],
            "{f:?}"
        );
    }

    /// A system whose first pivot is 0 (elimination without row exchanges divides by it),
    /// with the solution (1, -2, 3, 0.5) known: the residual is round-off.
    #[test]
    fn a_system_needing_row_exchanges_is_solved() {
        let a = vec![
            vec![0.0, 2.0, 1.0, -1.0],
            vec![3.0, 1.0, 0.0, 2.0],
            vec![1.0, -1.0, 4.0, 0.0],
            vec![2.0, 0.0, 1.0, 5.0],
        ];
        let x = [1.0, -2.0, 3.0, 0.5];
        let b: Vec<f64> = a
            .iter()
            .map(|r| r.iter().zip(&x).map(|(p, q)| p * q).sum())
            .collect();
        let got = solve_linear(a.clone(), b).unwrap();
        for (g, w) in got.iter().zip(&x) {
            assert!((g - w).abs() < 1e-12, "{got:?}");
        }
        // The inverse times the matrix is the identity.
        let inv = invert(&a).unwrap();
        for (i, row) in inv.iter().enumerate() {
            for j in 0..4 {
                let p: f64 = row.iter().zip(&a).map(|(r, ak)| r * ak[j]).sum();
                assert!((p - f64::from(u8::from(i == j))).abs() < 1e-12, "({i}, {j}): {p}");
            }
        }
    }

    /// Two equal rows, a non-finite entry: no solution is returned.
    #[test]
    fn singular_or_non_finite_systems_are_refused() {
        let a = vec![vec![1.0, 2.0], vec![1.0, 2.0]];
        assert!(solve_linear(a.clone(), vec![1.0, 1.0]).is_none());
        assert!(invert(&a).is_none());
        let a = vec![vec![f64::NAN, 0.0], vec![0.0, 1.0]];
        assert!(solve_linear(a, vec![1.0, 1.0]).is_none());
    }
}
