//! Benchmarks of the CPU reference path: one time step of a dense confined packing of 5000
//! disks at tolerance 1e-4 (time per step, iterations, contacts, ns per contact update), and
//! the Siconos fc2d problems. Figures are printed beside criterion's timings.

use std::hint::black_box;

use cdlab::backend::{Backend, CpuBackend, Loading};
use cdlab::engine::{CpuEngine, StepParams};
use cdlab::model::{Scene, WallDrive};
use cdlab::protocol::{prepare, walls};
use cdlab::solver::{Method, SolverParams};
use criterion::{Criterion, criterion_group, criterion_main};

fn params(method: Method) -> StepParams {
    StepParams {
        dt: 5e-4,
        theta: 0.5,
        alert: 0.05,
        overlap_limit: 0.25,
        solver: SolverParams {
            method,
            tol: 1e-4,
            max_iter: 1000,
            jacobi: cdlab::solver::JacobiSettings { relax: 0.5 },
            parallel: false,
            parallel_min: cdlab::solver::default_parallel_min(),
            threads: 0,
            gauss_seidel: cdlab::solver::GaussSeidelSettings {
                relax: cdlab::solver::default_gs_relax(),
                relax_after: cdlab::solver::default_gs_relax_after(),
            },
            velocity_tol: 0.0,
            open_skip: 0.0,
            deep_gap: 0.0,
            deep_sweeps: 0,
            anderson: cdlab::solver::AndersonSettings {
                depth: cdlab::solver::default_anderson_depth(),
            },
            check_every: 0,
        },
    }
}

/// A 5000-disk deposit, walls closed, the top wall pressing at 1 MPa, settled for 400 steps
/// with friction 0.3: a dense confined packing.
fn confined(n: usize) -> Scene {
    let pp = cdlab::Config::with_disks(n).protocol();
    let (mut scene, _) = prepare::deposit_scene(&pp).expect("deposit");
    scene.material.mu_disk = 0.3;
    scene.material.mu_wall = 0.3;
    scene.walls[walls::RIGHT].drive = WallDrive::Kinematic;
    let width = scene.walls[walls::RIGHT].point.x - scene.walls[walls::LEFT].point.x;
    let mass: f64 = scene.disks.mass.iter().sum();
    scene.walls[walls::TOP].drive = WallDrive::Force {
        mass: 0.1 * mass,
        force: 1e6 * width,
    };
    let mut b = CpuBackend::new(scene, params(Method::Gs)).expect("backend");
    b.run(400, &Loading::default()).expect("settle");
    b.scene().expect("scene")
}

fn step(c: &mut Criterion) {
    let scene = confined(5000);
    for method in [Method::Gs, Method::ColoredGs, Method::Jacobi] {
        // Figures of a few steps from the same state, printed for the report.
        let mut e = CpuEngine::new(params(method)).expect("engine");
        let mut s = scene.clone();
        let (mut it, mut upd, mut solve, mut total) = (0u64, 0u64, 0.0, 0.0);
        let mut contacts = 0;
        for _ in 0..20 {
            let st = e.step(&mut s).expect("step");
            it += st.solve.iterations as u64;
            upd += st.solve.iterations as u64 * st.contacts as u64;
            solve += st.solve_seconds;
            total += st.step_seconds;
            contacts = st.contacts;
        }
        println!(
            "{method:?}: {} disks, {contacts} contacts, {:.1} iterations/step, {:.3} ms/step, {:.2} ns per contact update (sweeps only), {:.2} ns per contact update (whole step)",
            s.disks.len(),
            it as f64 / 20.0,
            total / 20.0 * 1e3,
            solve / upd as f64 * 1e9,
            total / upd as f64 * 1e9
        );
        let mut e = CpuEngine::new(params(method)).expect("engine");
        let mut s = scene.clone();
        e.step(&mut s).expect("warm start");
        c.bench_function(&format!("step_5000_{method:?}"), |bench| {
            bench.iter_batched(
                || (e.clone(), s.clone()),
                |(mut e, mut s)| black_box(e.step(&mut s).expect("step")),
                criterion::BatchSize::LargeInput,
            )
        });
    }
}

/// The Siconos fc2d problems not at rest solved to 1e-5 from r = 0 (the 667-contact one
/// is solved by r = 0).
fn fc2d(c: &mut Criterion) {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fc2d");
    for name in [
        "fc2d_granularflowonwall_02020_00213.dat",
        "fc2d_granularflowonwall_07002_00801.dat",
    ] {
        let Ok(p) = cdlab::fc2d::read(&dir.join(name)) else {
            println!("{name}: not found beside the repository, skipped");
            continue;
        };
        let opts = cdlab::fc2d::SolveOptions::default();
        let rep = cdlab::fc2d::solve(&p, &opts);
        println!(
            "{name}: {} contacts, {} sweeps, error {:.2e}, {:.3} ms, {:.2} ns per contact update",
            rep.contacts,
            rep.iterations,
            rep.error,
            rep.seconds * 1e3,
            rep.seconds * 1e9 / (rep.contacts * rep.iterations) as f64
        );
        c.bench_function(name, |b| b.iter(|| black_box(cdlab::fc2d::solve(&p, &opts))));
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = step, fc2d
}
criterion_main!(benches);
