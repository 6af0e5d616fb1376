//! The Siconos fc2d problems shipped in `tests/data/fc2d/` (source and licence in its
//! README): an outside test suite of the local law and the Gauss-Seidel sweeps on problems
//! built by another code.

use std::path::{Path, PathBuf};

use cdlab::fc2d::{SolveOptions, parse, read, siconos_error, solve};

fn data(name: &str) -> PathBuf {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/fc2d")
        .join(name);
    assert!(p.exists(), "missing test problem {}", p.display());
    p
}

#[test]
fn both_shared_problems_reach_the_siconos_error_of_1e_5() {
    // Siconos tests its own solvers on these problems to an error of 1e-5; plain
    // Gauss-Seidel needs about 20 sweeps on the first and about 800 on the second.
    for (name, contacts, max_sweeps) in [
        ("fc2d_granularflowonwall_00667_00000.dat", 667, 100),
        ("fc2d_granularflowonwall_02020_00213.dat", 2020, 3000),
    ] {
        let p = read(&data(name)).unwrap();
        assert_eq!(p.nc, contacts);
        // The zero impulse is far from a solution: the error measure can fail.
        let e0 = siconos_error(&p, &vec![0.0; 2 * p.nc]);
        assert!(e0 > 1e-3, "{name}: r = 0 has error {e0}");
        let rep = solve(&p, &SolveOptions::default());
        assert!(
            rep.converged && rep.error < 1e-5,
            "{name}: error {} after {} sweeps",
            rep.error,
            rep.iterations
        );
        assert!(rep.iterations <= max_sweeps, "{name}: {} sweeps", rep.iterations);
        // The returned impulses are what the error was computed on.
        assert!((siconos_error(&p, &rep.r) - rep.error).abs() <= 1e-12);
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
