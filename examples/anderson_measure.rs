//! Measures Anderson-accelerated Gauss-Seidel against Gauss-Seidel (docs/method.md,
//! "Anderson-accelerated Gauss-Seidel"): sweeps and velocity rebuilds to a distance to the
//! local solutions (`local_residual`) of 1e-4, on the 2020-contact Siconos fc2d problem and
//! on a step of a recorded run (its last checkpoint, advanced one series window with the
//! step's problem captured), at the run's friction and with every contact's friction set
//! to 3 and to 12.
//!
//! `cargo run --release --example anderson_measure -- RUN_DIR [DEPTHS] [START] [ACCEPT]`
//! (DEPTHS comma-separated, default 0,3,5,10; depth 0 is plain Gauss-Seidel in contact order).
//! Environment: `MUS` (frictions set on the captured contacts, comma-separated, `run` for
//! the run's own; default run,3,12), `RUN_MU` (friction of the run itself before the
//! capture) with `WINDOWS` (series windows advanced before the capture, default 1),
//! `MAXIT` (sweep cap, default 20,000), `EVERY` and `DROP` (the solver's options),
//! `SEARCH` (also find colored Gauss-Seidel's sweeps to the target by bisection over its
//! cap), `CURVE=K` (print the convergence curve every K sweeps instead) and `COST` (print
//! the cost per contact and iteration instead).

use std::path::Path;
use std::time::Instant;

use cdlab::backend::CpuBackend;
use cdlab::fc2d;
use cdlab::protocol::biaxial::Lab;
use cdlab::protocol::checkpoint::decode;
use cdlab::protocol::{Collect, Phase};
use cdlab::record::read_run;
use cdlab::solver::anderson::{self, Options};
use cdlab::solver::captured::Captured;
use cdlab::solver::space::{ContactSpace, closing, local_residual};
use cdlab::solver::{Method, SolverParams};

const TARGET: f64 = 1e-4;

fn status<S: ContactSpace>(s: &S, c: usize) -> u8 {
    let (rn, rt) = s.impulse(c);
    let lim = s.mu(c) * rn;
    if rn <= 0.0 {
        0
    } else if rt.abs() < lim * (1.0 - 1e-12) {
        1
    } else if rt > 0.0 {
        2
    } else {
        3
    }
}

/// Convergence curve: every `every` sweeps, local_residual and the contacts whose status
/// (open, stick, slide either way) changed over the last sweep.
fn curve<S: ContactSpace>(name: &str, s: &mut S, opts: Options, every: u32) {
    let mut prev: Vec<u8> = (0..s.len()).map(|c| status(s, c)).collect();
    let mut line = String::new();
    anderson::solve_until(s, &opts, |s, it| {
        let now: Vec<u8> = (0..s.len()).map(|c| status(s, c)).collect();
        let flips = now.iter().zip(&prev).filter(|(a, b)| a != b).count();
        prev = now;
        if it % every == 0 || it < 10 {
            line += &format!(" {it}:{:.1e}/{flips}", local_residual(s));
        }
        false
    });
    println!(
        "{name} curve depth {} (sweep:local_residual/status changes):{line}",
        opts.depth
    );
}

fn anderson_row<S: ContactSpace>(name: &str, s: &mut S, opts: Options) {
    let t0 = Instant::now();
    let out = anderson::solve_until(s, &opts, |s, _| local_residual(s) <= TARGET);
    // The time includes the residual evaluated after every sweep.
    let secs = t0.elapsed().as_secs_f64();
    println!(
        "{name}: depth {} every {} start {} accept {}: {} sweeps, {} mixed, {} refused, local_residual {:.2e}, change {:.2e}, closing max {:.2e} m/s, {:.3} s with checks",
        opts.depth,
        opts.every,
        opts.start,
        opts.accept,
        out.stats.iterations,
        out.mixed,
        out.rejected,
        local_residual(s),
        out.stats.residual,
        closing(s).max,
        secs
    );
}

/// Iterations colored Gauss-Seidel needs to reach `local_residual <= TARGET` (each solve
/// restarts from the capture; doubling then bisection over the cap).
fn colored_iterations(c: &Captured, p: &SolverParams) -> (u32, f64) {
    let res_at = |k: u32| {
        let q = SolverParams {
            max_iter: k,
            tol: 1e-300,
            ..*p
        };
        let (mut out, _) = c.solve(&q);
        local_residual(&out.space())
    };
    let mut hi = 1;
    while res_at(hi) > TARGET {
        hi *= 2;
        if hi > 20_000 {
            return (u32::MAX, res_at(hi));
        }
    }
    let mut lo = hi / 2;
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if res_at(mid) <= TARGET {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    (hi, res_at(hi))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let depths: Vec<usize> = args
        .get(2)
        .map(|s| s.split(',').map(|d| d.parse().unwrap()).collect())
        .unwrap_or(vec![0, 3, 5, 10]);
    let start: u32 = args.get(3).map_or(anderson::START, |s| s.parse().unwrap());
    let accept: f64 = args.get(4).map_or(anderson::ACCEPT, |s| s.parse().unwrap());
    let opts = |depth| Options {
        tol: 1e-300,
        max_iter: 20_000,
        depth,
        start,
        accept,
        every: std::env::var("EVERY").map_or(anderson::EVERY, |v| v.parse().unwrap()),
        drop: std::env::var("DROP").map_or(anderson::DROP, |v| v.parse().unwrap()),
    };

    let p = fc2d::read(Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/fc2d/fc2d_granularflowonwall_02020_00213.dat"
    )))?;
    for &d in &depths {
        let mut s = fc2d::Space::new(&p);
        let t0 = Instant::now();
        let out = anderson::solve_until(&mut s, &opts(d), |s, _| {
            fc2d::siconos_error(&p, s.impulses()) < 1e-5
        });
        println!(
            "fc2d 2020 to Siconos error 1e-5: depth {d}: {} sweeps, {} mixed, {} refused, error {:.2e}, {:.3} s",
            out.stats.iterations,
            out.mixed,
            out.rejected,
            fc2d::siconos_error(&p, s.impulses()),
            t0.elapsed().as_secs_f64()
        );
        let mut s = fc2d::Space::new(&p);
        anderson_row("fc2d 2020", &mut s, opts(d));
    }

    let Some(dir) = args.get(1) else {
        return Ok(());
    };
    let rec = read_run(dir)?;
    let (_, bytes) = rec.last_checkpoint.clone().ok_or("no checkpoint")?;
    let mut ck = decode(&bytes)?;
    ck.state.phase = Phase::Compression;
    ck.state.params.strain_end = 0.99;
    ck.state.params.snapshot_every = 0.0;
    ck.state.params.step.solver.threads = 1;
    if let Ok(mu) = std::env::var("RUN_MU") {
        let mu: f64 = mu.parse()?;
        ck.state.params.mu = mu;
        ck.state.params.mu_wall = mu;
        ck.scene.material.mu_disk = mu;
        ck.scene.material.mu_wall = mu;
    }
    let windows: usize = std::env::var("WINDOWS").map_or(1, |v| v.parse().unwrap());
    let run_params = ck.state.params.step.solver;
    let mut backend = CpuBackend::new(ck.scene.clone(), ck.state.params.step)?;
    backend.engine_mut().capture(true);
    let mut lab = Lab::resume(backend, ck)?;
    for _ in 0..windows {
        lab.advance(&mut Collect::default())?;
    }
    let captured = lab.backend.engine().captured().ok_or("nothing captured")?.clone();
    println!(
        "captured step: {} contacts, run's solver {:?} tol {} relax {} after {}",
        captured.contacts.len(),
        run_params.method,
        run_params.tol,
        run_params.gauss_seidel.relax,
        run_params.gauss_seidel.relax_after
    );
    let frictions: Vec<Option<f64>> = std::env::var("MUS").map_or(vec![None, Some(3.0), Some(12.0)], |v| {
        v.split(',')
            .map(|m| {
                if m == "run" {
                    None
                } else {
                    Some(m.parse().unwrap())
                }
            })
            .collect()
    });
    let max_iter: u32 = std::env::var("MAXIT").map_or(20_000, |v| v.parse().unwrap());
    let search = std::env::var("SEARCH").is_ok();
    for mu in frictions {
        let mut c = captured.clone();
        if let Some(mu) = mu {
            for k in &mut c.contacts {
                k.mu = mu;
            }
        }
        let label = mu.map_or("run's friction".to_string(), |m| format!("friction {m}"));
        // Colored Gauss-Seidel as the run solves, without the velocity test (it stops on
        // another measure) and sweeping every candidate.
        let colored = SolverParams {
            method: Method::ColoredGs,
            velocity_tol: 0.0,
            open_skip: 0.0,
            threads: 1,
            ..run_params
        };
        let t0 = Instant::now();
        if search {
            let (k, r) = colored_iterations(&c, &colored);
            println!(
                "{label}: colored-gs (gs_relax {} after {}): {k} sweeps to local_residual {r:.2e} ({:.1} s search)",
                colored.gauss_seidel.relax,
                colored.gauss_seidel.relax_after,
                t0.elapsed().as_secs_f64()
            );
        }
        for tol in [3e-4, 1e-4] {
            let q = SolverParams { tol, ..colored };
            let t0 = Instant::now();
            let (mut out, st) = c.solve(&q);
            let t1 = t0.elapsed().as_secs_f64();
            let q2 = SolverParams {
                tol,
                method: Method::AndersonGs,
                ..colored
            };
            let t0 = Instant::now();
            let (mut out2, st2) = c.solve(&q2);
            let t2 = t0.elapsed().as_secs_f64();
            println!(
                "{label}: tol {tol:e}: colored-gs {:.1} ms, anderson-gs {:.1} ms (wall time of the solve, 1 thread)",
                t1 * 1e3,
                t2 * 1e3
            );
            println!(
                "{label}: stopping on change <= {tol:e}: colored-gs {} sweeps, local_residual {:.2e}, closing max {:.2e} m/s; anderson-gs (depth {}) {} sweeps, local_residual {:.2e}, closing max {:.2e} m/s",
                st.iterations,
                local_residual(&out.space()),
                closing(&out.space()).max,
                q2.anderson.depth,
                st2.iterations,
                local_residual(&out2.space()),
                closing(&out2.space()).max,
            );
        }
        if std::env::var("COST").is_ok() {
            // Cost per iteration: 500 iterations at a tolerance no solve meets.
            for d in [0u32, 1, 5, 10] {
                let q = SolverParams {
                    method: Method::AndersonGs,
                    anderson: cdlab::solver::AndersonSettings { depth: d },
                    tol: 1e-300,
                    max_iter: 500,
                    ..run_params
                };
                let t0 = Instant::now();
                let (_, st) = c.solve(&q);
                let secs = t0.elapsed().as_secs_f64();
                println!(
                    "{label}: depth {d}: {:.1} ns per contact and iteration ({} iterations)",
                    secs / (st.iterations as f64 * c.contacts.len() as f64) * 1e9,
                    st.iterations
                );
            }
            continue;
        }
        if let Ok(every) = std::env::var("CURVE") {
            for &d in &depths {
                let mut cc = c.clone();
                curve(
                    &label,
                    &mut cc.space(),
                    Options { max_iter, ..opts(d) },
                    every.parse().unwrap(),
                );
            }
            continue;
        }
        for &d in &depths {
            let mut cc = c.clone();
            anderson_row(&label, &mut cc.space(), Options { max_iter, ..opts(d) });
        }
    }
    Ok(())
}
