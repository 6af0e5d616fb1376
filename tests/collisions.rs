//! Closed-form collisions (docs/validation.md, "Collisions").

mod common;

use cdlab::solver::Method;
use common::*;
use glam::DVec2;

/// Two equal disks touching, approaching head-on with velocities `va`, `vb` along x.
fn pair(va: f64, vb: f64, e_n: f64) -> cdlab::model::Scene {
    let mut s = scene(0.0);
    s.material.e_n = e_n;
    s.disks.push(DVec2::new(-1.0, 0.0), 1.0, RHO).unwrap();
    s.disks.push(DVec2::new(1.0, 0.0), 1.0, RHO).unwrap();
    s.disks.vel[0] = DVec2::new(va, 0.0);
    s.disks.vel[1] = DVec2::new(vb, 0.0);
    s
}

/// Velocities of the head-on pair (2 and -1 m/s) after one step whose solver is stopped
/// after `iterations` sweeps, relaxed by `relax` from iteration `after + 1` on.
pub fn relaxed_pair(method: Method, relax: f64, after: u32, iterations: u32) -> (f64, f64) {
    let (a, b, _) = relaxed_pair_with(method, relax, after, iterations, 0.0);
    (a, b)
}

/// [`relaxed_pair`] with the velocity test at `velocity_tol` (m/s); also returns the
/// iterations taken.
fn relaxed_pair_with(
    method: Method,
    relax: f64,
    after: u32,
    iterations: u32,
    velocity_tol: f64,
) -> (f64, f64, u32) {
    let mut s = pair(2.0, -1.0, 0.0);
    let mut p = tight(method);
    p.solver.gauss_seidel.relax = relax;
    p.solver.gauss_seidel.relax_after = after;
    p.solver.max_iter = iterations;
    p.solver.velocity_tol = velocity_tol;
    let mut e = cdlab::engine::CpuEngine::new(p).unwrap();
    let st = e.step(&mut s).unwrap();
    (s.disks.vel[0].x, s.disks.vel[1].x, st.solve.iterations)
}

#[test]
fn velocity_test_stops_at_the_first_iteration_that_changes_no_velocity_by_more_than_it() {
    for method in [Method::Gs, Method::ColoredGs] {
        // Relaxed by 1/2 from a cold start, sweep k changes each disk's velocity by
        // 1.5 x 2^-k m/s, which the test divides by the relaxation: 1.5, 0.75, 0.375,
        // 0.1875 m/s. A test at 0.3 m/s stops after the fourth sweep (15/16 of the 1.5 m/s
        // change: 0.59375 and 0.40625 m/s); at 1 m/s after the second (3/4: 0.875 and
        // 0.125); off (0), at the cap of 30 (the impulse change, 2^-30 relative, stays
        // above tol = 1e-12).
        let cases = [(0.3, 4, 0.59375, 0.40625), (1.0, 2, 0.875, 0.125)];
        for (tol, its, va, vb) in cases {
            let (a, b, n) = relaxed_pair_with(method, 0.5, 0, 30, tol);
            assert_eq!(n, its, "{method:?} at {tol} m/s");
            assert!(
                (a - va).abs() < 1e-12 && (b - vb).abs() < 1e-12,
                "{method:?}: {a} {b}"
            );
        }
        let (_, _, n) = relaxed_pair_with(method, 0.5, 0, 30, 0.0);
        assert_eq!(n, 30, "{method:?}: the test off");
        // Not before iteration after + 1: with after = 5 and a test that any change meets
        // (10 m/s), the plain first sweep reaches the local solution and the second changes
        // nothing, which the impulse test accepts first.
        let (a, _, n) = relaxed_pair_with(method, 0.5, 5, 30, 10.0);
        assert_eq!((n, a), (2, 0.5), "{method:?}");
    }
}

#[test]
fn relaxed_gauss_seidel_moves_each_iteration_a_fraction_of_the_way() {
    for method in [Method::Gs, Method::ColoredGs] {
        // One contact: its local solution R* stops the approach (both at 0.5 m/s). Relaxed
        // by 1/2 from a cold start, iteration k leaves R_k = (1 - 2^-k) R*, so after three
        // sweeps 7/8 of the 1.5 m/s change of each disk: 2 - 1.3125 and -1 + 1.3125.
        let (a, b) = relaxed_pair(method, 0.5, 0, 3);
        assert!(
            (a - 0.6875).abs() < 1e-12 && (b - 0.3125).abs() < 1e-12,
            "{method:?}: {a} {b}"
        );
        // Unrelaxed first sweep: R* at once; later relaxed sweeps find nothing to change.
        let (a, b) = relaxed_pair(method, 0.5, 1, 3);
        assert!(
            (a - 0.5).abs() < 1e-12 && (b - 0.5).abs() < 1e-12,
            "{method:?}: {a} {b}"
        );
        // Converged relaxed run: the same fixed point as plain Gauss-Seidel. The test divides
        // the change by the relaxation, so stopping at 1e-12 leaves an error near 1e-12.
        let (a, b) = relaxed_pair(method, 0.5, 0, 1000);
        assert!(
            (a - 0.5).abs() < 1e-10 && (b - 0.5).abs() < 1e-10,
            "{method:?}: {a} {b}"
        );
    }
}

#[test]
fn perfectly_inelastic_head_on_collision_moves_both_at_the_mean_velocity() {
    for method in [Method::Gs, Method::ColoredGs, Method::Jacobi] {
        let mut s = pair(2.0, -1.0, 0.0);
        let p0 = momentum(&s);
        let mut e = engine(method);
        e.step(&mut s).unwrap();
        // Expected (closed form, e_n = 0, equal masses): both move at (2 + (-1)) / 2 = 0.5 m/s.
        for k in 0..2 {
            // Tolerance: the solver stops at a relative impulse change of 1e-12; relaxed Jacobi
            // (factor 0.5) leaves a remaining error of a few times that.
            assert!(
                (s.disks.vel[k].x - 0.5).abs() < 1e-10,
                "{method:?}: v{k} = {}",
                s.disks.vel[k]
            );
            assert_eq!(s.disks.vel[k].y, 0.0);
        }
        // Momentum is conserved to round-off: the contact's impulse is added to one disk and
        // taken from the other, a few ulps of the momentum at most.
        assert!((momentum(&s) - p0).length() <= 4.0 * f64::EPSILON * p0.length());
    }
}

#[test]
fn elastic_head_on_collision_swaps_velocities() {
    let mut s = pair(2.0, -1.0, 1.0);
    let mut e = engine(Method::Gs);
    e.step(&mut s).unwrap();
    // Expected (closed form, e_n = 1, equal masses): velocities swap, -1 and 2 m/s.
    assert!((s.disks.vel[0].x + 1.0).abs() < 1e-12, "{}", s.disks.vel[0]);
    assert!((s.disks.vel[1].x - 2.0).abs() < 1e-12, "{}", s.disks.vel[1]);
}

/// The head-on collisions at the built-in settings: one contact, solved exactly by its
/// first Gauss-Seidel update whatever the tolerance or relaxation, so the closed forms hold
/// to round-off; momentum to a few ulps.
#[test]
fn head_on_collisions_at_the_built_in_settings() {
    for method in [Method::ColoredGs, Method::Gs] {
        for (e_n, expected) in [(0.0, [0.5, 0.5]), (1.0, [-1.0, 2.0])] {
            let mut s = pair(2.0, -1.0, e_n);
            let p0 = momentum(&s);
            let mut e = cdlab::engine::CpuEngine::new(builtin(method)).unwrap();
            e.step(&mut s).unwrap();
            for (k, want) in expected.iter().enumerate() {
                assert!(
                    (s.disks.vel[k].x - want).abs() < 1e-12,
                    "{method:?}, e_n {e_n}: v{k} = {}, expected {want}",
                    s.disks.vel[k]
                );
            }
            assert!((momentum(&s) - p0).length() <= 4.0 * f64::EPSILON * p0.length());
        }
    }
}

#[test]
fn newtons_cradle_gives_the_simultaneous_impact_outcome() {
    // Three equal touching disks, the first at v = 1 m/s, e_n = 1. The scheme solves both
    // impacts simultaneously (Newton restitution on each contact's formal velocity), whose
    // unique solution is v = (-1/3, 2/3, 2/3) (impulses 4mv/3 and 2mv/3), not the sequential
    // "one ball out" of the textbook cradle; momentum 1 and energy 1/2 m are both conserved.
    let mut s = scene(0.0);
    s.material.e_n = 1.0;
    for k in 0..3 {
        s.disks.push(DVec2::new(2.0 * k as f64, 0.0), 1.0, RHO).unwrap();
    }
    s.disks.vel[0] = DVec2::new(1.0, 0.0);
    let mut e = engine(Method::Gs);
    for _ in 0..5 {
        e.step(&mut s).unwrap();
    }
    let expected = [-1.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0];
    for (k, want) in expected.iter().enumerate() {
        assert!(
            (s.disks.vel[k].x - want).abs() < 1e-9,
            "v{k} = {}",
            s.disks.vel[k]
        );
    }
}

/// Runs a free cloud (no walls, no external force) and returns the drift of its linear and
/// angular momentum, the scale `sum m |v|`, and the bound `alert * sum |R_t|` over all steps.
fn cloud_drift(mu: f64) -> (f64, f64, f64, f64) {
    let mut s = cloud(12, 12, 10.0, 7);
    s.material.mu_disk = mu;
    let mut e = engine(Method::ColoredGs);
    // theta = 1 makes the discrete angular momentum exact: with theta < 1 the position
    // update mixes v- and v+ and x cross v drifts at O(dt^2).
    e.params.theta = 1.0;
    let (p0, l0) = (momentum(&s), angular_momentum(&s));
    let scale: f64 = (0..s.disks.len())
        .map(|k| s.disks.mass[k] * s.disks.vel[k].length())
        .sum();
    let (mut touched, mut rt_sum) = (0, 0.0);
    for _ in 0..600 {
        // Momentum holds whether or not the sweeps converged: every update is pairwise.
        e.step(&mut s).unwrap();
        touched += e.contacts().iter().filter(|c| c.rn > 0.0).count();
        rt_sum += e.contacts().iter().map(|c| c.rt.abs()).sum::<f64>();
    }
    assert!(
        touched > 100,
        "the cloud must actually collide ({touched} loaded contacts)"
    );
    let dp = (momentum(&s) - p0).length();
    let dl = (angular_momentum(&s) - l0).abs();
    (dp, dl, scale, e.params.alert * rt_sum)
}

#[test]
fn momentum_of_a_free_cloud_is_conserved_through_collisions() {
    // Frictionless: impulses act along the line of centres, so both linear and angular
    // momentum are exact invariants of the scheme (to round-off).
    let (dp, dl, scale, _) = cloud_drift(0.0);
    assert!(dp < 1e-12 * scale, "dp = {dp:e}");
    assert!(dl < 1e-12 * scale * 30.0, "dL = {dl:e} (|x| < 30 m)");
    // Frictional: linear momentum is still exact. Angular momentum is exact up to the
    // lever-arm mismatch of contacts that close within the step: their impulse is applied
    // with the start-of-step frame while the points are still up to `alert` apart, so
    // |dL| <= alert * sum |R_t|.
    let (dp, dl, scale, bound) = cloud_drift(0.5);
    assert!(dp < 1e-12 * scale, "dp = {dp:e}");
    assert!(dl <= bound, "dL = {dl:e} above alert * sum|R_t| = {bound:e}");
}

#[test]
fn kinetic_energy_never_increases_without_external_work() {
    // Restitution 0, fixed walls, no gravity: each step can only dissipate.
    let mut s = cloud(10, 10, 5.0, 11);
    add_box(&mut s, -1.5, 22.0, -1.5, 22.0);
    s.material.mu_disk = 0.4;
    let mut e = engine(Method::ColoredGs);
    let mut ke = s.disks.kinetic_energy();
    let ke0 = ke;
    for step in 0..300 {
        e.step(&mut s).unwrap();
        let now = s.disks.kinetic_energy();
        // Allow the solver's relative tolerance (1e-12) on the impulses, nothing more.
        assert!(now <= ke * (1.0 + 1e-12), "step {step}: {ke} -> {now} J/m");
        ke = now;
    }
    assert!(ke < 0.9 * ke0, "collisions must dissipate: {ke0} -> {ke} J/m");
}

/// Three equal disks in a row along x: A (20 m/s) touching B, B at rest with a gap `gap`
/// to C at rest. One step with open contacts parked when their opening velocity exceeds
/// `open_skip` (m/s); returns the three velocities and whether the step was solved again
/// with every contact.
fn row_of_three(method: Method, gap: f64, open_skip: f64) -> ([f64; 3], bool) {
    let mut s = scene(0.0);
    for x in [-2.0, 0.0, 2.0 + gap] {
        s.disks.push(DVec2::new(x, 0.0), 1.0, RHO).unwrap();
    }
    s.disks.vel[0] = DVec2::new(20.0, 0.0);
    let mut p = tight(method);
    p.solver.open_skip = open_skip;
    let mut e = cdlab::engine::CpuEngine::new(p).unwrap();
    let st = e.step(&mut s).unwrap();
    ([0, 1, 2].map(|k| s.disks.vel[k].x), st.solve.unparked)
}

#[test]
fn a_parked_open_contact_that_would_close_is_solved_with_the_others() {
    for method in [Method::Gs, Method::ColoredGs] {
        // Gap 2 mm, dt 5e-4 s, theta 0.5: B may approach C at up to g / (theta dt) = 8 m/s
        // before the gap closes within the step. At the start B is at rest, so B-C opens at
        // 8 m/s and is parked under a 1 m/s threshold; A's impact then drives B into C.
        // Closed form (e_n = 0, equal masses): A and B end together at v, C at v - 8 (the
        // gap closes exactly), momentum 20 = 3 v - 8, so v = 28/3 and C moves at 4/3 m/s.
        // Without the recheck of parked contacts, C would stay at rest.
        for (open_skip, parked) in [(1.0, true), (100.0, false)] {
            let (v, unparked) = row_of_three(method, 2e-3, open_skip);
            assert_eq!(unparked, parked, "{method:?}, threshold {open_skip} m/s");
            let want = [28.0 / 3.0, 28.0 / 3.0, 4.0 / 3.0];
            for k in 0..3 {
                assert!(
                    (v[k] - want[k]).abs() < 1e-8,
                    "{method:?}, threshold {open_skip} m/s: {v:?}"
                );
            }
        }
        // Gap 4 mm: B-C may approach at 16 m/s and A-B leaves B at 10 m/s, so the parked
        // contact stays open and the step ends without a second solve: A and B at 10 m/s.
        let (v, unparked) = row_of_three(method, 4e-3, 1.0);
        assert!(!unparked, "{method:?}");
        assert!(
            (v[0] - 10.0).abs() < 1e-8 && (v[1] - 10.0).abs() < 1e-8 && v[2] == 0.0,
            "{method:?}: {v:?}"
        );
    }
}

/// An oblique bounce off a wall with normal and tangential restitution (Newton's law on the
/// contact point's velocity, docs/method.md, "Restitution"): a disk touching the floor, no gravity, arriving
/// at (v_x, -v_y) = (1, -2) m/s without spin, e_n = 0.5, e_t = 0.5, friction 1 (sticking).
/// Closed form: the normal velocity leaves at e_n v_y = 1 m/s; the contact point's
/// tangential velocity u_t = v_x + r w goes from 1 to -e_t = -0.5 m/s through the impulse
/// P_t = -(1 + e_t) u_t m / 3 (tangential inverse mass 1/m + r^2/I = 3/m for a disk), so
/// v_x = 1 - 1.5 / 3 = 0.5 m/s and w = (-0.5 - 0.5) / r. Sticking holds: |P_t| = 0.5 m
/// <= mu P_n = 1.5 m. The kinetic energy drops (e < 1).
#[test]
fn oblique_bounce_off_a_wall_with_tangential_restitution() {
    let r = 0.5;
    for method in [Method::Gs, Method::ColoredGs] {
        let mut s = scene(1.0);
        s.material.e_n = 0.5;
        s.material.e_t = 0.5;
        s.walls.push(floor());
        s.disks.push(DVec2::new(0.0, r), r, RHO).unwrap();
        s.disks.vel[0] = DVec2::new(1.0, -2.0);
        let ke0 = s.disks.kinetic_energy();
        let mut e = engine(method);
        e.step(&mut s).unwrap();
        let (v, w) = (s.disks.vel[0], s.disks.spin[0]);
        let close = |got: f64, want: f64, what: &str| {
            assert!(
                (got - want).abs() < 1e-9,
                "{method:?}: {what} = {got}, expected {want}"
            )
        };
        close(v.y, 1.0, "v_y (m/s)");
        close(v.x, 0.5, "v_x (m/s)");
        close(w, -1.0 / r, "spin (rad/s)");
        close(v.x + r * w, -0.5, "contact point's tangential velocity (m/s)");
        assert!(s.disks.kinetic_energy() < ke0, "{method:?}: energy must drop");
        // Free flight afterwards: it leaves the wall and keeps its velocity.
        e.step(&mut s).unwrap();
        assert_eq!(s.disks.vel[0], v, "{method:?}: no second impulse");
    }
}
