//! A performance model of the GPU path, fitted on the adapter at hand (docs/benchmarks.md,
//! "GPU performance model"): time per step = a x dispatches + b x bytes + c x readbacks,
//! where the three counts per step are the GPU counters (`cdlab::gpu::GpuCounters`: the
//! bytes from the per-kernel table of `src/gpu/traffic.rs`).
//!
//! The sheared sample of `cdlab bench` is stepped with a fixed number of solver iterations
//! per step (tolerance 1e-30, no velocity test, so every step runs exactly `max_iter`),
//! for each size, method (colored-gs, jacobi) and (iterations, convergence check interval)
//! setting: the settings move the three counts apart (sizes scale the bytes, the methods
//! and iterations the dispatches, the check interval the readbacks). The fit is weighted
//! least squares on relative residuals (the times span two decades). Larger sizes are
//! held out: their times are predicted from the fit and then measured.
//!
//! Environment: `CDLAB_GPU_MODEL_DISKS` (fit sizes, default 500,2000,5000),
//! `CDLAB_GPU_MODEL_HOLDOUT` (held-out sizes, default 20000,50000; empty for none),
//! `CDLAB_GPU_MODEL_STEPS` (measured steps per point, default 6). Run with
//! `cargo bench --bench gpu_model`; it needs a GPU adapter (lavapipe will do).

use std::time::Instant;

use cdlab::analysis::fit::{invert, solve_linear};
use cdlab::backend::{Backend, Loading};
use cdlab::engine::StepParams;
use cdlab::gpu::GpuBackend;
use cdlab::run::bench::sheared_sample;
use cdlab::solver::Method;

/// One measured point, per step.
#[derive(Clone, Debug)]
struct Point {
    disks: usize,
    method: Method,
    max_iter: u32,
    check_every: u32,
    contacts: u32,
    iterations: f64,
    colors: f64,
    dispatches: f64,
    /// Bytes read + written by the dispatches.
    bytes: f64,
    submissions: f64,
    readbacks: f64,
    ms: f64,
}

impl Point {
    /// The counted regressors: dispatches, bytes, readbacks.
    fn x(&self) -> [f64; 3] {
        [self.dispatches, self.bytes, self.readbacks]
    }
}

/// Model A: ms = a dispatches + b bytes + c readbacks.
fn counted(p: &Point) -> Vec<f64> {
    p.x().to_vec()
}

/// Model B: model A + d disks, the work per disk and step the byte table leaves out
/// (the neighbour walks of detection and coloring, see src/gpu/traffic.rs).
fn with_disks(p: &Point) -> Vec<f64> {
    let mut x = p.x().to_vec();
    x.push(p.disks as f64);
    x
}

fn env_list(name: &str, default: &str) -> Vec<usize> {
    let v = std::env::var(name).unwrap_or_else(|_| default.to_string());
    v.split(',')
        .filter(|s| !s.trim().is_empty())
        .map(|s| {
            s.trim()
                .parse()
                .unwrap_or_else(|e| panic!("{name} = {v:?}: {s:?} is not a count ({e})"))
        })
        .collect()
}

fn params(method: Method) -> StepParams {
    let mut p = cdlab::Config::with_disks(50).protocol().step;
    p.solver.method = method;
    // Never converged: every step runs exactly max_iter iterations.
    p.solver.tol = 1e-30;
    p.solver.velocity_tol = 0.0;
    p
}

/// Measures every (max_iter, check_every) setting on one backend (one sample, one method).
fn measure(n: usize, method: Method, settings: &[(u32, u32)], steps: u32) -> Vec<Point> {
    let scene = sheared_sample(n).expect("sample");
    let mut g =
        GpuBackend::new(scene, params(method)).expect("GPU backend (set CDLAB_REQUIRE_GPU=1 and a backend)");
    // Warm start, buffer growth, coloring settled.
    g.run(3, &Loading::default()).expect("warm-up");
    let mut out = Vec::new();
    for &(max_iter, every) in settings {
        let mut p = params(method);
        p.solver.max_iter = max_iter;
        g.set_params(p).expect("params");
        g.conv_every = every;
        g.run(1, &Loading::default()).expect("step");
        let k0 = g.counters();
        let t0 = Instant::now();
        let red = g.run(steps, &Loading::default()).expect("steps");
        let secs = t0.elapsed().as_secs_f64();
        let k = g.counters() - k0;
        let s = k.steps as f64;
        let point = Point {
            disks: n,
            method,
            max_iter,
            check_every: every,
            contacts: red.candidates,
            iterations: k.iterations as f64 / s,
            colors: red.colors_mean,
            dispatches: k.dispatches as f64 / s,
            bytes: (k.bytes_read + k.bytes_written) as f64 / s,
            submissions: k.submissions as f64 / s,
            readbacks: k.readbacks as f64 / s,
            ms: secs * 1e3 / s,
        };
        eprintln!("{}", row(&point, None));
        out.push(point);
    }
    out
}

fn row(p: &Point, model_ms: Option<f64>) -> String {
    let fit = model_ms.map_or(String::new(), |m| {
        format!(" {:.2} | {:+.1}% |", m, 100.0 * (m - p.ms) / p.ms)
    });
    format!(
        "| {} | {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.2} | {:.1} | {:.1} | {:.2} |{fit}",
        p.disks,
        p.method.name(),
        p.contacts,
        p.check_every,
        p.iterations,
        p.colors,
        p.dispatches,
        p.bytes / 1e6,
        p.submissions,
        p.readbacks,
        p.ms,
    )
}

/// A fitted linear model: ms per step = regressors . coef, with the coefficients'
/// standard errors.
struct Fit {
    coef: Vec<f64>,
    se: Vec<f64>,
    /// The regressors of a point.
    x: fn(&Point) -> Vec<f64>,
}

impl Fit {
    fn predict(&self, p: &Point) -> f64 {
        (self.x)(p).iter().zip(&self.coef).map(|(x, c)| x * c).sum()
    }

    /// Relative residuals (model - measured) / measured.
    fn residuals(&self, points: &[Point]) -> Vec<f64> {
        points.iter().map(|p| (self.predict(p) - p.ms) / p.ms).collect()
    }
}

/// Weighted least squares of ms = x . coef with weights 1 / ms^2: relative residuals,
/// since the times span two decades and each is uncertain by a fraction of itself.
fn fit(points: &[Point], x: fn(&Point) -> Vec<f64>) -> Fit {
    let k = x(&points[0]).len();
    let mut ata = vec![vec![0.0; k]; k];
    let mut atb = vec![0.0; k];
    for p in points {
        let row: Vec<f64> = x(p).iter().map(|v| v / p.ms).collect();
        for i in 0..k {
            for j in 0..k {
                ata[i][j] += row[i] * row[j];
            }
            atb[i] += row[i];
        }
    }
    // Columns scaled to unit size first: bytes are 1e6 times the other counts.
    let scale: Vec<f64> = (0..k).map(|i| ata[i][i].sqrt()).collect();
    let scaled: Vec<Vec<f64>> = (0..k)
        .map(|i| (0..k).map(|j| ata[i][j] / (scale[i] * scale[j])).collect())
        .collect();
    let y = solve_linear(scaled.clone(), (0..k).map(|i| atb[i] / scale[i]).collect())
        .expect("a determined fit: the points vary in every regressor");
    let coef: Vec<f64> = (0..k).map(|i| y[i] / scale[i]).collect();
    let mut f = Fit {
        coef,
        se: vec![0.0; k],
        x,
    };
    let dof = (points.len() as f64 - k as f64).max(1.0);
    let s2 = f.residuals(points).iter().map(|r| r * r).sum::<f64>() / dof;
    // Diagonal of (A^T A)^-1 through the scaled system.
    let inv = invert(&scaled).expect("a determined fit");
    f.se = (0..k).map(|i| (s2 * inv[i][i]).sqrt() / scale[i]).collect();
    f
}

fn rms_and_worst(r: &[f64]) -> (f64, f64) {
    let rms = (r.iter().map(|r| r * r).sum::<f64>() / r.len().max(1) as f64).sqrt();
    (rms, r.iter().map(|r| r.abs()).fold(0.0, f64::max))
}

/// Per-step counts as a function of the iterations at one size, from two settings with
/// the same check interval: count = fixed + per_iteration x iterations.
struct Linear {
    disks: usize,
    contacts: u32,
    fixed: [f64; 3],
    per_iteration: [f64; 3],
    check_every: u32,
}

fn linear(points: &[Point], n: usize) -> Option<Linear> {
    let gs: Vec<&Point> = points
        .iter()
        .filter(|p| p.disks == n && p.method == Method::ColoredGs && p.check_every == 8)
        .collect();
    let (lo, hi) = (
        gs.iter().min_by_key(|p| p.max_iter)?,
        gs.iter().max_by_key(|p| p.max_iter)?,
    );
    if hi.iterations <= lo.iterations {
        return None;
    }
    let dk = hi.iterations - lo.iterations;
    let (xl, xh) = (lo.x(), hi.x());
    let per: [f64; 3] = std::array::from_fn(|i| (xh[i] - xl[i]) / dk);
    Some(Linear {
        disks: n,
        contacts: hi.contacts,
        fixed: std::array::from_fn(|i| xl[i] - per[i] * lo.iterations),
        per_iteration: per,
        check_every: 8,
    })
}

/// A device of the predictions: name, bandwidth (bytes/s), time per dispatch (s), time
/// per readback round trip (s).
struct Device {
    name: &'static str,
    bandwidth: f64,
    dispatch: f64,
    sync: f64,
}

fn main() {
    // `cargo bench` passes `--bench`; nothing to parse.
    let fit_sizes = env_list("CDLAB_GPU_MODEL_DISKS", "500,2000,5000");
    let holdout = env_list("CDLAB_GPU_MODEL_HOLDOUT", "20000,50000");
    let steps = env_list("CDLAB_GPU_MODEL_STEPS", "6")
        .first()
        .copied()
        .unwrap_or(4) as u32;
    // (max_iter, check_every): the check interval moves the readbacks, the iterations the
    // dispatches and bytes together, the sizes the bytes alone.
    let settings = [(8, 1), (8, 8), (32, 8), (32, 32)];
    let header = "| disks | method | contacts | check every | iterations/step | colors | dispatches/step | MB/step | submissions/step | readbacks/step | ms/step |";
    let rule = "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |";
    eprintln!("{header}\n{rule}");
    let mut points = Vec::new();
    for &n in &fit_sizes {
        for method in [Method::ColoredGs, Method::Jacobi] {
            points.extend(measure(n, method, &settings, steps));
        }
    }
    // Held-out sizes, measured before fitting and predicted from the fit only.
    let mut held = Vec::new();
    for &n in &holdout {
        held.extend(measure(n, Method::ColoredGs, &[(8, 8), (32, 8)], steps.min(3)));
    }
    let models = [
        ("A: a dispatches + b bytes + c readbacks", fit(&points, counted)),
        ("B: A + d disks", fit(&points, with_disks)),
    ];
    for (name, f) in &models {
        println!(
            "\n## Model {name}, fitted on {} points ({steps} steps each)\n",
            points.len()
        );
        let units = ["ms per dispatch", "ms per byte", "ms per readback", "ms per disk"];
        for (i, (c, e)) in f.coef.iter().zip(&f.se).enumerate() {
            println!("- {} = {c:.4e} ± {e:.1e} {}", ["a", "b", "c", "d"][i], units[i]);
        }
        println!(
            "- that is {:.1} us per dispatch, {:.2} GB/s, {:.0} us per readback{}",
            f.coef[0] * 1e3,
            1e-6 / f.coef[1],
            f.coef[2] * 1e3,
            f.coef.get(3).map_or(String::new(), |d| format!(
                ", {:.2} us per disk = {:.0} bytes per disk",
                d * 1e3,
                d / f.coef[1]
            ))
        );
        println!("\n{header} model ms | residual |\n{rule} --- | --- |");
        for p in points.iter().chain(&held) {
            println!("{}", row(p, Some(f.predict(p))));
        }
        let (rms, worst) = rms_and_worst(&f.residuals(&points));
        let (hrms, hworst) = rms_and_worst(&f.residuals(&held));
        println!(
            "\nrelative residuals: fitted points rms {:.1}%, largest {:.1}%; held-out points rms {:.1}%, largest {:.1}%",
            100.0 * rms,
            100.0 * worst,
            100.0 * hrms,
            100.0 * hworst
        );
    }
    let f = &models[1].1;
    let (a, b, c) = (f.coef[0], f.coef[1], f.coef[2]);
    // Model B's per-disk term, carried to other devices as the bytes it costs here.
    let bytes_per_disk = f.coef[3] / b;

    // Counts per step as a function of the iterations, then the predictions.
    let all: Vec<Point> = points.iter().chain(&held).cloned().collect();
    let mut sizes: Vec<usize> = all.iter().map(|p| p.disks).collect();
    sizes.sort_unstable();
    sizes.dedup();
    let lines: Vec<Linear> = sizes.iter().filter_map(|&n| linear(&all, n)).collect();
    println!(
        "\n## Counts per step (colored-gs, check every 8): fixed + per iteration\n\n\
         | disks | contacts | dispatches | MB | readbacks |\n| --- | --- | --- | --- | --- |"
    );
    for l in &lines {
        println!(
            "| {} | {} | {:.1} + {:.2} k | {:.2} + {:.3} k | {:.2} + {:.3} k |",
            l.disks,
            l.contacts,
            l.fixed[0],
            l.per_iteration[0],
            l.fixed[1] / 1e6,
            l.per_iteration[1] / 1e6,
            l.fixed[2],
            l.per_iteration[2]
        );
    }
    // Assumptions (docs/benchmarks.md names their sources): bandwidth as published,
    // dispatch and readback latencies as round figures.
    let devices = [
        Device {
            name: "fitted adapter",
            bandwidth: 1e3 / b,
            dispatch: a * 1e-3,
            sync: c * 1e-3,
        },
        Device {
            name: "H100 SXM (3.35 TB/s, 5 us/dispatch, 30 us/readback)",
            bandwidth: 3.35e12,
            dispatch: 5e-6,
            sync: 30e-6,
        },
        Device {
            name: "A100 80GB (2.0 TB/s, 5 us/dispatch, 30 us/readback)",
            bandwidth: 2.0e12,
            dispatch: 5e-6,
            sync: 30e-6,
        },
    ];
    println!(
        "\n## Predictions (ms/step; the counts above, extrapolated linearly in the iterations)\n\n\
         MB include model B's per-disk term as bytes ({bytes_per_disk:.0} per disk).\n\n\
         | device | disks | iterations/step | dispatches | MB | readbacks | ms/step | of which dispatches / bytes / readbacks |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- |"
    );
    // The sizes of the paper's tests when measured, else every size.
    let paper = |n: usize| n == 5000 || n == 50_000;
    let shown: Vec<&Linear> = if lines.iter().any(|l| paper(l.disks)) {
        lines.iter().filter(|l| paper(l.disks)).collect()
    } else {
        lines.iter().collect()
    };
    for dev in &devices {
        for l in &shown {
            for k in [6.0, 31.0, 120.0, 640.0] {
                // Readbacks: one per check of `check_every` iterations, whole batches.
                let batches = (k / l.check_every as f64).ceil();
                let x = [
                    l.fixed[0] + l.per_iteration[0] * k,
                    l.fixed[1] + l.per_iteration[1] * k,
                    l.fixed[2] + batches,
                ];
                let bytes = x[1] + bytes_per_disk * l.disks as f64;
                let parts = [x[0] * dev.dispatch, bytes / dev.bandwidth, x[2] * dev.sync].map(|s| s * 1e3);
                println!(
                    "| {} | {} | {k} | {:.0} | {:.1} | {:.1} | {:.3} | {:.3} / {:.3} / {:.3} |",
                    dev.name,
                    l.disks,
                    x[0],
                    bytes / 1e6,
                    x[2],
                    parts.iter().sum::<f64>(),
                    parts[0],
                    parts[1],
                    parts[2]
                );
            }
        }
    }
}
