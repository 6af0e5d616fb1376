//! Time per step of a real test state: continues the compression of a recorded run from its
//! last checkpoint (a finished run is compressed further) for a number of series windows on
//! the CPU path, and prints ms per step, iterations per step and ns per contact update.
//!
//! `CDLAB_RUN=out/biaxial cargo bench --bench checkpoint`, with optional `CDLAB_WINDOWS`
//! (default 30 windows of the run's series interval), `CDLAB_THREADS` (team size, default 1),
//! `CDLAB_TOL` (solver tolerance, default the run's), `CDLAB_MAX_ITER` (iteration cap),
//! `CDLAB_GS_RELAX` (Gauss-Seidel relaxation after `gs_relax_after` iterations), `CDLAB_METHOD` (gs, colored-gs,
//! jacobi, and the other methods of `solver.method`), `CDLAB_DT` (time step in ms),
//! `CDLAB_MU` (disk-disk friction), `CDLAB_ALERT` (alert distance as a fraction of the smallest radius) and
//! `CDLAB_OPEN_SKIP` (the `solver.open_skip_gap` of the configuration: a fraction of the
//! smallest radius; 0 sweeps every candidate). `CDLAB_BACKEND=gpu` continues on the GPU
//! path instead (a device is required) and adds the device's counts per step (dispatches,
//! MB moved, readbacks; docs/benchmarks.md, "GPU performance model"). Without `CDLAB_RUN`
//! it says so and measures nothing.
//!
//! It also prints how far the disk pairs that overlap at the end sank over the measured steps
//! (their overlap at the end minus at the start, in `r_min`): the largest overlap of the
//! sample is often an old contact, while a pair that sinks at every step shows the residual
//! approach the solver leaves (docs/results.md, "Overlaps at high friction").

use std::collections::HashMap;

use cdlab::backend::{Backend, CpuBackend};
use cdlab::contact::detect::CellGrid;
use cdlab::model::Scene;
use cdlab::protocol::Collect;
use cdlab::protocol::biaxial::Lab;

mod common;
use common::{continued, env, r_min};

/// The overlap of every overlapping disk pair, in units of `r_min`, keyed by the pair's
/// indices, found on the cell grid of contact detection.
fn pair_overlaps(s: &Scene, r_min: f64) -> cdlab::error::Result<HashMap<(usize, usize), f64>> {
    let d = &s.disks;
    let r_max = d.radius.iter().cloned().fold(0.0, f64::max);
    let mut grid = CellGrid::default();
    grid.build(&d.pos, 2.0 * r_max)?;
    let mut out = HashMap::new();
    for i in 0..d.pos.len() {
        grid.for_neighbours(i, |j| {
            let gap = (d.pos[i] - d.pos[j]).length() - d.radius[i] - d.radius[j];
            if j > i && gap < 0.0 {
                out.insert((i, j), -gap / r_min);
            }
        });
    }
    Ok(out)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let Some(dir) = std::env::var_os("CDLAB_RUN") else {
        println!("checkpoint bench: set CDLAB_RUN=DIR (a run directory) to measure its compression");
        return Ok(());
    };
    let mut ck = continued(&dir, env("CDLAB_THREADS").unwrap_or(1))?;
    let solver = &mut ck.state.params.step.solver;
    if let Some(tol) = env("CDLAB_TOL") {
        solver.tol = tol;
    }
    if let Some(cap) = env("CDLAB_MAX_ITER") {
        solver.max_iter = cap;
    }
    if let Some(w) = env("CDLAB_GS_RELAX") {
        solver.gauss_seidel.relax = w;
    }
    if let Some(m) = env::<String>("CDLAB_METHOD") {
        solver.method = m.parse()?;
    }
    // Fractions of the smallest radius, as in the configuration.
    let r_min = r_min(&ck);
    if let Some(gap) = env::<f64>("CDLAB_OPEN_SKIP") {
        let step = &mut ck.state.params.step;
        step.solver.open_skip = gap * r_min / step.dt;
    }
    if let Some(alert) = env::<f64>("CDLAB_ALERT") {
        ck.state.params.step.alert = alert * r_min;
    }
    let windows: usize = env("CDLAB_WINDOWS").unwrap_or(30);
    let before = pair_overlaps(&ck.scene, r_min)?;
    let params = ck.state.params.step;
    if env::<String>("CDLAB_BACKEND").as_deref() == Some("gpu") {
        let backend = cdlab::gpu::backend::GpuBackend::new(ck.scene.clone(), params)?;
        let start = backend.counters();
        let (mut lab, obs, secs) = measure(backend, ck, windows)?;
        let steps = steps_of(&lab.state, &obs);
        let d = lab.backend.counters() - start;
        let per = |x: f64| x / steps;
        println!(
            "GPU ({}): {:.1} dispatches/step, {:.2} MB/step moved on the device, {:.2} readbacks/step",
            lab.backend.name(),
            per(d.dispatches as f64),
            per((d.bytes_read + d.bytes_written) as f64) / 1e6,
            per(d.readbacks as f64),
        );
        let scene = lab.backend.scene()?;
        return report(&dir, &lab.state, &obs, secs, &before, &scene, r_min);
    }
    let backend = CpuBackend::new(ck.scene.clone(), params)?;
    let (lab, obs, secs) = measure(backend, ck, windows)?;
    report(
        &dir,
        &lab.state,
        &obs,
        secs,
        &before,
        lab.backend.scene_ref(),
        r_min,
    )
}

/// Continues the lab for `windows` series windows; returns it, the rows and the seconds.
fn measure<B: Backend>(
    backend: B,
    ck: cdlab::protocol::checkpoint::Checkpoint,
    windows: usize,
) -> Result<(Lab<B>, Collect, f64), Box<dyn std::error::Error>> {
    let mut lab = Lab::resume(backend, ck)?;
    let mut obs = Collect::default();
    let t0 = std::time::Instant::now();
    for _ in 0..windows {
        lab.advance(&mut obs)?;
    }
    Ok((lab, obs, t0.elapsed().as_secs_f64()))
}

/// Steps measured: the series rows times the steps per row.
fn steps_of(state: &cdlab::protocol::LabState, obs: &Collect) -> f64 {
    obs.rows.len().max(1) as f64 * state.params.series_every as f64
}

/// Prints the time, iterations and contacts per step, and how far the deepest pairs sank.
fn report(
    dir: &std::ffi::OsStr,
    state: &cdlab::protocol::LabState,
    obs: &Collect,
    secs: f64,
    before: &HashMap<(usize, usize), f64>,
    end: &Scene,
    r_min: f64,
) -> Result<(), Box<dyn std::error::Error>> {
    let after = pair_overlaps(end, r_min)?;
    let mut sank: Vec<f64> = after
        .iter()
        .map(|(pair, &o)| o - before.get(pair).copied().unwrap_or(0.0))
        .collect();
    sank.sort_by(|a, b| b.total_cmp(a));
    let rows = obs.rows.len().max(1) as f64;
    let steps = steps_of(state, obs);
    let iterations = obs.rows.iter().map(|r| r.iterations).sum::<f64>() / rows;
    let contacts = obs.rows.iter().map(|r| r.n_contacts as f64).sum::<f64>() / rows;
    let last = obs.rows.last().ok_or("no window ran")?;
    let cap = state.params.step.solver.max_iter;
    let capped = obs
        .rows
        .iter()
        .filter(|r| r.iterations_max >= u64::from(cap))
        .count();
    println!(
        "{steps} steps from {}: {:.3} ms/step, {iterations:.1} iterations/step ({capped} of {} windows hold a step at the cap of {cap}), {contacts:.0} contacts, {:.2} ns per contact update (whole step); at the end sigma1 {:.3} MPa, {} force-carrying contacts, max overlap {:.2e} r_min",
        std::path::Path::new(dir).display(),
        secs / steps * 1e3,
        obs.rows.len(),
        secs / (steps * iterations * contacts) * 1e9,
        last.sigma1_pa / 1e6,
        last.n_force,
        last.overlap_max_rel,
    );
    println!(
        "pairs that sank deepest over these steps: {} (r_min; a pair that was not overlapping at the start counts from 0)",
        sank.iter()
            .take(3)
            .map(|x| format!("{x:.3e}"))
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}
