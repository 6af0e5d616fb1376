//! The exact local Signorini-Coulomb solution (docs/validation.md, "Local law").

mod common;

use cdlab::solver::law::{solve_block, solve_diagonal};
use common::Rng;

/// Checks Signorini and Coulomb on the post-solve velocity u = W r + u_free; returns the
/// case hit: 0 separating, 1 sticking, 2 sliding.
fn check(w: [[f64; 2]; 2], uf: [f64; 2], mu: f64, r: [f64; 2]) -> usize {
    let u = [
        w[0][0] * r[0] + w[0][1] * r[1] + uf[0],
        w[1][0] * r[0] + w[1][1] * r[1] + uf[1],
    ];
    let scale = 1e-12 * (1.0 + uf[0].abs() + uf[1].abs());
    let rscale = 1e-12 * (1.0 + r[0].abs() + r[1].abs());
    // Signorini: u_n >= 0, r_n >= 0, u_n r_n = 0.
    assert!(r[0] >= 0.0 && u[0] >= -scale, "signorini {r:?} {u:?}");
    assert!(
        (u[0] * r[0]).abs() <= scale * rscale * 1e12,
        "complementarity {r:?} {u:?}"
    );
    // Coulomb: |r_t| <= mu r_n, and r_t = -mu r_n sign(u_t) when u_t != 0.
    assert!(r[1].abs() <= mu * r[0] + rscale, "cone {r:?}");
    if r[0] == 0.0 {
        return 0;
    }
    if u[1].abs() <= scale {
        1
    } else {
        assert!(
            (r[1] + mu * r[0] * u[1].signum()).abs() <= rscale,
            "slide {r:?} {u:?}"
        );
        2
    }
}

#[test]
fn diagonal_local_solution_satisfies_signorini_and_coulomb_in_all_three_cases() {
    let mut rng = Rng(3);
    let mut hits = [0; 3];
    for _ in 0..20_000 {
        let (wnn, wtt) = (rng.range(0.1, 10.0), rng.range(0.1, 30.0));
        let uf = [rng.range(-5.0, 5.0), rng.range(-5.0, 5.0)];
        let mu = rng.range(0.0, 2.0);
        let (rn, rt) = solve_diagonal(wnn, wtt, uf[0], uf[1], mu);
        hits[check([[wnn, 0.0], [0.0, wtt]], uf, mu, [rn, rt])] += 1;
    }
    assert!(
        hits.iter().all(|&h| h > 1000),
        "each case must be exercised: {hits:?}"
    );
}

#[test]
fn diagonal_local_solution_matches_hand_computed_cases() {
    // Separating: u_free_n = +1 gives no impulse.
    assert_eq!(solve_diagonal(2.0, 6.0, 1.0, -3.0, 0.5), (0.0, 0.0));
    // Sticking: r_n = 4/2 = 2, r_t = 3/6 = 0.5 <= 0.5 * 2.
    assert_eq!(solve_diagonal(2.0, 6.0, -4.0, -3.0, 0.5), (2.0, 0.5));
    // Sliding: r_n = 2, the stick value 12/6 = 2 exceeds mu r_n = 1, so r_t = 1.
    assert_eq!(solve_diagonal(2.0, 6.0, -4.0, -12.0, 0.5), (2.0, 1.0));
}

#[test]
fn coupled_block_solution_satisfies_signorini_and_coulomb() {
    let mut rng = Rng(5);
    let mut hits = [0; 3];
    for _ in 0..20_000 {
        let (a, b) = (rng.range(0.1, 10.0), rng.range(0.1, 10.0));
        // |W_nt| up to 0.9 sqrt(W_nn W_tt): positive definite.
        let c = rng.range(-0.9, 0.9) * (a * b).sqrt();
        let uf = [rng.range(-5.0, 5.0), rng.range(-5.0, 5.0)];
        let mu = rng.range(0.0, 2.0);
        let (rn, rt) = solve_block(a, b, c, uf[0], uf[1], mu);
        hits[check([[a, c], [c, b]], uf, mu, [rn, rt])] += 1;
    }
    assert!(
        hits.iter().all(|&h| h > 1000),
        "each case must be exercised: {hits:?}"
    );
}

/// Friction exactly 0: no tangential impulse at all, and the normal impulse closes the
/// contact alone, R_n = -u_free_n / W_nn (Signorini with a frictionless cone), for the
/// diagonal and the coupled block alike (with mu = 0 the coupled slide has u_n = 0 and
/// R_t = 0, so W_nn R_n + u_free_n = 0).
#[test]
fn zero_friction_gives_no_tangential_impulse() {
    let mut rng = Rng(11);
    for _ in 0..2000 {
        let (a, b) = (rng.range(0.1, 10.0), rng.range(0.1, 10.0));
        let c = rng.range(-0.9, 0.9) * (a * b).sqrt();
        let uf = [rng.range(-5.0, -0.01), rng.range(-5.0, 5.0)];
        let (rn, rt) = solve_diagonal(a, b, uf[0], uf[1], 0.0);
        assert_eq!(rt, 0.0);
        assert_eq!(rn, -uf[0] / a);
        let (rn, rt) = solve_block(a, b, c, uf[0], uf[1], 0.0);
        assert_eq!(rt, 0.0, "block {a} {b} {c} {uf:?}");
        assert!(
            (rn + uf[0] / a).abs() <= 1e-12 * rn,
            "block: {rn}, expected {}",
            -uf[0] / a
        );
    }
}

/// Friction above 2 (a rough-walled test uses up to 10): the same laws, with sticking and
/// sliding both exercised.
#[test]
fn friction_above_two_satisfies_signorini_and_coulomb() {
    let mut rng = Rng(12);
    let mut hits = [[0; 3]; 2];
    for _ in 0..20_000 {
        let (a, b) = (rng.range(0.1, 10.0), rng.range(0.1, 30.0));
        let c = rng.range(-0.9, 0.9) * (a * b).sqrt();
        // Tangential free velocities up to 200 times the normal one, so that even mu = 10
        // slides.
        let uf = [rng.range(-5.0, 5.0), rng.range(-1000.0, 1000.0)];
        let mu = rng.range(2.0, 10.0);
        let (rn, rt) = solve_diagonal(a, b, uf[0], uf[1], mu);
        hits[0][check([[a, 0.0], [0.0, b]], uf, mu, [rn, rt])] += 1;
        let (rn, rt) = solve_block(a, b, c, uf[0], uf[1], mu);
        hits[1][check([[a, c], [c, b]], uf, mu, [rn, rt])] += 1;
    }
    assert!(
        hits.iter().flatten().all(|&h| h > 500),
        "each case must be exercised: {hits:?}"
    );
}

/// W_tt = 0: a tangential impulse moves nothing (no tangential mobility), so the law
/// leaves it at 0 whatever the tangential velocity, and the normal impulse is unchanged.
#[test]
fn no_tangential_mobility_gives_no_tangential_impulse() {
    for (ufn, uft, mu) in [(-4.0, -3.0, 0.5), (-4.0, 7.0, 2.5), (1.0, 3.0, 0.3)] {
        let (rn, rt) = solve_diagonal(2.0, 0.0, ufn, uft, mu);
        assert_eq!(rt, 0.0, "{ufn} {uft} {mu}");
        assert_eq!(rn, if ufn < 0.0 { -ufn / 2.0 } else { 0.0 });
    }
}

/// A singular block (W_nt^2 = W_nn W_tt: a body that moves only along one oblique axis)
/// has no sticking solution to solve for (the stick branch needs det > 0); the law must
/// still find the slide that satisfies Signorini and Coulomb, in both directions.
#[test]
fn singular_block_slides_by_the_law() {
    let mut rng = Rng(13);
    let mut hits = [0; 3];
    for _ in 0..5000 {
        let (a, b) = (rng.range(0.1, 10.0), rng.range(0.1, 10.0));
        let c = (a * b).sqrt() * if rng.uniform() < 0.5 { 1.0 } else { -1.0 };
        let uf = [rng.range(-5.0, -0.01), rng.range(-5.0, 5.0)];
        // Below 1/(slope of the axis) the slide's normal equation stays solvable.
        let mu = rng.range(0.0, 0.9) * (a / b).sqrt();
        let (rn, rt) = solve_block(a, b, c, uf[0], uf[1], mu);
        assert!(rn > 0.0, "an approaching contact pushes: {rn}");
        hits[check([[a, c], [c, b]], uf, mu, [rn, rt])] += 1;
    }
    assert!(hits[2] > 1000, "sliding must be exercised: {hits:?}");
}

/// The last branch of `solve_block`, taken when neither the stick solution nor a slide with
/// a consistent sliding direction exists. A positive-definite block always has one of them,
/// so the branch serves round-off at a case boundary; an indefinite block (W_nt^2 > W_nn
/// W_tt, which no pair of bodies produces) reaches it for certain. Its contract: the last
/// slide whose normal equation was solvable, which closes the contact exactly (u_n = 0)
/// on the edge of the Coulomb cone (|R_t| = mu R_n, R_n >= 0).
#[test]
fn the_fallback_returns_a_closing_slide_on_the_cone() {
    // W = [[1, 2], [2, 1]], mu = 1: sliding with s = +1 has W_nn - mu W_nt = -1 <= 0 (no
    // solution); s = -1 gives R_n = 1/3, R_t = +1/3 and u_t = 5 + (W_nt + mu W_tt) R_n = 6,
    // of the wrong sign for s = -1 (which needs u_t <= 0); det W = -3 rules out sticking. So
    // every direct branch fails.
    let (wnn, wtt, wnt, ufn, uft, mu) = (1.0, 1.0, 2.0, -1.0, 5.0, 1.0);
    let ut = uft + (wnt + mu * wtt) / 3.0;
    assert!(ut > 0.0 && wnn * wtt - wnt * wnt < 0.0 && wnn - mu * wnt <= 0.0);
    let (rn, rt) = solve_block(wnn, wtt, wnt, ufn, uft, mu);
    // Expected from the slide equations above (s = -1): R_n = -u_n / (W_nn + mu W_nt).
    assert!((rn - 1.0 / 3.0).abs() < 1e-15, "{rn}");
    assert!((rt - 1.0 / 3.0).abs() < 1e-15, "{rt}");
    let un = ufn + wnn * rn + wnt * rt;
    assert!(un.abs() < 1e-15, "the contact closes exactly: u_n = {un}");
    assert!((rt.abs() - mu * rn).abs() < 1e-15 && rn >= 0.0);
}
