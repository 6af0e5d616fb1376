//! The contact problem as every iterative solver sees it (`solver::space`): a kept step
//! replays exactly, both stores of a problem (the engine's bodies and fc2d's Delassus
//! matrix) give the same Gauss-Seidel, and the common measures read what they claim.

mod common;

use std::path::Path;

use cdlab::fc2d::{self, SolveOptions, siconos_error};
use cdlab::solver::Method;
use cdlab::solver::space::{ContactSpace, closing, local_residual, local_solution};
use common::{RHO, add_box, cloud, engine, floor, scene};
use glam::DVec2;

/// A pile of 64 disks settled under gravity in a box, with capture on.
fn settled_pile(method: Method) -> (cdlab::engine::CpuEngine, cdlab::model::Scene) {
    let mut s = cloud(8, 8, 0.0, 7);
    s.gravity = DVec2::new(0.0, -9.81);
    add_box(&mut s, -1.5, 17.0, -1.5, 40.0);
    let mut e = engine(method);
    e.params.solver.tol = 1e-6;
    e.params.dt = 2e-3;
    for _ in 0..400 {
        e.step(&mut s).unwrap();
    }
    e.capture(true);
    e.step(&mut s).unwrap();
    (e, s)
}

#[test]
fn a_kept_step_solved_again_gives_the_engines_impulses_bit_for_bit() {
    for method in [Method::ColoredGs, Method::Gs, Method::Jacobi] {
        let (e, _) = settled_pile(method);
        let kept = e.captured().expect("capture is on and a step ran");
        assert_eq!(kept.contacts.len(), e.contacts().len());
        let (solved, stats) = kept.solve(&e.params.solver);
        assert!(stats.iterations > 0);
        for (a, b) in solved.contacts.iter().zip(e.contacts()) {
            assert_eq!(a.rn.to_bits(), b.rn.to_bits(), "{method:?}");
            assert_eq!(a.rt.to_bits(), b.rt.to_bits(), "{method:?}");
        }
        // The pile carries its weight: some contact is loaded.
        assert!(solved.contacts.iter().any(|c| c.rn > 0.0));
    }
}

#[test]
fn the_distance_to_the_local_solutions_is_small_after_a_solve_and_not_before() {
    let (e, _) = settled_pile(Method::Gs);
    let kept = e.captured().unwrap();
    let (mut solved, _) = kept.solve(&e.params.solver);
    // Stopping at a relative change of 1e-6, plain Gauss-Seidel leaves each impulse about
    // that close to its local solution.
    let after = local_residual(&solved.space());
    assert!(after < 1e-5, "after the solve: {after:e}");
    // From zero impulses the local solutions are far: the measure can fail.
    let mut zero = kept.clone();
    let n = zero.contacts.len();
    zero.space().set_all(&vec![(0.0, 0.0); n]);
    let before = local_residual(&zero.space());
    assert!(before > 0.5, "at zero impulses: {before:e}");
}

#[test]
fn setting_impulses_one_by_one_or_all_at_once_gives_the_same_velocities() {
    let (e, _) = settled_pile(Method::Gs);
    let mut a = e.captured().unwrap().clone();
    let mut b = a.clone();
    let target: Vec<(f64, f64)> = a.contacts.iter().map(|c| (0.5 * c.rn, 0.25 * c.rt)).collect();
    {
        let mut s = a.space();
        for (k, &(rn, rt)) in target.iter().enumerate() {
            s.set(k, rn, rt);
        }
    }
    b.space().set_all(&target);
    let scale = a.gv.iter().map(|v| v.length()).fold(0.0, f64::max);
    for (u, v) in a.gv.iter().zip(&b.gv) {
        // Same sums in another order: round-off only.
        assert!((*u - *v).length() <= 1e-12 * scale, "{u} vs {v}");
    }
}

#[test]
fn one_disk_resting_on_the_floor_needs_its_weight_times_dt() {
    // A disk at rest touching a fixed floor: the free velocity is -g dt, so the exact
    // impulse is R_n = m g dt (N s per m) and R_t = 0; with half of it the contact still
    // closes at g dt / 2.
    let (g, dt, r) = (9.81, 1e-3, 0.5);
    let mut s = scene(0.3);
    s.gravity = DVec2::new(0.0, -g);
    s.walls.push(floor());
    s.disks.push(DVec2::new(0.0, r), r, RHO).unwrap();
    let m = s.disks.mass[0];
    let mut e = engine(Method::Gs);
    e.params.dt = dt;
    e.capture(true);
    e.step(&mut s).unwrap();
    let mut kept = e.captured().unwrap().clone();
    let mut space = kept.space();
    assert_eq!(space.len(), 1);
    space.set_all(&[(0.0, 0.0)]);
    let (rn, rt) = local_solution(&space, 0);
    assert!(
        (rn - m * g * dt).abs() <= 1e-12 * m * g * dt,
        "R_n {rn}, m g dt {}",
        m * g * dt
    );
    assert_eq!(rt, 0.0);
    // Nothing carried, everything asked: relative distance 1.
    assert!((local_residual(&space) - 1.0).abs() < 1e-12);
    assert_eq!(closing(&space).loaded, 0);
    space.set_all(&[(0.5 * rn, 0.0)]);
    let c = closing(&space);
    assert_eq!(c.loaded, 1);
    assert!((c.max - 0.5 * g * dt).abs() <= 1e-12, "closing {} m/s", c.max);
    assert!((local_residual(&space) - 0.5).abs() < 1e-12);
    space.set_all(&[(rn, 0.0)]);
    assert!(local_residual(&space) < 1e-12);
    assert!(closing(&space).max < 1e-12);
}

#[test]
fn gauss_seidel_through_the_space_repeats_the_fc2d_solver() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fc2d/fc2d_granularflowonwall_02020_00213.dat");
    let p = fc2d::read(&path).unwrap();
    let opts = SolveOptions {
        tol: 1e-5,
        max_iter: 2000,
        check_every: 10,
    };
    let reference = fc2d::solve(&p, &opts);
    assert!(reference.converged && reference.iterations > 100);
    let mut s = fc2d::Space::new(&p);
    for _ in 0..reference.iterations {
        for c in 0..s.len() {
            let (rn, rt) = local_solution(&s, c);
            s.set(c, rn, rt);
        }
    }
    // Equal to round-off: the space's local solve takes the diagonal form of
    // `solver::law` when a block's coupling term is 0, fc2d always the full 2x2 form,
    // which rounds differently.
    let scale = reference.r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    for (a, b) in s.impulses().iter().zip(&reference.r) {
        assert!((a - b).abs() <= 1e-9 * scale, "{a} vs {b}");
    }
    assert!(siconos_error(&p, s.impulses()) < 1e-5);
    // Near a solution both measures are small; far from it (r = 0) both are large.
    assert!(local_residual(&s) < 1e-3, "{:e}", local_residual(&s));
    let n = s.len();
    s.set_all(&vec![(0.0, 0.0); n]);
    assert!(local_residual(&s) > 0.5);
}

/// Jacobi's stopping test reads the unrelaxed change (docs/method.md, "Jacobi"): the change
/// of iteration `k` divided by `jacobi_relax` is `|L(x_{k-1}) - x_{k-1}|`, the distance of
/// the previous iterate to its local solutions (`space::local_solution`), over `|x_k|`.
/// A test of the relaxed change reads `jacobi_relax` (0.5 here) times this and fails.
#[test]
fn jacobis_stopping_test_reads_the_unrelaxed_change() {
    let (e, _) = settled_pile(Method::Jacobi);
    let kept = e.captured().unwrap();
    let mut p = e.params.solver;
    assert_eq!(
        p.jacobi.relax, 0.5,
        "the default relaxation, which the old test halved"
    );
    p.tol = 1e-30;
    let k = 7;
    p.max_iter = k;
    let (mut xk, stats) = kept.solve(&p);
    assert_eq!(stats.iterations, k);
    p.max_iter = k - 1;
    let (mut prev, _) = kept.solve(&p);
    let (prev, xk) = (prev.space(), xk.space());
    let (mut d2, mut r2) = (0.0, 0.0);
    for c in 0..prev.len() {
        let (ln, lt) = local_solution(&prev, c);
        let (rn, rt) = prev.impulse(c);
        d2 += (ln - rn).powi(2) + (lt - rt).powi(2);
        let (rn, rt) = xk.impulse(c);
        r2 += rn * rn + rt * rt;
    }
    let want = (d2 / r2).sqrt();
    assert!(want > 1e-6, "the iterate is still moving: {want:e}");
    assert!(
        (stats.residual - want).abs() <= 1e-9 * want,
        "reported {:e}, unrelaxed change {want:e}",
        stats.residual
    );
}
