//! Static force transmission checked against hand calculations (docs/validation.md,
//! "Statics").

mod common;

use cdlab::model::{Scene, Wall, WallDrive};
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
    let (n, r, force) = (5usize, 1.0, 2.0e6);
    let mut s = scene(0.3);
    if gravity {
        s.gravity = DVec2::new(0.0, -G);
    }
    s.walls.push(floor());
    // Top wall: force-driven along its inward normal (-y), mass of the column.
    s.walls.push(Wall {
        drive: WallDrive::Force { mass: 1.0e4, force },
        ..Wall::fixed(DVec2::new(0.0, 2.0 * r * n as f64), -DVec2::Y)
    });
    for k in 0..n {
        s.disks
            .push(DVec2::new(0.0, r + 2.0 * r * k as f64), r, RHO)
            .unwrap();
    }
    let weight = s.disks.mass[0] * G * gravity as u8 as f64;
    let mut e = engine(method);
    for _ in 0..20 {
        e.step(&mut s).unwrap();
    }
    let (floor_body, top_body) = (n, n + 1);
    // Expected: the contact above disk k carries F plus the weights of the disks above it;
    // the floor carries F plus the whole weight. Tolerance 1e-6: the solver's relative
    // tolerance is 1e-12 but a chain of 6 contacts converges slowly under Gauss-Seidel.
    let tol = 1e-6 * force;
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
        s.walls[1].vel.length() < 1e-6,
        "top wall velocity {}",
        s.walls[1].vel
    );
}

#[test]
fn loaded_column_carries_the_top_force_through_every_contact() {
    column(false, Method::Gs);
    column(false, Method::ColoredGs);
}

#[test]
fn loaded_column_under_gravity_adds_the_weights_above() {
    column(true, Method::Gs);
    column(true, Method::ColoredGs);
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
    // Hand calculation: each upper contact carries N = W / (2 cos 30) = W / sqrt(3); its
    // horizontal part N sin 30 = W / (2 sqrt 3) goes to the side wall; the floor carries
    // the bottom disk's weight plus N cos 30 = W / 2; the bottom disks press not at all on
    // each other.
    let tol = 1e-6 * w;
    let n_top = w / 3f64.sqrt();
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
        let expected = w / (2.0 * 3f64.sqrt());
        assert!(
            (got - expected).abs() < tol,
            "wall at {bottom}: {got}, expected {expected} N/m"
        );
    }
    let got = normal_force(&s, &e, 0, 1);
    assert!(
        got.abs() < tol,
        "bottom disks press each other with {got} N/m, expected 0"
    );
}

/// A column of disks on the floor under gravity whose two lowest disks overlap by 1% of
/// their radius (the others touch), after one step of two Gauss-Seidel iterations. Without
/// local updates the iterations stop with that contact still closing (the contacts above,
/// solved after it, push disk 1 down). With `deep_gap` below its overlap that contact alone
/// is updated again and leaves the step satisfying its law exactly: the normal relative
/// velocity `U_n^+` of a loaded contact is 0 (the Signorini law of docs/method.md; theta 0.5 from
/// rest). The contacts that are not deep are not touched: disk 2 keeps the velocity the
/// iterations left.
#[test]
fn a_deep_loaded_contact_leaves_the_step_satisfying_its_law() {
    let (n, r) = (5usize, 1.0);
    for method in [Method::Gs, Method::ColoredGs] {
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
