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
//! smallest radius; 0 sweeps every candidate). Without `CDLAB_RUN` it says so and measures nothing.
//!
//! It also prints how far the disk pairs that overlap at the end sank over the measured steps
//! (their overlap at the end minus at the start, in `r_min`): the largest overlap of the
//! sample is often an old contact, while a pair that sinks at every step shows the residual
//! approach the solver leaves (docs/results.md, "Overlaps at high friction").

use std::collections::HashMap;

use cdlab::backend::CpuBackend;
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
        solver.gs_relax = w;
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
    let backend = CpuBackend::new(ck.scene.clone(), ck.state.params.step)?;
    let mut lab = Lab::resume(backend, ck)?;
    let mut obs = Collect::default();
    let t0 = std::time::Instant::now();
    for _ in 0..windows {
        lab.advance(&mut obs)?;
    }
    let secs = t0.elapsed().as_secs_f64();
    let after = pair_overlaps(lab.backend.scene_ref(), r_min)?;
    let mut sank: Vec<f64> = after
        .iter()
        .map(|(pair, &o)| o - before.get(pair).copied().unwrap_or(0.0))
        .collect();
    sank.sort_by(|a, b| b.total_cmp(a));
    let rows = obs.rows.len().max(1) as f64;
    let steps = rows * lab.state.params.series_every as f64;
    let iterations = obs.rows.iter().map(|r| r.iterations).sum::<f64>() / rows;
    let contacts = obs.rows.iter().map(|r| r.n_contacts as f64).sum::<f64>() / rows;
    let last = obs.rows.last().ok_or("no window ran")?;
    let cap = lab.state.params.step.solver.max_iter;
    let capped = obs
        .rows
        .iter()
        .filter(|r| r.iterations_max >= u64::from(cap))
        .count();
    println!(
        "{steps} steps from {}: {:.3} ms/step, {iterations:.1} iterations/step ({capped} of {} windows hold a step at the cap of {cap}), {contacts:.0} contacts, {:.2} ns per contact update (whole step); at the end sigma1 {:.3} MPa, {} force-carrying contacts, max overlap {:.2e} r_min",
        std::path::Path::new(&dir).display(),
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
