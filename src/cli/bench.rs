//! `cdlab bench`: time per step and per contact update of a confined dense sample under
//! shear, on the CPU and GPU paths, for several sample sizes, with the GPU's dispatches,
//! submissions and readbacks per step and the memory used ([`crate::run::bench`]). Prints a
//! table and writes `bench.json` and `bench.md` (`cli/bench_report.rs`).

use std::path::PathBuf;

use super::bench_report::{line, machine_table, markdown};
use crate::error::{Error, Result};
use crate::run::bench::{measure_cpu, measure_gpu, sheared_sample};

/// Options of `cdlab bench`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Sample sizes (disks), comma separated.
    #[arg(long, value_delimiter = ',', default_value = "5000,50000")]
    pub disks: Vec<usize>,
    /// Measured steps per case.
    #[arg(long, default_value_t = 10)]
    pub steps: u32,
    /// Steps run before measuring (warm start, buffer growth).
    #[arg(long, default_value_t = 5)]
    pub warmup: u32,
    /// Backends, comma separated: cpu, gpu.
    #[arg(long, value_delimiter = ',', default_value = "cpu,gpu")]
    pub backend: Vec<String>,
    /// Solver tolerance.
    #[arg(long, default_value_t = 1e-4)]
    pub tol: f64,
    /// Steps per window (the steps between two waits for the device, as between two
    /// series rows of a test: output.series_every).
    #[arg(long, default_value_t = 10)]
    pub window: u32,
    /// Iterations between two convergence tests, comma separated to compare several
    /// (solver.check_every; 0: the backend's default).
    #[arg(long, value_delimiter = ',', default_value = "0")]
    pub check_every: Vec<u32>,
    /// Solver methods, comma separated (solver.method: colored-gs, jacobi, ...; the GPU
    /// runs colored-gs, gs and jacobi).
    #[arg(long, value_delimiter = ',', default_value = "colored-gs")]
    pub method: Vec<String>,
    /// GPU: host threads recording a window's steps, comma separated to compare several
    /// (0: the backend's choice, `GpuBackend::recording_threads`).
    #[arg(long, value_delimiter = ',', default_value = "0")]
    pub record_threads: Vec<u32>,
    /// GPU: whether iterations past the typical count (up to 32,768 contacts) or in the
    /// recording margin (more contacts) are swept by one workgroup each
    /// (`GpuBackend::overflow_sweeps`), comma separated to compare (true, false).
    #[arg(long, value_delimiter = ',', default_value = "true")]
    pub sweep_all: Vec<bool>,
    /// Rounds: every case is measured this many times, the sizes in turn, and the ratios
    /// between sizes are given per round with their median (on a shared machine one
    /// round's ratio moves with the load).
    #[arg(long, default_value_t = 1)]
    pub rounds: u32,
    /// Output directory.
    #[arg(long, default_value = "out/bench")]
    pub out: PathBuf,
}

/// Runs `cdlab bench`.
pub fn run(args: &Args) -> Result<()> {
    if args.disks.iter().any(|&n| n < 50) {
        return Err(Error::invalid(
            "--disks",
            format!("{:?}", args.disks),
            "every size must be >= 50",
        ));
    }
    for &n in &args.disks {
        crate::config::validate::check_disk_count("--disks", n)?;
    }
    if args.steps == 0 {
        return Err(Error::invalid("--steps", 0, "must be >= 1"));
    }
    if args.rounds == 0 {
        return Err(Error::invalid("--rounds", 0, "must be >= 1"));
    }
    if args.window == 0 {
        return Err(Error::invalid("--window", 0, "must be >= 1"));
    }
    if args.sweep_all.is_empty() {
        return Err(Error::invalid("--sweep-all", "", "give true, false or both"));
    }
    if args.record_threads.is_empty() {
        return Err(Error::invalid("--record-threads", "", "give at least one count"));
    }
    if args.check_every.is_empty() {
        return Err(Error::invalid("--check-every", "", "give at least one interval"));
    }
    let mut params = crate::config::Config::with_disks(50).protocol().step;
    params.solver.tol = args.tol;
    params.validate()?;
    let run = crate::run::bench::Run {
        warmup: args.warmup,
        steps: args.steps,
        window: args.window,
        record_threads: 0,
        sweep_all: true,
    };
    let mut scenes = Vec::new();
    for &n in &args.disks {
        // The geometric deposit of a large sample takes a while (about half a minute at
        // 50,000 disks on one core): say so before it starts.
        eprintln!("{n} disks: depositing the sample");
        let t = std::time::Instant::now();
        scenes.push((n, sheared_sample(n)?));
        eprintln!("{n} disks: sample ready in {:.1} s", t.elapsed().as_secs_f64());
    }
    let mut cases = Vec::new();
    let mut failures = Vec::new();
    let mut machines = Vec::new();
    for (round, (n, scene)) in (1..=args.rounds).flat_map(|r| scenes.iter().map(move |s| (r, s))) {
        let n = *n;
        if args.rounds > 1 {
            eprintln!("round {round} of {}, {n} disks", args.rounds);
        }
        // The machine moves from round to round on a shared host: each round gets its own
        // probe, before its first size.
        if machines.len() < round as usize {
            let m = crate::run::machine::probe();
            eprintln!("round {round}: {}", m.line());
            machines.push(m);
        }
        let combos = args.backend.iter().flat_map(|b| {
            // Recording threads and sweep_all are the GPU's: the CPU runs each case once.
            let gpu = b == "gpu";
            let threads = if gpu {
                &args.record_threads[..]
            } else {
                &args.record_threads[..1]
            };
            let all = if gpu {
                &args.sweep_all[..]
            } else {
                &args.sweep_all[..1]
            };
            args.method.iter().flat_map(move |m| {
                args.check_every.iter().flat_map(move |e| {
                    threads
                        .iter()
                        .flat_map(move |t| all.iter().map(move |a| (b, m, *e, *t, *a)))
                })
            })
        });
        for (b, method, every, threads, sweep_all) in combos {
            let run = crate::run::bench::Run {
                record_threads: threads,
                sweep_all,
                ..run
            };
            let mut params = params;
            params.solver.check_every = every;
            params.solver.method = method.parse()?;
            let mut case = match b.as_str() {
                "cpu" => measure_cpu(scene.clone(), params, n, run)?,
                "gpu" => match measure_gpu(scene.clone(), params, n, run) {
                    Ok(c) => c,
                    // Only a missing adapter is a skip: any other GPU error is a failure.
                    Err(e @ Error::Gpu(crate::error::GpuError::NoAdapter(_))) => {
                        eprintln!("gpu, {n} disks: skipped: {e}");
                        continue;
                    }
                    Err(e) => {
                        eprintln!("gpu, {n} disks: FAILED: {e}");
                        failures.push(format!("gpu, {n} disks: {e}"));
                        continue;
                    }
                },
                other => return Err(Error::invalid("--backend", other, "cpu or gpu")),
            };
            case.round = round;
            case.machine = Some(machines[round as usize - 1]);
            eprintln!("{}", line(&case));
            cases.push(case);
        }
    }
    crate::fsio::create_dir_all(&args.out)?;
    let json = serde_json::to_string_pretty(&cases).map_err(|e| Error::Other(e.to_string()))?;
    let p = args.out.join("bench.json");
    crate::record::atomic::write_file(&p, json.as_bytes())?;
    let mut md = markdown(&cases, args.tol, args.warmup, args.steps);
    md.push_str(&machine_table(&machines));
    for f in &failures {
        md.push_str(&format!("\nFAILED: {f}\n"));
    }
    let p = args.out.join("bench.md");
    crate::record::atomic::write_file(&p, md.as_bytes())?;
    println!("{md}");
    Ok(())
}
