//! Static force transmission checked against hand calculations (docs/validation.md,
//! "Statics").

mod common;

use cdlab::model::Scene;
use cdlab::solver::Method;
use common::*;
use glam::DVec2;

const G: f64 = 9.81;

/// Normal force (N/m) of the contact between disk `i` and body `j` (either order).
fn normal_force(_s: &Scene, e: &cdlab::engine::CpuEngine, i: usize, j: usize) -> f64 {
    let c = e
        .contacts()
        .iter()
        .find(|c| (c.i as usize, c.disk_j as usize) == (i, j) || (c.i as usize, c.disk_j as usize) == (j, i))
        .unwrap_or_else(|| panic!("no contact {i}-{j}"));
    c.rn / e.params.dt
}

fn column(gravity: bool, method: Method) {
    column_of(5, gravity, method);
}

fn column_of(n: usize, gravity: bool, method: Method) {
    // Tolerance 1e-6 of the force: the solver's relative tolerance is 1e-12 but a chain of
    // 6 contacts converges slowly under Gauss-Seidel.
    column_with(n, gravity, tight(method), 20, 1e-6, 1e-6);
}

/// A column of `n` disks between the floor and a force-driven top wall, `steps` steps with
/// `params`; every contact's force within `rel` of the force against the hand calculation,
/// and the top wall at rest within `still` (m/s).
fn column_with(
    n: usize,
    gravity: bool,
    params: cdlab::engine::StepParams,
    steps: usize,
    rel: f64,
    still: f64,
) {
    let (r, force) = (1.0, 2.0e6);
    // Top wall: force-driven along its inward normal (-y).
    let mut s = common::column(n, r, if gravity { G } else { 0.0 }, Some(force));
    let weight = s.disks.mass[0] * G * gravity as u8 as f64;
    let mut e = cdlab::engine::CpuEngine::new(params).unwrap();
    for _ in 0..steps {
        e.step(&mut s).unwrap();
    }
    let (floor_body, top_body) = (n, n + 1);
    // Expected: the contact above disk k carries F plus the weights of the disks above it;
    // the floor carries F plus the whole weight.
    let tol = rel * force;
    let top = normal_force(&s, &e, n - 1, top_body);
    assert!(
        (top - force).abs() < tol,
        "top contact {top} N/m, expected {force}"
    );
    for k in 0..n - 1 {
        let expected = force + weight * (n - 1 - k) as f64;
        let got = normal_force(&s, &e, k, k + 1);
        assert!(
            (got - expected).abs() < tol,
            "contact {k}-{}: {got}, expected {expected} N/m",
            k + 1
        );
    }
    let expected = force + weight * n as f64;
    let got = normal_force(&s, &e, 0, floor_body);
    assert!(
        (got - expected).abs() < tol,
        "floor {got}, expected {expected} N/m"
    );
    // The wall impulse balance agrees: the floor pushes up by the same total.
    let imp = e.wall_impulses();
    assert!(
        (imp[0].y / e.params.dt + expected).abs() < tol,
        "floor reaction {}",
        imp[0].y / e.params.dt
    );
    // The column is rigid and in equilibrium: the force-driven wall has stopped.
    assert!(
        s.walls[1].vel.length() < still,
        "top wall velocity {}",
        s.walls[1].vel
    );
}

#[test]
fn loaded_column_carries_the_top_force_through_every_contact() {
    column(false, Method::Gs);
    column(false, Method::ColoredGs);
}

/// The loaded column at the built-in settings (relaxation, velocity test, local updates
/// of deep contacts, tolerance 1e-4), left 200 steps to settle: every force within 1e-4
/// of the top force (the solver's tolerance) and the top wall at rest within 1e-5 m/s (the
/// velocity test's `velocity_tol`). After the 20 steps of the tight twin the column is
/// still settling at these settings (1.1e-3 of the force, the wall at 3.4e-5 m/s); after
/// 100 steps 3.5e-5, after 200 steps 1e-6.
#[test]
fn loaded_column_at_the_built_in_settings() {
    for method in [Method::ColoredGs, Method::Gs] {
        column_with(5, true, builtin(method), 200, 1e-4, 1e-5);
    }
}

#[test]
fn loaded_column_under_gravity_adds_the_weights_above() {
    column(true, Method::Gs);
    column(true, Method::ColoredGs);
}

/// Jacobi (every contact updated from the same iterate, relaxed) on a column of 30 disks,
/// 31 contacts in one chain: a determinate problem whose forces the hand calculation fixes
/// (top force plus the weights above each contact), the same as Gauss-Seidel reaches. A
/// chain is Jacobi's slow case (information travels one contact per iteration).
#[test]
fn jacobi_on_a_long_loaded_column_reaches_the_statically_determined_forces() {
    column_of(30, true, Method::Jacobi);
    column_of(30, true, Method::Gs);
}

#[test]
fn frictionless_pyramid_in_a_box_matches_the_hand_calculation() {
    // Two disks of radius 1 on the floor touching each other and the side walls, a third
    // resting on both (centres 60 degrees apart), gravity on, no friction.
    let mut s = scene(0.0);
    s.gravity = DVec2::new(0.0, -G);
    add_box(&mut s, -2.0, 2.0, 0.0, 100.0);
    s.disks.push(DVec2::new(-1.0, 1.0), 1.0, RHO).unwrap();
    s.disks.push(DVec2::new(1.0, 1.0), 1.0, RHO).unwrap();
    s.disks
        .push(DVec2::new(0.0, 1.0 + 3f64.sqrt()), 1.0, RHO)
        .unwrap();
    let w = s.disks.mass[2] * G;
    let mut e = engine(Method::Gs);
    for _ in 0..10 {
        e.step(&mut s).unwrap();
    }
    let (floor, left, right) = (3, 5, 6);
    // Hand calculation. Seven contact forces, six equations of equilibrium (two per disk):
    // the problem is statically indeterminate, and the force N_01 between the two bottom
    // disks can take any value >= 0 (pressing them together more loads the side walls by as
    // much). What statics fixes, and only that, is asserted:
    // - top disk: its two contacts, 60 degrees apart about the vertical, carry
    //   N = W / (2 cos 30) = W / sqrt(3) each (its horizontal balance makes them equal);
    // - bottom disk, vertical: the floor carries its weight plus N cos 30 = W / 2, so 1.5 W;
    // - bottom disk, horizontal: its side wall carries N sin 30 + N_01 = W / (2 sqrt 3) +
    //   N_01, so both walls carry the same force, at least W / (2 sqrt 3);
    // - every normal force is >= 0 (contacts only push), and each disk's contact forces
    //   and weight sum to zero as vectors.
    let tol = 1e-6 * w;
    let n_top = w / 3f64.sqrt();
    let n_01 = normal_force(&s, &e, 0, 1);
    assert!(n_01 >= -tol, "bottom disks pull each other with {n_01} N/m");
    let mut side_forces = Vec::new();
    for (bottom, side) in [(0, left), (1, right)] {
        let got = normal_force(&s, &e, 2, bottom);
        assert!(
            (got - n_top).abs() < tol,
            "top-{bottom}: {got}, expected {n_top} N/m"
        );
        let got = normal_force(&s, &e, bottom, floor);
        assert!(
            (got - 1.5 * w).abs() < tol,
            "floor under {bottom}: {got}, expected {} N/m",
            1.5 * w
        );
        let got = normal_force(&s, &e, bottom, side);
        let expected = w / (2.0 * 3f64.sqrt()) + n_01;
        assert!(
            (got - expected).abs() < tol,
            "wall at {bottom}: {got}, expected W/(2 sqrt 3) + N_01 = {expected} N/m"
        );
        side_forces.push(got);
    }
    assert!(
        (side_forces[0] - side_forces[1]).abs() < tol,
        "side walls {side_forces:?} N/m: the box is not in horizontal equilibrium"
    );
    assert_each_disk_balanced(&s, &e, tol);
}

/// Each disk's contact forces (impulse / dt along the normal, which points from j to i; no
/// friction, so no tangential part) and its weight sum to zero; every normal force pushes.
fn assert_each_disk_balanced(s: &Scene, e: &cdlab::engine::CpuEngine, tol: f64) {
    let dt = e.params.dt;
    for k in 0..s.disks.len() {
        let mut sum = s.disks.mass[k] * s.gravity;
        for c in e.contacts() {
            if c.i as usize == k {
                sum += c.n * c.rn / dt;
            } else if c.j as usize == k {
                sum -= c.n * c.rn / dt;
            }
            assert!(c.rn >= 0.0, "contact {}-{}: normal impulse {}", c.i, c.j, c.rn);
            assert_eq!(c.rt, 0.0, "friction 0: no tangential impulse");
        }
        assert!(sum.length() < tol, "disk {k}: forces sum to {sum} N/m");
    }
}

/// Two layers in a box, larger than the pyramid: four disks of radius 1 on the floor in a
/// row from wall to wall (centres x = -3, -1, 1, 3), two more in the outer pockets (x = -2
/// and 2, 60 degrees above their supports, not touching each other or the walls); gravity,
/// no friction. Hand calculation (W = weight of a disk, N_a the force between the two left
/// bottom disks, left undetermined by statics like the pyramid's N_01):
/// - each upper disk rests on two contacts of W / sqrt(3);
/// - each bottom disk carries one upper contact: the floor under it carries 1.5 W;
/// - horizontal balance of the bottom disks from the left: wall = W/(2 sqrt 3) + N_a; the
///   middle contact = N_a + W/(2 sqrt 3); the same from the right with N_c, and the middle
///   disks' balances give N_a = N_c. So the two walls carry the same force and the middle
///   contact exceeds each outer one by exactly W / (2 sqrt 3): it is never unloaded.
#[test]
fn two_layers_in_a_box_match_the_hand_calculation() {
    let mut s = scene(0.0);
    s.gravity = DVec2::new(0.0, -G);
    add_box(&mut s, -4.0, 4.0, 0.0, 100.0);
    for x in [-3.0, -1.0, 1.0, 3.0] {
        s.disks.push(DVec2::new(x, 1.0), 1.0, RHO).unwrap();
    }
    for x in [-2.0, 2.0] {
        s.disks.push(DVec2::new(x, 1.0 + 3f64.sqrt()), 1.0, RHO).unwrap();
    }
    let w = s.disks.mass[0] * G;
    let mut e = engine(Method::Gs);
    for _ in 0..10 {
        e.step(&mut s).unwrap();
    }
    // Bodies: disks 0-5, then the walls of add_box (floor, top, left, right).
    let (floor, left, right) = (6, 8, 9);
    let tol = 1e-6 * w;
    let near = |got: f64, expected: f64, what: &str| {
        assert!(
            (got - expected).abs() < tol,
            "{what}: {got} N/m, expected {expected} N/m"
        )
    };
    let n_up = w / 3f64.sqrt();
    let h = w / (2.0 * 3f64.sqrt());
    for (upper, supports) in [(4, [0, 1]), (5, [2, 3])] {
        for b in supports {
            near(
                normal_force(&s, &e, upper, b),
                n_up,
                &format!("upper {upper} on {b}"),
            );
        }
    }
    for b in 0..4 {
        near(
            normal_force(&s, &e, b, floor),
            1.5 * w,
            &format!("floor under {b}"),
        );
    }
    let (n_a, n_b, n_c) = (
        normal_force(&s, &e, 0, 1),
        normal_force(&s, &e, 1, 2),
        normal_force(&s, &e, 2, 3),
    );
    near(normal_force(&s, &e, 0, left), h + n_a, "left wall");
    near(normal_force(&s, &e, 3, right), h + n_c, "right wall");
    near(n_b, n_a + h, "middle contact");
    near(n_a, n_c, "outer contacts");
    assert!(n_b >= h - tol, "middle contact {n_b} N/m, at least {h} N/m");
    // The upper disks touch neither each other nor the walls.
    for c in e.contacts() {
        let pair = (c.i as usize, c.disk_j as usize);
        assert!(
            !matches!(pair, (4, 5) | (5, 4) | (4, 8) | (5, 9)),
            "unexpected contact {pair:?}"
        );
    }
    assert_each_disk_balanced(&s, &e, tol);
}

/// A column of disks on the floor under gravity whose two lowest disks overlap by 1% of
/// their radius (the others touch), after one step of two Gauss-Seidel (or Jacobi) iterations. Without
/// local updates the iterations stop with that contact still closing (the contacts above,
/// solved after it, push disk 1 down). With `deep_gap` below its overlap that contact alone
/// is updated again and leaves the step satisfying its law exactly: the normal relative
/// velocity `U_n^+` of a loaded contact is 0 (the Signorini law of docs/method.md; theta 0.5 from
/// rest). The contacts that are not deep are not touched: disk 2 keeps the velocity the
/// iterations left.
#[test]
fn a_deep_loaded_contact_leaves_the_step_satisfying_its_law() {
    let (n, r) = (5usize, 1.0);
    for method in [Method::Gs, Method::ColoredGs, Method::Jacobi] {
        let run = |deep_gap: f64| {
            let mut s = sunk_column(n, r, G);
            let mut p = tight(method);
            p.solver.max_iter = 2;
            p.solver.deep_gap = deep_gap;
            p.solver.deep_sweeps = 3;
            let mut e = cdlab::engine::CpuEngine::new(p).unwrap();
            let stats = e.step(&mut s).unwrap();
            let v = &s.disks.vel;
            (v[1].y - v[0].y, v[2].y, stats.solve.deep)
        };
        let (off, above_off, none) = run(0.0);
        assert_eq!(none, 0, "{method:?}");
        assert!(
            off < -1e-4,
            "{method:?}: without local updates the contact should still close; it opens at {off} m/s"
        );
        let (on, above_on, deep) = run(0.005 * r);
        // One contact is deep: disks 0-1 (the floor contact and the others touch).
        assert_eq!(deep, 1, "{method:?}");
        assert!(
            on.abs() < 1e-12,
            "{method:?}: the deep contact leaves at {on} m/s, expected 0"
        );
        assert_eq!(above_on, above_off, "{method:?}");
    }
}

/// `solver.check_every` takes effect on the CPU: the iterates are those of a test every
/// iteration, so a step tested every 5 iterations stops at the first multiple of 5 at which
/// the test holds, and with a tight tolerance at or after the every-iteration stop. Runs a
/// loaded column of 40 disks (many iterations), Gauss-Seidel and Jacobi.
#[test]
fn check_every_sets_where_the_cpu_solve_may_stop() {
    use cdlab::backend::{Backend, CpuBackend, Loading};
    for method in [Method::ColoredGs, Method::Jacobi] {
        let run = |every: u32| {
            let mut p = tight(method);
            p.solver.tol = 1e-6;
            p.solver.check_every = every;
            let scene = common::column(40, 0.5, G, Some(-2.0e4));
            let mut b = CpuBackend::new(scene, p).expect("backend");
            let red = b.run(1, &Loading::default()).expect("step");
            assert_eq!(red.capped_steps, 0, "{method:?}: the step must converge");
            red.iterations_sum
        };
        let (one, five) = (run(1), run(5));
        assert!(one > 10, "{method:?}: {one} iterations, too few to test");
        assert_eq!(five % 5, 0, "{method:?}: {five} iterations with a test every 5");
        assert!(
            five >= one && five < one + 5,
            "{method:?}: {five} iterations tested every 5, {one} tested every one"
        );
        // The default (0) is every iteration on the CPU.
        assert_eq!(run(0), one, "{method:?}");
    }
}
