//! Solvers side by side on the same contact problems, taken from a real test: continues the
//! compression of a recorded run from its last checkpoint on the CPU path, keeps the
//! contact problem of the last step of several series windows (`CpuEngine::capture`), and
//! solves each of them again with every listed method. For each problem and method it
//! records
//!
//! - the convergence curve: the method's own stopping measure (the relative change of one
//!   iteration), the distance of the impulses to their local solutions
//!   (`solver::space::local_residual`, the measure common to every method) and the
//!   closing velocity left at loaded contacts, after 1, 2, 3, 4, 6, 8, ... iterations
//!   (each point a fresh solve capped there: the solves are deterministic, so the point at
//!   cap k is the iterate after k iterations);
//! - the solve to tolerance with the run's solver settings (only the method changed):
//!   iterations, contact updates, wall time, and the same measures at the end.
//!
//! `CDLAB_RUN=out/biaxial cargo bench --bench solvers`, with optional
//! `CDLAB_METHODS` (comma separated, default `colored-gs,gs,jacobi`),
//! `CDLAB_STATES` (problems kept, default 3), `CDLAB_WINDOWS` (series windows between two
//! kept problems, default 5), `CDLAB_DT` (time step in ms for the continued steps; default
//! the run's), `CDLAB_MU` (disk-disk friction for the continued steps; default the run's),
//! `CDLAB_TOL` (tolerance of the solves to tolerance; default the run's),
//! `CDLAB_CURVE_MAX` (last cap of the curves, default the run's iteration cap) and
//! `CDLAB_OUT` (CSV file of every point, default `solvers.csv` in the current directory)
//! and `CDLAB_DIAG` (an iteration count: colored Gauss-Seidel is run that long on each kept
//! problem and the contacts ranked by their share of the squared distance to the local
//! solutions, grouped by partner and by the status of the impulse and of its local
//! solution).
//! Without `CDLAB_RUN` it says so and measures nothing.

use std::time::Instant;

use cdlab::backend::CpuBackend;
use cdlab::protocol::Collect;
use cdlab::protocol::biaxial::Lab;
use cdlab::solver::captured::Captured;
use cdlab::solver::space::{closing, local_residual};
use cdlab::solver::{Method, SolveStats, SolverParams};

mod common;
use common::{continued, env, r_min};

/// What one solve left: the method's own last change, the common measures and its cost.
struct Point {
    stats: SolveStats,
    residual: f64,
    closing_max: f64,
    closing_mean: f64,
    loaded: usize,
    seconds: f64,
}

fn measure(problem: &Captured, params: &SolverParams) -> Point {
    let t0 = Instant::now();
    let (mut solved, stats) = problem.solve(params);
    let seconds = t0.elapsed().as_secs_f64();
    let space = solved.space();
    let c = closing(&space);
    Point {
        stats,
        residual: local_residual(&space),
        closing_max: c.max,
        closing_mean: c.mean,
        loaded: c.loaded,
        seconds,
    }
}

/// Where the distance to the local solutions sits after `params.max_iter` iterations: the
/// share of its square carried by the worst contacts, and what kind of contact they are
/// (partner, status of the impulse and of its local solution).
fn diagnose(step: u64, problem: &Captured, params: &SolverParams, disks: usize) {
    use cdlab::solver::space::{ContactSpace, local_solution};
    let (mut solved, _) = problem.solve(params);
    let space = solved.space();
    let status = |rn: f64, rt: f64, mu: f64| {
        if rn <= 0.0 {
            "open"
        } else if rt.abs() >= mu * rn * (1.0 - 1e-9) {
            "slide"
        } else {
            "stick"
        }
    };
    let mut rows: Vec<(f64, usize)> = (0..space.len())
        .map(|c| {
            let (ln, lt) = local_solution(&space, c);
            let (rn, rt) = space.impulse(c);
            ((ln - rn).powi(2) + (lt - rt).powi(2), c)
        })
        .collect();
    let total: f64 = rows.iter().map(|r| r.0).sum();
    rows.sort_by(|a, b| b.0.total_cmp(&a.0));
    let share = |k: usize| rows.iter().take(k).map(|r| r.0).sum::<f64>() / total;
    println!(
        "step {step}, {} iterations of {}: the worst 10 contacts carry {:.0}% of the squared distance, the worst 1% ({}) {:.0}%",
        params.max_iter,
        params.method.name(),
        100.0 * share(10),
        space.len() / 100,
        100.0 * share(space.len() / 100)
    );
    let mut kinds = std::collections::BTreeMap::<String, (usize, f64)>::new();
    for &(d2, c) in rows.iter().take(space.len() / 100) {
        let k = &space.contacts[c];
        let (ln, lt) = local_solution(&space, c);
        let partner = if k.ma != 0.0 || k.wnt != 0.0 {
            "force-driven wall"
        } else if k.disk_j as usize >= disks {
            "wall"
        } else if !k.moves_j() {
            "glued disk"
        } else {
            "disk"
        };
        let key = format!(
            "{partner:>17}, {:>5} -> {:<5}",
            status(k.rn, k.rt, k.mu),
            status(ln, lt, k.mu)
        );
        let e = kinds.entry(key).or_default();
        e.0 += 1;
        e.1 += d2 / total;
    }
    for (k, (n, s)) in kinds {
        println!(
            "    {k}: {n:>5} contacts, {:.1}% of the squared distance",
            100.0 * s
        );
    }
}

/// Caps of the convergence curve: 1, 2, 3, 4, 6, 8, 11, 16, ... up to `max` (factor about
/// 1.4, so that a curve costs about 3.5 solves of `max` iterations).
fn caps(max: u32) -> Vec<u32> {
    let mut out = vec![];
    let mut k = 1.0f64;
    while (k as u32) < max {
        let c = k.round() as u32;
        if out.last() != Some(&c) {
            out.push(c);
        }
        k *= 1.4;
    }
    out.push(max);
    out
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let Some(dir) = std::env::var_os("CDLAB_RUN") else {
        println!("solvers bench: set CDLAB_RUN=DIR (a run directory) to compare the solvers on its states");
        return Ok(());
    };
    let ck = continued(&dir, 1)?;
    let base = ck.state.params.step.solver;
    let tol = env("CDLAB_TOL").unwrap_or(base.tol);
    let curve_max = env("CDLAB_CURVE_MAX").unwrap_or(base.max_iter);
    let methods: Vec<Method> = std::env::var("CDLAB_METHODS")
        .unwrap_or_else(|_| "colored-gs,gs,jacobi".into())
        .split(',')
        .map(str::parse)
        .collect::<Result<_, _>>()?;
    let states: usize = env("CDLAB_STATES").unwrap_or(3);
    let windows: usize = env("CDLAB_WINDOWS").unwrap_or(5);
    let out = std::env::var("CDLAB_OUT").unwrap_or_else(|_| "solvers.csv".into());
    let (dt, mu) = (ck.state.params.step.dt, ck.scene.material.mu_disk);
    let r_min = r_min(&ck);
    let disks = ck.scene.disks.len();

    let mut backend = CpuBackend::new(ck.scene.clone(), ck.state.params.step)?;
    backend.engine_mut().capture(true);
    let mut lab = Lab::resume(backend, ck)?;
    let mut obs = Collect::default();
    let mut problems = vec![];
    for _ in 0..states {
        for _ in 0..windows {
            lab.advance(&mut obs)?;
        }
        let p = lab.backend.engine().captured().ok_or("no step ran")?.clone();
        problems.push((lab.backend.scene_ref().step, p));
    }

    let mut csv = String::from(
        "disks,mu,dt_s,state_step,contacts,method,kind,cap,iterations,converged,change,local_residual,closing_max_mps,closing_mean_mps,loaded,seconds\n",
    );
    println!(
        "{} from {}: {disks} disks, friction {mu}, dt {:.4} ms, tolerance {tol:.1e}; sinking = closing velocity x dt / r_min per step",
        if states == 1 { "1 problem" } else { "problems" },
        std::path::Path::new(&dir).display(),
        dt * 1e3
    );
    println!(
        "{:>10} {:>7} {:>12} {:>6} {:>10} {:>11} {:>13} {:>11} {:>11} {:>10}",
        "step",
        "contacts",
        "method",
        "iter",
        "updates",
        "wall (ms)",
        "local resid.",
        "change",
        "sink max",
        "sink mean"
    );
    for (step, p) in &problems {
        let nc = p.contacts.len();
        for &method in &methods {
            let name = method.name();
            let to_tol = SolverParams { method, tol, ..base };
            let pt = measure(p, &to_tol);
            let row = |kind: &str, cap: u32, pt: &Point| {
                format!(
                    "{disks},{mu},{dt},{step},{nc},{name},{kind},{cap},{},{},{:e},{:e},{:e},{:e},{},{:e}\n",
                    pt.stats.iterations,
                    pt.stats.converged,
                    pt.stats.residual,
                    pt.residual,
                    pt.closing_max,
                    pt.closing_mean,
                    pt.loaded,
                    pt.seconds
                )
            };
            csv.push_str(&row("tolerance", to_tol.max_iter, &pt));
            println!(
                "{step:>10} {nc:>7} {name:>12} {:>6} {:>10} {:>11.3} {:>13.2e} {:>11.2e} {:>11.2e} {:>10.2e}",
                pt.stats.iterations,
                u64::from(pt.stats.iterations) * nc as u64,
                pt.seconds * 1e3,
                pt.residual,
                pt.stats.residual,
                pt.closing_max * dt / r_min,
                pt.closing_mean * dt / r_min,
            );
            // The curve: the method alone, no other stopping test, capped at each point.
            for cap in caps(curve_max) {
                let params = SolverParams {
                    method,
                    tol: f64::MIN_POSITIVE,
                    max_iter: cap,
                    velocity_tol: 0.0,
                    ..base
                };
                let pt = measure(p, &params);
                csv.push_str(&row("curve", cap, &pt));
            }
        }
    }
    if let Some(cap) = env::<u32>("CDLAB_DIAG") {
        for (step, p) in &problems {
            diagnose(
                *step,
                p,
                &SolverParams {
                    tol: f64::MIN_POSITIVE,
                    max_iter: cap,
                    velocity_tol: 0.0,
                    ..base
                },
                disks,
            );
        }
    }
    cdlab::fsio::write_file(std::path::Path::new(&out), csv.as_bytes())?;
    println!("every point written to {out}");
    Ok(())
}
