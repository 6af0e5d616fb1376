//! Anderson-accelerated Gauss-Seidel (`solver.method = "anderson-gs"`, docs/method.md,
//! "Anderson-accelerated Gauss-Seidel"): closed-form contacts, the Siconos fc2d problems,
//! a cross-check against Gauss-Seidel on the same engine state, and bit-reproducibility.

mod common;

use std::path::Path;

use cdlab::engine::CpuEngine;
use cdlab::fc2d;
use cdlab::model::{Scene, WallDrive};
use cdlab::protocol::{prepare, walls};
use cdlab::solver::anderson::{self, Options};
use cdlab::solver::captured::Captured;
use cdlab::solver::space::{ContactSpace, local_residual};
use cdlab::solver::{Method, SolverParams};
use common::*;
use glam::DVec2;

const G: f64 = 9.81;

/// One disk resting on the floor under gravity, sliding along it at `v` (m/s), stepped once
/// with Anderson-accelerated Gauss-Seidel; returns (R_n, R_t, m g dt, m v / 3) of its contact.
fn disk_pushed_along_the_floor(v: f64, mu: f64) -> (f64, f64, f64, f64) {
    let r = 0.5;
    let mut s = scene(mu);
    s.gravity = DVec2::new(0.0, -G);
    s.walls.push(floor());
    let k = s.disks.push(DVec2::new(0.0, r), r, RHO).unwrap();
    s.disks.vel[k] = DVec2::new(v, 0.0);
    let mut e = CpuEngine::new(tight(Method::AndersonGs)).unwrap();
    let st = e.step(&mut s).unwrap();
    assert!(st.solve.converged, "{:?}", st.solve);
    let c = e
        .contacts()
        .iter()
        .find(|c| c.rn > 0.0)
        .expect("a loaded contact");
    let m = s.disks.mass[k];
    let dt = e.params.dt;
    (c.rn, c.rt, m * G * dt, m * v / 3.0)
}

#[test]
fn a_disk_pushed_along_a_plane_sticks_below_mu_n_and_slides_at_mu_n() {
    let (mu, dt) = (0.3, tight(Method::AndersonGs).dt);
    // Stopping the contact point of a disk (I = m r^2 / 2) moving at v takes a tangential
    // impulse v / W_tt with W_tt = 1/m + r^2/I = 3/m, i.e. m v / 3; the floor carries the
    // weight over the step, R_n = m g dt. It sticks when m v / 3 <= mu m g dt.
    let v_slip = 3.0 * mu * G * dt;
    let (rn, rt, weight, stop) = disk_pushed_along_the_floor(0.5 * v_slip, mu);
    assert!(
        (rn - weight).abs() <= 1e-9 * weight,
        "R_n {rn}, expected m g dt = {weight}"
    );
    // The tangent is t = (n_y, -n_x) = (1, 0): the floor pushes back, R_t = -m v / 3.
    assert!(
        (rt + stop).abs() <= 1e-9 * stop,
        "R_t {rt}, expected stick -m v/3 = {}",
        -stop
    );
    let (rn, rt, weight, _) = disk_pushed_along_the_floor(2.0 * v_slip, mu);
    assert!(
        (rn - weight).abs() <= 1e-9 * weight,
        "R_n {rn}, expected {weight}"
    );
    // Twice the slip speed: the stick impulse would be 2 mu R_n, so it slides at -mu R_n.
    assert!(
        (rt + mu * rn).abs() <= 1e-9 * rn,
        "R_t {rt}, expected slide -mu R_n = {}",
        -mu * rn
    );
}

#[test]
fn a_column_under_gravity_carries_the_weight_above_each_contact() {
    let (n, r) = (12, 0.5);
    let mut s = column(n, r, G, None);
    let mut p = tight(Method::AndersonGs);
    p.solver.tol = 1e-10;
    let mut e = CpuEngine::new(p).unwrap();
    for _ in 0..5 {
        let st = e.step(&mut s).unwrap();
        assert!(st.solve.converged, "{:?}", st.solve);
    }
    let weight = s.disks.mass[0] * G;
    let floor_body = n as u32;
    for c in e.contacts() {
        // Statics of a column at rest: the contact below disk k (k = 0 at the floor)
        // carries the weight of disks k..n, (n - k) m g, over the step.
        let k = if c.j == floor_body {
            0
        } else {
            c.i.max(c.j) as usize
        };
        let expected = (n - k) as f64 * weight;
        let force = c.rn / e.params.dt;
        assert!(
            (force - expected).abs() <= 1e-6 * n as f64 * weight,
            "contact {}-{}: {force} N/m, expected {expected}",
            c.i,
            c.j
        );
        assert!(c.rt.abs() <= 1e-9 * c.rn, "no friction needed: R_t {}", c.rt);
    }
    assert_eq!(e.contacts().iter().filter(|c| c.rn > 0.0).count(), n);
}

fn fc2d_problem(name: &str) -> fc2d::Problem {
    fc2d::read(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/fc2d")
            .join(name),
    )
    .unwrap()
}

/// Sweeps (and velocity rebuilds) until the Siconos error is below 1e-5, from r = 0.
fn to_siconos_1e_5(p: &fc2d::Problem, depth: usize) -> (u32, u32, Vec<f64>) {
    let mut s = fc2d::Space::new(p);
    let opts = Options {
        tol: 1e-300,
        max_iter: 5000,
        depth,
        ..Options::from_params(&SolverParams::default())
    };
    let out = anderson::solve_until(&mut s, &opts, |s, _| fc2d::siconos_error(p, s.impulses()) < 1e-5);
    (out.stats.iterations, out.rebuilds(), s.impulses().to_vec())
}

#[test]
fn both_siconos_problems_reach_an_error_of_1e_5_in_fewer_sweeps_than_gauss_seidel() {
    for name in [
        "FC2D_SliderCrankLagrangian00000.dat",
        "FC2D_SliderCrankLagrangian00001.dat",
        "fc2d_granularflowonwall_02020_00213.dat",
        "fc2d_granularflowonwall_07002_00801.dat",
    ] {
        let p = fc2d_problem(name);
        let (sweeps, rebuilds, r) = to_siconos_1e_5(&p, 5);
        let err = fc2d::siconos_error(&p, &r);
        assert!(err < 1e-5, "{name}: error {err} after {sweeps} sweeps");
        // Depth 0 is plain Gauss-Seidel in contact order through the same code.
        let (gs, gs_rebuilds, _) = to_siconos_1e_5(&p, 0);
        assert_eq!(gs_rebuilds, 0);
        println!(
            "{name}: anderson-gs {sweeps} sweeps + {rebuilds} rebuilds (u = W r + q), gauss-seidel {gs} sweeps"
        );
        // A rebuild is one product with W, about the cost of a sweep: count both. On the
        // slider-crank steps (2 contacts) Gauss-Seidel needs 216 and 219 sweeps
        // (tests/fc2d.rs) and the mixing 6 products; on the 2020-contact problem 806 and
        // 164; on the 7002-contact one 1021 and 657. (The 667-contact problem is at rest:
        // r = 0 solves it.)
        let bound = if p.nc < 5000 { gs / 3 } else { gs * 3 / 4 };
        assert!(
            sweeps + rebuilds <= bound,
            "{name}: {sweeps} + {rebuilds} against gauss-seidel {gs}"
        );
    }
}

/// A confined, loaded packing of `n` disks with friction 0.3: the protocol's deposit with
/// the top wall pressing at 1 MPa, stepped `steps` times by Gauss-Seidel with the last
/// step's problem captured.
fn packed(n: usize, steps: usize) -> (Scene, Captured) {
    let pp = cdlab::Config::with_disks(n).protocol();
    let (mut s, _) = prepare::deposit_scene(&pp).unwrap();
    s.material.mu_disk = 0.3;
    s.material.mu_wall = 0.3;
    s.walls[walls::RIGHT].drive = WallDrive::Kinematic;
    let width = s.walls[walls::RIGHT].point.x - s.walls[walls::LEFT].point.x;
    let mass: f64 = s.disks.mass.iter().sum();
    s.walls[walls::TOP].drive = WallDrive::Force {
        mass: 0.1 * mass,
        force: 1e6 * width,
    };
    let mut p = tight(Method::Gs);
    p.solver.tol = 1e-5;
    p.solver.max_iter = 2000;
    let mut e = CpuEngine::new(p).unwrap();
    e.capture(true);
    for _ in 0..steps {
        e.step(&mut s).unwrap();
    }
    let c = e.captured().expect("captured").clone();
    (s, c)
}

fn solve(c: &Captured, method: Method, tol: f64) -> (Captured, cdlab::solver::SolveStats) {
    let p = SolverParams {
        method,
        tol,
        max_iter: 20_000,
        parallel: false,
        open_skip: 0.0,
        velocity_tol: 0.0,
        gauss_seidel: cdlab::solver::GaussSeidelSettings {
            relax: 1.0,
            ..SolverParams::default().gauss_seidel
        },
        ..SolverParams::default()
    };
    c.solve(&p)
}

/// Total impulse (N s/m) the disks receive from wall body `b` over the step.
fn wall_impulse(c: &Captured, b: u32) -> DVec2 {
    c.contacts
        .iter()
        .filter(|k| k.j == b)
        .map(|k| k.rn * k.n + k.rt * DVec2::new(k.n.y, -k.n.x))
        .sum()
}

#[test]
fn anderson_and_gauss_seidel_reach_the_same_law_and_velocities_on_a_packing() {
    let (s, c) = packed(300, 30);
    let loaded = c.contacts.iter().filter(|k| k.rn > 0.0).count();
    assert!(loaded > 300, "a dense packing: {loaded} loaded contacts");
    let tol = 1e-6;
    let (mut gs, gs_stats) = solve(&c, Method::Gs, tol);
    let (mut aa, aa_stats) = solve(&c, Method::AndersonGs, tol);
    assert!(
        gs_stats.converged && aa_stats.converged,
        "{gs_stats:?} {aa_stats:?}"
    );
    println!(
        "{} contacts: gauss-seidel {} sweeps, anderson-gs {} sweeps to a change of {tol:e}",
        c.contacts.len(),
        gs_stats.iterations,
        aa_stats.iterations
    );
    // Both satisfy the same law to the same tolerance: a relative change of 1e-9 per sweep
    // leaves the impulses within about 1e-9 / (1 - rate) of their local solutions, far below
    // this bound (docs/method.md, "Anderson-accelerated Gauss-Seidel", on the two measures).
    let (rg, ra) = (local_residual(&gs.space()), local_residual(&aa.space()));
    println!("local residuals {rg:e} {ra:e}");
    assert!(
        rg <= 1e-6 && ra <= 1e-6,
        "local residuals: gauss-seidel {rg:e}, anderson {ra:e}"
    );
    // The impulses of a hyperstatic packing are not unique (self-stresses of the force
    // network can be added, the fixed walls of the box among them), so neither are they
    // compared one by one nor is each fixed wall's share. What is unique is compared: the
    // velocities of the bodies (the force-driven top wall's included), hence by the momentum
    // balance of the disks the total impulse from the walls, and the impulse on the top
    // wall (its mass times its velocity change). Bound: both solvers stop at a relative
    // change of 1e-6 per sweep, but Gauss-Seidel converges at a rate close to 1 here (about
    // 17,000 sweeps), so its iterate may lie up to 1e-6 / (1 - rate), about 1e-2 in
    // relative terms, from the solution. Bounds: 1e-4 of the largest velocity; 1e-3 of the
    // largest wall impulse (the total is the disks' momentum change, sum m (v - v_free),
    // so it moves with the velocities: 1e-5 m/s on every one of 300 disks of about 10^4
    // kg/m (radii 0.5-2 m, 2600 kg/m^3) would be 30 N s/m, 6e-3 of the 5000 N s/m on the
    // bottom wall; the differences are smaller and mostly of one sign, 2e-4 here).
    let vmax = gs.gv.iter().map(|v| v.length()).fold(0.0, f64::max);
    let dv = gs
        .gv
        .iter()
        .zip(&aa.gv)
        .map(|(a, b)| (*a - *b).length())
        .fold(0.0, f64::max);
    println!("velocities differ by {dv:e} m/s (largest {vmax:e} m/s)");
    assert!(
        dv <= 1e-4 * vmax,
        "velocities differ by {dv:e} m/s (largest {vmax:e})"
    );
    let n_disks = s.disks.len() as u32;
    let walls_of = |c: &Captured| (0..4).map(|w| wall_impulse(c, n_disks + w)).collect::<Vec<_>>();
    let (wg, wa) = (walls_of(&gs), walls_of(&aa));
    let scale = wg.iter().map(|w| w.length()).fold(0.0, f64::max);
    assert!(scale > 0.0);
    let total = |w: &[DVec2]| w.iter().copied().sum::<DVec2>();
    let (tg, ta) = (total(&wg), total(&wa));
    assert!(
        (tg - ta).length() <= 1e-3 * scale,
        "total wall impulse: gauss-seidel {tg}, anderson {ta} N s/m"
    );
    let top = walls::TOP;
    assert!(
        (wg[top] - wa[top]).length() <= 1e-3 * scale,
        "top wall: gauss-seidel {}, anderson {} N s/m",
        wg[top],
        wa[top]
    );
    for w in 0..4 {
        println!(
            "wall {w}: {:e} of the largest wall impulse",
            (wg[w] - wa[w]).length() / scale
        );
    }
}

#[test]
fn the_same_problem_solved_twice_gives_identical_bits() {
    let (_, c) = packed(200, 10);
    let (a, sa) = solve(&c, Method::AndersonGs, 1e-8);
    let (b, sb) = solve(&c, Method::AndersonGs, 1e-8);
    assert_eq!(sa, sb);
    assert!(sa.iterations > 1);
    for (x, y) in a.contacts.iter().zip(&b.contacts) {
        assert_eq!((x.rn.to_bits(), x.rt.to_bits()), (y.rn.to_bits(), y.rt.to_bits()));
    }
    for (x, y) in a.gv.iter().zip(&b.gv) {
        assert_eq!(x.to_array().map(f64::to_bits), y.to_array().map(f64::to_bits));
    }
    let p = fc2d_problem("fc2d_granularflowonwall_02020_00213.dat");
    assert_eq!(to_siconos_1e_5(&p, 5), to_siconos_1e_5(&p, 5));
}

#[test]
fn the_method_and_its_depth_are_read_from_the_configuration_and_checked() {
    let c = cdlab::config::Config::from_toml_str(
        "[solver]\nmethod = \"anderson-gs\"\nanderson_depth = 7\nbackend = \"cpu\"\n",
    )
    .unwrap();
    assert_eq!(c.solver.method, Method::AndersonGs);
    assert_eq!(c.solver.anderson_depth, 7);
    let e = cdlab::config::Config::from_toml_str("[solver]\nanderson_depth = 51\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("solver.anderson_depth"), "{e}");
    let e =
        cdlab::config::Config::from_toml_str("[solver]\nmethod = \"anderson-gs\"\ndeep_overlap = 0.002\n")
            .unwrap_err()
            .to_string();
    assert!(
        e.contains("solver.deep_overlap") && e.contains("anderson-gs"),
        "{e}"
    );
    // The GPU backend refuses it before opening a device, naming the key.
    let mut p = tight(Method::AndersonGs);
    p.solver.anderson.depth = 5;
    let e = cdlab::gpu::backend::GpuBackend::new(Scene::default(), p)
        .err()
        .expect("refused")
        .to_string();
    assert!(e.contains("solver.method"), "{e}");
}

#[test]
fn an_empty_problem_converges_at_once() {
    let mut c = Captured {
        gv0: vec![glam::DVec3::ZERO; 2],
        gv: vec![glam::DVec3::ZERO; 2],
        ..Default::default()
    };
    let st = anderson::solve(&mut c.space(), &SolverParams::default());
    assert!(st.converged && st.iterations == 1 && st.residual == 0.0, "{st:?}");
    assert_eq!(c.space().len(), 0);
}
