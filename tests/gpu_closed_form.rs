//! Closed-form cases on the GPU path (docs/validation.md, "Cross-checks between the two
//! backends": collisions, rolling, statics and a glued-wall case, and GPU twins of the
//! slipping incline, the sliding-then-rolling disk, the elastic swap and the conservation
//! checks), with f32 tolerances. Skips visibly without an adapter (see
//! `gpu_support::gpu_or_skip`).

mod common;
#[path = "gpu_support/mod.rs"]
mod gpu_support;

use cdlab::backend::{Backend, Loading};
use cdlab::solver::Method;
use common::*;
use glam::DVec2;
use gpu_support::*;

#[test]
fn gpu_head_on_inelastic_collision_gives_the_mean_velocity() {
    for method in [Method::ColoredGs, Method::Jacobi] {
        let mut s = scene(0.0);
        s.disks.push(DVec2::new(-1.0, 0.0), 1.0, RHO).unwrap();
        s.disks.push(DVec2::new(1.0, 0.0), 1.0, RHO).unwrap();
        s.disks.vel[0] = DVec2::new(2.0, 0.0);
        s.disks.vel[1] = DVec2::new(-1.0, 0.0);
        let Some(mut g) = gpu_or_skip("head-on", &s, gpu_params(method)) else {
            return;
        };
        g.run(1, &Loading::default()).unwrap();
        let out = g.scene().unwrap();
        // Expected 0.5 m/s; f32 arithmetic on O(1) velocities: a few ulp (6e-8) plus the
        // solver's 1e-6 relative stop.
        for k in 0..2 {
            let v = out.disks.vel[k];
            assert!((v.x - 0.5).abs() < 1e-5, "{method:?}: v{k} = {v}");
            assert_eq!(v.y, 0.0);
        }
    }
}

/// The head-on pair (2 and -1 m/s, one contact) after one GPU step: the solver relaxed by
/// 1/2 after `after` plain iterations, capped at `max_iter`, with the velocity test at
/// `velocity_tol` (m/s) and a convergence readback every `conv_every` iterations. Returns
/// the two velocities and the iterations, or `None` when the test skips.
fn relaxed_pair(after: u32, max_iter: u32, velocity_tol: f64, conv_every: u32) -> Option<(f64, f64, u64)> {
    let mut s = scene(0.0);
    s.disks.push(DVec2::new(-1.0, 0.0), 1.0, RHO).unwrap();
    s.disks.push(DVec2::new(1.0, 0.0), 1.0, RHO).unwrap();
    s.disks.vel[0] = DVec2::new(2.0, 0.0);
    s.disks.vel[1] = DVec2::new(-1.0, 0.0);
    let mut p = gpu_params(Method::ColoredGs);
    p.solver.gauss_seidel.relax = 0.5;
    p.solver.gauss_seidel.relax_after = after;
    p.solver.max_iter = max_iter;
    p.solver.velocity_tol = velocity_tol;
    let mut g = gpu_or_skip("relaxed pair", &s, p)?;
    g.conv_every = conv_every;
    let red = g.run(1, &Loading::default()).unwrap();
    let out = g.scene().unwrap();
    Some((out.disks.vel[0].x, out.disks.vel[1].x, red.iterations_sum))
}

#[test]
fn gpu_relaxed_gauss_seidel_moves_each_iteration_a_fraction_of_the_way() {
    // CPU twin: collisions.rs, relaxed_gauss_seidel_moves_each_iteration_a_fraction_of_the_way.
    // (unrelaxed iterations, iteration cap, expected velocities): from a cold start
    // iteration k relaxed by 1/2 leaves (1 - 2^-k) of the local solution, which stops the
    // approach of the pair at 0.5 m/s. The first and third cases stop at the cap; the
    // others reach the local solution in their first, unrelaxed, iteration. Readbacks every
    // 3 iterations: a batch must still switch at `after`.
    let cases = [
        (0, 3, (0.6875, 0.3125)),
        (1, 3, (0.5, 0.5)),
        (0, 1, (1.25, -0.25)),
        (2, 4, (0.5, 0.5)),
    ];
    for (after, iterations, (va, vb)) in cases {
        let Some((a, b, n)) = relaxed_pair(after, iterations, 0.0, 3) else {
            return;
        };
        if va != 0.5 {
            assert_eq!(n, iterations as u64, "iterations");
        }
        // f32 velocities of order 1: a few ulp.
        assert!(
            (a - va).abs() < 1e-6 && (b - vb).abs() < 1e-6,
            "after {after}, {iterations} iterations: {a} {b}, expected {va} {vb}"
        );
    }
}

#[test]
fn gpu_velocity_test_stops_at_the_first_iteration_that_changes_no_velocity_by_more_than_it() {
    // CPU twin: collisions.rs, velocity_test_stops_at_the_first_iteration_that_changes_no_
    // velocity_by_more_than_it. Relaxed by 1/2 from a cold start, sweep k changes each
    // disk's velocity by 1.5 x 2^-k m/s, 3 x 2^-k once divided by the relaxation. (test
    // in m/s, unrelaxed sweeps, iterations, velocities): 0.3 stops after the fourth sweep,
    // 1 after the second, and a test applying from the sixth sweep lets the impulse test
    // stop at the second.
    let cases = [
        (0.3, 0, 4, (0.59375, 0.40625)),
        (1.0, 0, 2, (0.875, 0.125)),
        (10.0, 5, 2, (0.5, 0.5)),
    ];
    for (tol, after, iterations, (va, vb)) in cases {
        let Some((a, b, n)) = relaxed_pair(after, 30, tol, 1) else {
            return;
        };
        assert_eq!(n, iterations as u64, "test at {tol} m/s");
        assert!(
            (a - va).abs() < 1e-6 && (b - vb).abs() < 1e-6,
            "test at {tol} m/s: {a} {b}, expected {va} {vb}"
        );
    }
}

#[test]
fn gpu_loaded_column_carries_the_top_force_through_every_contact() {
    let (n, r, force) = (5usize, 1.0, 2.0e6);
    let s = column(n, r, G, Some(force));
    let weight = s.disks.mass[0] * G;
    let Some(mut g) = gpu_or_skip("column", &s, gpu_params(Method::ColoredGs)) else {
        return;
    };
    let red = g.run(20, &Loading::default()).unwrap();
    let dt = g.params().dt;
    let contacts = g.contacts().unwrap();
    let force_of = |i: u32, j: u32| {
        contacts
            .iter()
            .find(|c| (c.i, c.j) == (i, j))
            .unwrap_or_else(|| panic!("no contact {i}-{j}"))
            .f_n
    };
    // Expected: F plus the weights above each contact. Tolerance 1e-4 F: f32 impulses
    // (6e-8) through a chain of 6 contacts solved to a relative change of 1e-6.
    let tol = 1e-4 * force;
    let top = force_of(n as u32 - 1, n as u32 + 1);
    assert!((top - force).abs() < tol, "top {top}");
    for k in 0..n - 1 {
        let expected = force + weight * (n - 1 - k) as f64;
        let got = force_of(k as u32, k as u32 + 1);
        assert!(
            (got - expected).abs() < tol,
            "contact {k}: {got}, expected {expected}"
        );
    }
    let expected = force + weight * n as f64;
    let got = force_of(0, n as u32);
    assert!((got - expected).abs() < tol, "floor {got}, expected {expected}");
    // The floor's reaction in the reductions (last step's impulse equals the average once
    // the column is at rest; the first steps settle, hence the looser 1e-2).
    let _ = dt;
    assert!(
        (red.wall_force[0].y + expected).abs() < 1e-2 * expected,
        "floor reaction {}",
        red.wall_force[0].y
    );
}

#[test]
fn gpu_disk_on_an_incline_rolls_at_two_thirds_g_sin_a() {
    let (mu, r, steps) = (0.3, 0.8, 200u32);
    let a = 0.6f64.atan();
    let mut s = scene(mu);
    s.walls.push(floor());
    s.gravity = G * DVec2::new(a.sin(), -a.cos());
    s.disks.push(DVec2::new(0.0, r), r, RHO).unwrap();
    // Tolerance 1e-5, not gpu_params' 1e-6: the disk reaches 2 m/s, where f32 steps by
    // 2.4e-7 m/s, against a change of 2.5e-3 m/s a step, and the contact's impulse then
    // keeps changing by 1e-6 to 1e-5 of itself from one iteration to the next, however long
    // it is swept. At 1e-6, 30 of the 200 steps ran to the cap of 5000 iterations (151,360
    // in all, 33 s on lavapipe) and ended with the same velocity and spin, bit for bit, as
    // at 1e-5 (every step settled at its first test, after 8 iterations: 0.6 s).
    let mut params = gpu_params(Method::ColoredGs);
    params.solver.tol = 1e-5;
    let Some(mut g) = gpu_or_skip("incline", &s, params) else {
        return;
    };
    let run = g.run(steps, &Loading::default()).unwrap();
    assert_eq!(
        run.capped_steps, 0,
        "{} steps ran to the iteration cap",
        run.capped_steps
    );
    let out = g.scene().unwrap();
    let t = steps as f64 * g.params().dt;
    let acc = out.disks.vel[0].x / t;
    let alpha = out.disks.spin[0] / t;
    let expected = 2.0 / 3.0 * G * a.sin();
    // f32 velocity summed over 200 steps: 200 x 6e-8 relative, plus the solver's 1e-6.
    assert!(
        (acc - expected).abs() < 1e-4 * expected,
        "a = {acc}, expected {expected}"
    );
    assert!(
        (alpha + expected / r).abs() < 1e-4 * expected / r,
        "alpha = {alpha}"
    );
}

#[test]
fn gpu_glued_disk_on_a_force_driven_wall_matches_the_hand_calculation() {
    // A free disk B on the floor against a left wall; a disk A glued to a force-driven top
    // wall (pushing down with F) touches B at 60 degrees. The wall moves along y only, so
    // the A-B contact is oblique to its axis: W_nt != 0 and the local problem is the 2x2
    // block. Frictionless, the three normal forces are determinate: A-B carries 2F/sqrt3,
    // the floor F, the left wall F/sqrt3.
    let (r, f) = (1.0, 1.0e6);
    let mut s = scene(0.0);
    s.walls.push(floor());
    s.walls
        .push(cdlab::model::Wall::fixed(DVec2::new(-r, 0.0), DVec2::X));
    let top = r + 3f64.sqrt() * r;
    s.walls.push(cdlab::model::Wall {
        drive: cdlab::model::WallDrive::Force {
            mass: 1.0e3,
            force: f,
        },
        ..cdlab::model::Wall::fixed(DVec2::new(0.0, top + r), -DVec2::Y)
    });
    s.disks.push(DVec2::new(0.0, r), r, RHO).unwrap();
    s.disks.push(DVec2::new(r, top), r, RHO).unwrap();
    s.disks.glue(1, 2);
    let params = gpu_params(Method::ColoredGs);
    let Some(mut g) = gpu_or_skip("glued block", &s, params) else {
        return;
    };
    g.run(20, &Loading::default()).unwrap();
    let raw = g.raw_contacts().unwrap();
    assert!(raw.iter().any(|c| c.wnt != 0.0), "no coupled contact: {raw:?}");
    let contacts = g.contacts().unwrap();
    let force_of = |j: u32| contacts.iter().find(|c| (c.i, c.j) == (0, j)).unwrap().f_n;
    // f32 impulses solved to 1e-6: 1e-4 F.
    let tol = 1e-4 * f;
    let ab = force_of(1);
    assert!((ab - 2.0 * f / 3f64.sqrt()).abs() < tol, "A-B {ab}");
    let floor_n = force_of(2);
    assert!((floor_n - f).abs() < tol, "floor {floor_n}");
    let left = force_of(3);
    assert!((left - f / 3f64.sqrt()).abs() < tol, "left wall {left}");
}

/// GPU twin of statics.rs, `a_deep_loaded_contact_leaves_the_step_satisfying_its_law`: a
/// column of five disks on the floor under gravity whose two lowest disks overlap by 1% of
/// their radius, one step of two colored Gauss-Seidel (or Jacobi) iterations. Without local
/// updates the contact 0-1 is left closing; with `deep_gap` below its overlap it alone is
/// marked, counted once in the step's reductions, and leaves the step with `U_n^+ = 0` (the
/// Signorini law of docs/method.md for a loaded contact) to f32 precision; disk 2, touched
/// by no local update, keeps the velocity the iterations left it. The CPU path, from the
/// same column, gives the same velocities of disks 0 and 1 to f32 precision.
#[test]
fn gpu_deep_loaded_contact_leaves_the_step_satisfying_its_law() {
    for method in [Method::ColoredGs, Method::Jacobi] {
        deep_loaded_contact(method);
    }
}

fn deep_loaded_contact(method: Method) {
    let (n, r) = (5usize, 1.0);
    let column = || sunk_column(n, r, G);
    let params = |deep_gap: f64| {
        let mut p = gpu_params(method);
        p.solver.max_iter = 2;
        p.solver.deep_gap = deep_gap;
        p.solver.deep_sweeps = 3;
        p
    };
    let run = |deep_gap: f64| {
        let mut g = gpu_or_skip("deep contacts", &column(), params(deep_gap))?;
        let red = g.run(1, &Loading::default()).unwrap();
        let v = g.scene().unwrap().disks.vel;
        Some((v[0].y, v[1].y, v[2].y, red.deep_sum))
    };
    let Some((u0, u1, above_off, none)) = run(0.0) else {
        return;
    };
    assert_eq!(none, 0, "{method:?}");
    assert!(
        u1 - u0 < -1e-4,
        "{method:?}: without local updates the contact should still close; it opens at {} m/s",
        u1 - u0
    );
    let Some((v0, v1, above_on, deep)) = run(0.005 * r) else {
        return;
    };
    assert_eq!(deep, 1, "{method:?}: one deep contact (disks 0-1) in one step");
    // Velocities of order g dt = 5e-3 m/s in f32: a few ulp are 1e-9 m/s.
    assert!(
        (v1 - v0).abs() < 1e-7,
        "{method:?}: the deep contact leaves at {} m/s, expected 0",
        v1 - v0
    );
    assert_eq!(
        above_on, above_off,
        "{method:?}: disk 2 is touched by no local update"
    );
    // The CPU twin from the same column and parameters.
    let mut s = column();
    let mut e = cdlab::engine::CpuEngine::new(params(0.005 * r)).unwrap();
    let stats = e.step(&mut s).unwrap();
    assert_eq!(stats.solve.deep, 1, "{method:?}");
    let cpu = &s.disks.vel;
    assert!((cpu[1].y - cpu[0].y).abs() < 1e-12, "{method:?}");
    for (k, g) in [(0, v0), (1, v1)] {
        assert!(
            (cpu[k].y - g).abs() < 1e-6 * cpu[k].y.abs().max(1e-3),
            "{method:?}, disk {k}: GPU {g} m/s, CPU {} m/s",
            cpu[k].y
        );
    }
}

/// GPU twin of rolling.rs's slipping incline, with the wall friction apart from the disk
/// friction: on a 45-degree incline with mu_wall = 0.2 (mu_disk = 0.8, unused by the floor)
/// the disk slips: a = g (sin a - mu_wall cos a), angular acceleration
/// -2 mu_wall g cos a / r (Coulomb friction at the contact point, I = m r^2 / 2).
#[test]
fn gpu_disk_on_a_steep_incline_slips_with_the_wall_friction() {
    let (r, steps) = (0.8, 200u32);
    let a = std::f64::consts::FRAC_PI_4;
    let mut s = scene(0.8);
    s.material.mu_wall = 0.2;
    s.walls.push(floor());
    s.gravity = G * DVec2::new(a.sin(), -a.cos());
    s.disks.push(DVec2::new(0.0, r), r, RHO).unwrap();
    let Some(mut g) = gpu_or_skip("slipping incline", &s, gpu_params(Method::ColoredGs)) else {
        return;
    };
    g.run(steps, &Loading::default()).unwrap();
    let out = g.scene().unwrap();
    let t = steps as f64 * g.params().dt;
    let (acc, alpha) = (out.disks.vel[0].x / t, out.disks.spin[0] / t);
    let expected = G * (a.sin() - 0.2 * a.cos());
    let expected_alpha = -2.0 * 0.2 * G * a.cos() / r;
    // As the rolling incline above: f32 velocity summed over 200 steps, 1e-4 relative.
    assert!(
        (acc - expected).abs() < 1e-4 * expected,
        "a = {acc}, expected {expected} m/s^2"
    );
    assert!(
        (alpha - expected_alpha).abs() < 1e-4 * expected_alpha.abs(),
        "alpha = {alpha}, expected {expected_alpha} rad/s^2"
    );
}

/// GPU twin of rolling.rs's sliding-then-rolling disk: thrown at v0 = 3 m/s with backspin
/// w0 = 4 rad/s on a floor with mu 0.4, the slip v + r w decays at 3 mu g and rolling starts
/// at t* = (v0 + r w0) / (3 mu g) = 0.595 s; afterwards v = (2 v0 - r w0) / 3 = 4/3 m/s and
/// w = -v / r. Checked at 1.5 t*, well into the rolling.
#[test]
fn gpu_sliding_spinning_disk_ends_rolling_at_the_predicted_velocity() {
    let (mu, r, v0, w0) = (0.4, 0.5, 3.0, 4.0);
    let mut s = scene(mu);
    s.walls.push(floor());
    s.gravity = DVec2::new(0.0, -G);
    s.disks.push(DVec2::new(0.0, r), r, RHO).unwrap();
    s.disks.vel[0] = DVec2::new(v0, 0.0);
    s.disks.spin[0] = w0;
    let p = gpu_params(Method::ColoredGs);
    let Some(mut g) = gpu_or_skip("sliding then rolling", &s, p) else {
        return;
    };
    let t_roll = (v0 + r * w0) / (3.0 * mu * G);
    let v_final = (2.0 * v0 - r * w0) / 3.0;
    g.run((1.5 * t_roll / p.dt) as u32, &Loading::default()).unwrap();
    let out = g.scene().unwrap();
    let (v, w) = (out.disks.vel[0].x, out.disks.spin[0]);
    // f32: the slip decays by the same 1.7e-2 m/s per step for 1190 steps; each step rounds
    // v and w to an f32 ulp (2.4e-7 at 3 m/s), so 1190 roundings leave at most 3e-4 m/s,
    // and once rolling the slip is held at 0 by the sticking contact.
    assert!((v - v_final).abs() < 3e-4, "v = {v}, expected {v_final} m/s");
    assert!(
        (w + v_final / r).abs() < 3e-4 / r,
        "w = {w}, expected {} rad/s",
        -v_final / r
    );
    assert!((v + r * w).abs() < 1e-5, "still slipping at {} m/s", v + r * w);
}

/// GPU twin of collisions.rs's elastic swap: equal disks at 2 and -1 m/s, e_n = 1, swap
/// their velocities (closed form of a head-on elastic collision of equal masses).
#[test]
fn gpu_elastic_head_on_collision_swaps_velocities() {
    for method in [Method::ColoredGs, Method::Jacobi] {
        let mut s = scene(0.0);
        s.material.e_n = 1.0;
        s.disks.push(DVec2::new(-1.0, 0.0), 1.0, RHO).unwrap();
        s.disks.push(DVec2::new(1.0, 0.0), 1.0, RHO).unwrap();
        s.disks.vel[0] = DVec2::new(2.0, 0.0);
        s.disks.vel[1] = DVec2::new(-1.0, 0.0);
        let Some(mut g) = gpu_or_skip("elastic swap", &s, gpu_params(method)) else {
            return;
        };
        g.run(1, &Loading::default()).unwrap();
        let out = g.scene().unwrap();
        // As the inelastic case: f32 ulps plus the solver's 1e-6 relative stop.
        for (k, want) in [(0, -1.0), (1, 2.0)] {
            let v = out.disks.vel[k];
            assert!(
                (v.x - want).abs() < 1e-5,
                "{method:?}: v{k} = {v}, expected {want}"
            );
            assert_eq!(v.y, 0.0);
        }
    }
}

/// GPU twins of collisions.rs's conservation checks: a free cloud of 144 disks (no wall, no
/// gravity) keeps its linear momentum, and a cloud in a fixed box with restitution 0 never
/// gains kinetic energy, both to f32 round-off.
#[test]
fn gpu_cloud_conserves_momentum_and_never_gains_energy() {
    let mut s = cloud(12, 12, 10.0, 7);
    s.material.mu_disk = 0.5;
    let mut p = gpu_params(Method::ColoredGs);
    p.solver.tol = 1e-5;
    p.solver.max_iter = 200;
    let Some(mut g) = gpu_or_skip("free cloud", &s, p) else {
        return;
    };
    let scale: f64 = (0..s.disks.len())
        .map(|k| s.disks.mass[k] * s.disks.vel[k].length())
        .sum();
    let p0 = momentum(&s);
    g.run(300, &Loading::default()).unwrap();
    let out = g.scene().unwrap();
    let dp = (momentum(&out) - p0).length();
    // Every impulse is applied pairwise, so the drift is f32 rounding only: each velocity
    // update rounds to half an f32 ulp (2^-24 relative) with errors of either sign that
    // mostly cancel (the drift seen is a fraction of an ulp of sum m |v| over these 300
    // steps). Bound: 10 ulps of sum m |v|; a one-sided impulse (a missing reaction) would
    // move the momentum by whole impulses, orders of magnitude more.
    let bound = 10.0 * 2f64.powi(-24) * scale;
    assert!(dp <= bound, "dp = {dp:e} kg m/s per m, bound {bound:e}");

    let mut s = cloud(10, 10, 5.0, 11);
    add_box(&mut s, -1.5, 22.0, -1.5, 22.0);
    s.material.mu_disk = 0.4;
    let mut g = gpu_or_skip("cloud in a box", &s, p).unwrap();
    let mut ke = s.disks.kinetic_energy();
    let ke0 = ke;
    for step in 0..100 {
        g.run(3, &Loading::default()).unwrap();
        let now = g.scene().unwrap().disks.kinetic_energy();
        // Collisions with e = 0 dissipate; f32 velocities may add their rounding: v rounded
        // by 2^-24 relative moves v^2 by 2^-23, so at most 4 x 2^-24 of the energy.
        assert!(
            now <= ke * (1.0 + 4.0 * 2f64.powi(-24)),
            "steps {}: {ke} -> {now} J/m",
            3 * step
        );
        ke = now;
    }
    assert!(ke < 0.9 * ke0, "collisions must dissipate: {ke0} -> {ke} J/m");
}

/// Two free disks and a kinematic one, 2000 m apart on both axes, so that each sits about
/// 1000 m from the sample centre (where an f32 position's spacing is 6.1e-5 m), no gravity,
/// plus a kinematic floor 2000 m below the centre moving at `wall_vel`. The disks move at
/// `disk_speed` along (1, -1), (-1, 1) and (1, 1); positions are off the f32 grid so that
/// the upload's low words are not zero.
fn far_scene(disk_speed: f64, wall_vel: DVec2) -> cdlab::model::Scene {
    let mut s = scene(0.0);
    let at = [
        DVec2::new(0.123_456_789, 0.987_654_321),
        DVec2::new(2_000.314_159_265, 2_000.271_828_182),
        DVec2::new(0.577_215_664, 2_000.141_421_356),
    ];
    let dirs = [DVec2::new(1.0, -1.0), DVec2::new(-1.0, 1.0), DVec2::new(1.0, 1.0)];
    for (p, d) in at.iter().zip(dirs) {
        let k = s.disks.push(*p, 1.0, RHO).unwrap();
        s.disks.vel[k] = disk_speed * d;
    }
    s.disks.set_kind(2, cdlab::model::BodyKind::Kinematic);
    s.disks.vel[2] = disk_speed * dirs[2];
    s.walls.push(cdlab::model::Wall {
        vel: wall_vel,
        ..cdlab::model::Wall::fixed(DVec2::new(-999.876_543_21, -1_000.123_456_789), DVec2::Y)
    });
    s
}

#[test]
fn gpu_disks_far_from_the_centre_keep_steps_of_1e_7_m() {
    // 1e-7 m per step is 1/600 of the f32 spacing at 1000 m: a single-float position
    // never moves. Two-float positions must land where f64 says, to 1e-9 m, after 1000
    // steps (the f32 rounding of dt and v alone is about 1e-11 m of the 1e-4 m travelled).
    let steps = 1000;
    let p = gpu_params(Method::ColoredGs);
    let speed = 1e-7 / p.dt;
    let s = far_scene(speed, DVec2::ZERO);
    let Some(mut g) = gpu_or_skip("far disks", &s, p) else {
        return;
    };
    g.run(steps, &Loading::default()).unwrap();
    let out = g.scene().unwrap();
    for k in 0..3 {
        let want = s.disks.pos[k] + steps as f64 * p.dt * s.disks.vel[k];
        let err = (out.disks.pos[k] - want).abs().max_element();
        eprintln!("far disk {k}: error {err:.3e} m after {steps} steps");
        assert!(
            err < 1e-9,
            "disk {k}: {} instead of {want} ({err:.3e} m)",
            out.disks.pos[k]
        );
    }
}

#[test]
fn gpu_wall_far_from_the_centre_moves_by_its_exact_steps() {
    // The floor is 2000 m below the centre (f32 spacing 1.2e-4 m) and moves 2.5e-4 m per
    // step: a single-float point rounds every step to whole spacings. Its point must follow
    // f64 to 1e-9 m over the 0.25 m travelled. The reference takes dt and the velocity as
    // the device gets them (f32): their rounding is the same at any distance from the
    // centre and not what this test is about.
    let steps = 1000;
    let p = gpu_params(Method::ColoredGs);
    let v = DVec2::new(0.3, 0.4);
    let s = far_scene(0.0, v);
    let Some(mut g) = gpu_or_skip("far wall", &s, p) else {
        return;
    };
    g.run(steps, &Loading::default()).unwrap();
    let out = g.scene().unwrap();
    let dt32 = p.dt as f32;
    let step = DVec2::new((dt32 * v.x as f32) as f64, (dt32 * v.y as f32) as f64);
    let want = s.walls[0].point + steps as f64 * step;
    let err = (out.walls[0].point - want).abs().max_element();
    eprintln!("far wall: error {err:.3e} m after {steps} steps of {step}");
    assert!(
        err < 1e-9,
        "{} instead of {want} ({err:.3e} m)",
        out.walls[0].point
    );
}

#[test]
fn gpu_contact_gaps_far_from_the_centre_have_f32_precision_of_the_gap() {
    // A disk 1000 m from the centre (on both axes) 1.3 mm from a second disk and 1.7 mm
    // above a floor, both within the alert distance. The gaps the GPU finds must be the f64
    // ones to the f32 precision of a 2 m distance (about 1e-7 m), not to the f32 spacing of
    // the positions (6.1e-5 m at 1000 m, which a single-float position gave).
    let mut s = scene(0.3);
    let a = DVec2::new(0.123_456_789, 0.987_654_321);
    let b = a + 2.0013 * DVec2::new(1.0, 1.0).normalize();
    let floor_y = a.y - 1.0 - 0.0017;
    for p in [a, b, DVec2::new(2_000.314_159_265, 2_000.271_828_182)] {
        s.disks.push(p, 1.0, RHO).unwrap();
    }
    s.walls.push(cdlab::model::Wall::fixed(
        DVec2::new(-0.555_555_555, floor_y),
        DVec2::Y,
    ));
    let Some(mut g) = gpu_or_skip("far gaps", &s, gpu_params(Method::ColoredGs)) else {
        return;
    };
    g.run(1, &Loading::default()).unwrap();
    let contacts = g.raw_contacts().unwrap();
    let want = |j: u32| {
        if j == 1 {
            (b - a).length() - 2.0
        } else {
            a.y - floor_y - 1.0
        }
    };
    let mut seen = 0;
    for c in contacts.iter().filter(|c| c.disk_j == 1 || c.disk_j == 3) {
        let err = (c.gap as f64 - want(c.disk_j)).abs();
        eprintln!(
            "far gap with partner {}: {} m, error {err:.3e} m",
            c.disk_j, c.gap
        );
        assert!(
            err < 1e-6,
            "partner {}: gap {} instead of {}",
            c.disk_j,
            c.gap,
            want(c.disk_j)
        );
        seen += 1;
    }
    assert_eq!(seen, 2, "both contacts found: {contacts:?}");
}
