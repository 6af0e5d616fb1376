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
