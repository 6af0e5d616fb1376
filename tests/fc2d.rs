//! The Siconos fc2d problems shipped in `tests/data/fc2d/` (source and licence in its
//! README): an outside test suite of the local law and the Gauss-Seidel sweeps on problems
//! built by another code.

use std::path::{Path, PathBuf};

use cdlab::fc2d::{Problem, SolveOptions, parse, read, siconos_error, solve};

fn data(name: &str) -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/fc2d")
        .join(name);
    assert!(p.exists(), "missing test problem {}", p.display());
    p
}

/// The problem's error as Siconos defines it (its fc2d Gauss-Seidel passes |q| as the
/// norm): for each contact the distance between `r` and the projection on the cone of
/// `r - (u_n + mu |u_t|, u_t)`, root of the summed squares, over |q| unless |q| is below
/// the machine epsilon. Written here again, apart from the library's, as the yardstick.
fn error_of(p: &Problem, r: &[f64]) -> f64 {
    let mut u = p.q.clone();
    add_columns(p, r, &mut u);
    let mut sum = 0.0;
    for c in 0..p.nc {
        let (rn, rt, un, ut, mu) = (r[2 * c], r[2 * c + 1], u[2 * c], u[2 * c + 1], p.mu[c]);
        let (zn, zt) = (rn - (un + mu * ut.abs()), rt - ut);
        // Projection on the cone |t| <= mu n: inside, the polar cone (to 0), or the edge.
        let (pn, pt) = if zt.abs() <= mu * zn {
            (zn, zt)
        } else if mu * zt.abs() <= -zn {
            (0.0, 0.0)
        } else {
            let n = (zn + mu * zt.abs()) / (1.0 + mu * mu);
            (n, mu * n * zt.signum())
        };
        sum += (rn - pn).powi(2) + (rt - pt).powi(2);
    }
    let q = p.q.iter().map(|x| x * x).sum::<f64>().sqrt();
    if q > f64::EPSILON {
        sum.sqrt() / q
    } else {
        sum.sqrt()
    }
}

/// `u += W r`, column by column.
fn add_columns(p: &Problem, r: &[f64], u: &mut [f64]) {
    for (j, &rj) in r.iter().enumerate() {
        column(p, j, rj, u);
    }
}

/// `u += a W[:, j]`.
fn column(p: &Problem, j: usize, a: f64, u: &mut [f64]) {
    let w = &p.w;
    for k in w.col_start[j]..w.col_start[j + 1] {
        u[w.row_idx[k]] += a * w.vals[k];
    }
}

/// An independent Gauss-Seidel: each contact's 2x2 problem solved by trying its cases in
/// turn (apart, sticking, sliding one way, sliding the other), as the first fc2d solvers
/// of Siconos do, where the library computes the solution of the block directly. From
/// `r = 0`, in contact order, the error tested after every sweep; returns the sweeps to
/// reach `tol` and the impulses.
fn reference_sweeps(p: &Problem, tol: f64, cap: usize) -> (usize, Vec<f64>) {
    let mut r = vec![0.0; 2 * p.nc];
    let mut u = p.q.clone();
    let mut sweeps = 0;
    while error_of(p, &r) >= tol && sweeps < cap {
        for c in 0..p.nc {
            let (a, b) = (2 * c, 2 * c + 1);
            let (wnn, wtt, wnt, wtn) = (p.w.get(a, a), p.w.get(b, b), p.w.get(a, b), p.w.get(b, a));
            // The velocity without this contact's own impulse.
            let fn_ = u[a] - wnn * r[a] - wnt * r[b];
            let ft = u[b] - wtn * r[a] - wtt * r[b];
            let mu = p.mu[c];
            let (rn, rt) = if fn_ >= 0.0 {
                (0.0, 0.0)
            } else {
                let det = wnn * wtt - wnt * wtn;
                let (sn, st) = ((-fn_ * wtt + ft * wnt) / det, (fn_ * wtn - ft * wnn) / det);
                if sn >= 0.0 && st.abs() <= mu * sn {
                    (sn, st)
                } else {
                    // Sliding with r_t = s mu r_n and u_n = 0: the tangential velocity must
                    // oppose the friction (s u_t <= 0).
                    let slide = |s: f64| {
                        let n = -fn_ / (wnn + s * mu * wnt);
                        (n, s * mu * n, wtn * n + wtt * s * mu * n + ft)
                    };
                    let (n, t, ut) = slide(1.0);
                    if n >= 0.0 && ut <= 0.0 {
                        (n, t)
                    } else {
                        let (n, t, _) = slide(-1.0);
                        (n, t)
                    }
                }
            };
            column(p, a, rn - r[a], &mut u);
            column(p, b, rt - r[b], &mut u);
            r[a] = rn;
            r[b] = rt;
        }
        sweeps += 1;
    }
    (sweeps, r)
}

/// The five fc2d problems Siconos ships and tests its own Gauss-Seidel on, to an error of
/// 1e-5 within 10,000 sweeps (tests/data/fc2d/README.md): two of a slider-crank
/// mechanism, stored dense, and three of a granular flow, stored sparse. The library's Gauss-Seidel must
/// reach that error in the sweeps the independent solver above takes, within two: both are
/// exact Gauss-Seidel in the same order, so a slower sweep, a looser local solution or an
/// error measured wrong shows as a different count. The first problem is the flow at rest
/// (|q| about 1e-18): `r = 0` solves it already.
#[test]
fn the_shared_problems_reach_the_siconos_error_in_the_reference_sweeps() {
    for (name, contacts, at_rest) in [
        // A slider-crank mechanism (two contacts, friction 0.01), stored dense.
        ("FC2D_SliderCrankLagrangian00000.dat", 2, false),
        ("FC2D_SliderCrankLagrangian00001.dat", 2, false),
        ("fc2d_granularflowonwall_00667_00000.dat", 667, true),
        ("fc2d_granularflowonwall_02020_00213.dat", 2020, false),
        ("fc2d_granularflowonwall_07002_00801.dat", 7002, false),
    ] {
        let p = read(&data(name)).unwrap();
        assert_eq!(p.nc, contacts);
        let zero = vec![0.0; 2 * p.nc];
        let e0 = siconos_error(&p, &zero);
        assert!(
            (e0 - error_of(&p, &zero)).abs() <= 1e-12 * e0.max(1e-300),
            "{name}: {e0}"
        );
        assert_eq!(e0 < 1e-5, at_rest, "{name}: r = 0 has error {e0}");
        let (reference, r_ref) = reference_sweeps(&p, 1e-5, 10_000);
        assert!(
            error_of(&p, &r_ref) < 1e-5,
            "{name}: the reference solver did not converge"
        );
        let opts = SolveOptions {
            check_every: 1,
            ..SolveOptions::default()
        };
        let rep = solve(&p, &opts);
        eprintln!("{name}: {} sweeps, reference {reference}", rep.iterations);
        assert!(
            rep.converged && rep.error < 1e-5,
            "{name}: error {} after {} sweeps",
            rep.error,
            rep.iterations
        );
        assert!(
            rep.iterations.abs_diff(reference) <= 2,
            "{name}: {} sweeps, the reference Gauss-Seidel {reference}",
            rep.iterations
        );
        // The returned impulses are what the error was computed on, by either measure.
        assert!((siconos_error(&p, &rep.r) - rep.error).abs() <= 1e-12);
        assert!((error_of(&p, &rep.r) - rep.error).abs() <= 1e-9 * rep.error.max(1e-300));
    }
}

#[test]
fn malformed_problem_files_are_rejected_with_the_line() {
    let good = std::fs::read_to_string(data("fc2d_granularflowonwall_00667_00000.dat")).unwrap();
    let path = Path::new("bad.dat");
    let cases: Vec<(String, &str)> = vec![
        (String::new(), "ends"),
        ("3\n667\n".into(), "dimension"),
        (good.replacen("1334\n1334", "1334\n1336", 1), "does not match"),
        (good.replacen("856.713", "nan", 1), "finite"),
        (
            good.replacen("      649 : -454.43", "      9999 : -454.43", 1),
            "out of range",
        ),
        (good[..good.len() / 2].to_string(), "file ends"),
        (
            good.replacen(
                "5.000000000000000000000000e-01",
                "-5.000000000000000000000000e-01",
                1,
            ),
            "negative friction",
        ),
        (good.replacen("CSparse", "Dense", 1), "CSparse"),
        (
            good.replacen("2\n667\n2\n", "2\n667\n1\n", 1),
            "only dense (0) and sparse",
        ),
    ];
    for (text, expect) in cases {
        let e = parse(&text, path).unwrap_err().to_string();
        assert!(
            e.contains(expect) && e.contains("bad.dat"),
            "expected `{expect}` in: {e}"
        );
    }
}

/// A small problem written in the fc2d layout (see `src/fc2d/parse.rs`): `nc` contacts,
/// a diagonal Delassus matrix, q and mu on their own lines.
fn synthetic(nc: usize) -> String {
    let n = 2 * nc;
    let mut t =
        format!("2\n{nc}\n2\n{n}\n{n}\n2\nCSparse synthetic\n{n}-by-{n}, nzmax: {n} nnz: {n}, 1-norm: 1.5\n");
    for j in 0..n {
        t += &format!("    col {j} : locations {j} to {j}\n      {j} : 1.25\n");
    }
    let q: Vec<String> = (0..n).map(|k| format!("-0.{}5", k + 1)).collect();
    let mu: Vec<String> = (0..nc).map(|k| format!("0.{}3", k + 2)).collect();
    t + &q.join(" ") + "\n" + &mu.join(" ") + "\n"
}

/// The same problem written dense (Siconos's storage 0: line `j` is column `j`) and sparse
/// reads as the same problem; a dense column with a value too few is refused with its
/// line.
#[test]
fn a_dense_problem_reads_as_its_sparse_twin() {
    let nc = 3;
    let n = 2 * nc;
    // An unsymmetric matrix with zeros off the diagonal, which the sparse file leaves out.
    let w = |i: usize, j: usize| match (i == j, (i + j) % 3) {
        (true, _) => 4.0 + i as f64,
        (false, 0) => 0.25 * (i as f64 - j as f64),
        _ => 0.0,
    };
    let q: Vec<String> = (0..n).map(|k| format!("-0.{}5", k + 1)).collect();
    let mu = "0.2 0.3 0.4";
    let mut dense = format!("2\n{nc}\n0\n{n}\n{n}\n{n}\t{n}\n");
    for j in 0..n {
        let col: Vec<String> = (0..n).map(|i| format!("{:.6e}", w(i, j))).collect();
        dense += &(col.join(" ") + " \n");
    }
    dense += &(q.join(" ") + "\n" + mu + "\n");
    let nnz = (0..n * n).filter(|k| w(k % n, k / n) != 0.0).count();
    let mut sparse =
        format!("2\n{nc}\n2\n{n}\n{n}\n2\nCSparse twin\n{n}-by-{n}, nzmax: {nnz} nnz: {nnz}, 1-norm: 1\n");
    let mut at = 0;
    for j in 0..n {
        let rows: Vec<usize> = (0..n).filter(|&i| w(i, j) != 0.0).collect();
        sparse += &format!("    col {j} : locations {at} to {}\n", at + rows.len() - 1);
        for i in rows {
            sparse += &format!("      {i} : {:.6e}\n", w(i, j));
            at += 1;
        }
    }
    sparse += &(q.join(" ") + "\n" + mu + "\n");
    let (d, s) = (
        parse(&dense, Path::new("dense.dat")).unwrap(),
        parse(&sparse, Path::new("sparse.dat")).unwrap(),
    );
    assert_eq!((d.nc, &d.q, &d.mu), (s.nc, &s.q, &s.mu));
    assert_eq!(
        (&d.w.col_start, &d.w.row_idx, &d.w.vals),
        (&s.w.col_start, &s.w.row_idx, &s.w.vals)
    );
    // Line 7 is column 0 (after the five header lines and the size line).
    let mut lines: Vec<String> = dense.lines().map(str::to_string).collect();
    lines[6] = lines[6].trim_end().rsplit_once(' ').unwrap().0.to_string();
    let short = lines.join("\n") + "\n";
    let e = parse(&short, Path::new("dense.dat")).unwrap_err().to_string();
    assert!(
        e.contains("dense.dat") && e.contains("line 7") && e.contains("column 0"),
        "{e}"
    );
}

/// A file cut at any byte is refused, never read as a smaller or different problem: every
/// cut of a synthetic file, and of the shipped files every cut in the last 300 bytes (the
/// q and mu lines, where a cut inside a number still parses as a number) and every 499th
/// byte elsewhere.
#[test]
fn a_file_cut_at_any_byte_is_refused() {
    let path = Path::new("cut.dat");
    let text = synthetic(3);
    let whole = parse(&text, path).unwrap();
    assert_eq!((whole.nc, whole.mu.clone()), (3, vec![0.23, 0.33, 0.43]));
    for cut in 0..text.len() {
        let e = parse(&text[..cut], path);
        assert!(
            e.is_err(),
            "the synthetic file cut at byte {cut} of {} was read",
            text.len()
        );
    }
    for name in [
        "FC2D_SliderCrankLagrangian00000.dat",
        "fc2d_granularflowonwall_00667_00000.dat",
        "fc2d_granularflowonwall_02020_00213.dat",
    ] {
        let text = std::fs::read_to_string(data(name)).unwrap();
        parse(&text, path).unwrap();
        let tail = text.len().saturating_sub(300);
        for cut in (0..tail).step_by(499).chain(tail..text.len()) {
            assert!(
                parse(&text[..cut], path).is_err(),
                "{name} cut at byte {cut} was read"
            );
        }
    }
}

/// A header announcing more contacts than the file can hold is refused before anything is
/// allocated for them (it was a capacity-overflow panic at 2^62 contacts).
#[test]
fn a_huge_contact_count_is_refused_without_allocating() {
    let text = synthetic(2);
    for nc in [u64::MAX / 2, 1 << 62, 1 << 40, 10_000] {
        let n = nc.wrapping_mul(2);
        let bad = text.replacen("\n2\n2\n4\n4\n", &format!("\n{nc}\n2\n{n}\n{n}\n"), 1);
        let e = parse(&bad, Path::new("huge.dat")).unwrap_err().to_string();
        assert!(
            e.contains("huge.dat") && e.contains("contacts announced"),
            "{nc}: {e}"
        );
    }
}
