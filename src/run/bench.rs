//! The cost of a step (`cdlab bench`): a confined dense sample under shear stepped on one
//! backend, timed per step and per contact update, with the GPU's dispatches, submissions
//! and readbacks per step and the memory used. Timings are measured here, never asserted:
//! `cdlab bench` prints and writes them.

use std::time::Instant;

use glam::DVec2;

use crate::backend::{Backend, CpuBackend, Loading};
use crate::engine::StepParams;
use crate::error::Result;
use crate::gpu::backend::GpuBackend;
use crate::model::{Scene, WallDrive};
use crate::protocol::{prepare, walls};

/// The device's time per step outside the solve, by phase (ms).
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct DevicePhases {
    /// Grid, pair detection, contact records and warm start.
    pub detection: f64,
    /// Incidence lists, warm-start gather, colors and the solve's dispatch arguments.
    pub coloring: f64,
    /// Local updates of deep contacts.
    pub deep_updates: f64,
    /// Integration, wall impulses and the records kept for the next warm start.
    pub integration: f64,
}

/// One measured case (`bench.json`).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Case {
    /// Backend and adapter.
    pub backend: String,
    /// Disks.
    pub disks: usize,
    /// Candidate contacts at the end.
    pub contacts: u32,
    /// Mean solver iterations per step.
    pub iterations_per_step: f64,
    /// Wall time per step (ms).
    pub ms_per_step: f64,
    /// Wall time per contact update (ns): time / (contacts x iterations), counting every
    /// candidate, the open ones the CPU sweeps leave out (`solver.open_skip_gap`) included.
    pub ns_per_contact_update: f64,
    /// Mean colors per step.
    pub colors_per_step: f64,
    /// GPU: coloring rounds per step (0 when every contact kept its last color).
    pub color_rounds_per_step: f64,
    /// GPU: steps redone after a capacity grew or the coloring needed more rounds.
    pub redone_steps: u64,
    /// Steps per window: the steps run between two waits for the device (a series row of
    /// a test).
    pub window: u32,
    /// Iterations between two convergence tests (`solver.check_every` as the backend
    /// applies it).
    pub check_every: u32,
    /// GPU: host threads that recorded the windows (0 on the CPU).
    pub record_threads: u32,
    /// GPU: whether iterations past the typical count (up to 32,768 contacts) or in the
    /// recording margin (more contacts) were swept by one workgroup.
    pub sweep_all: bool,
    /// GPU: dispatches with work, submissions and readbacks per step (0 on the CPU).
    pub dispatches_per_step: f64,
    /// GPU: dispatches recorded per step that launched no workgroup (the solver's blocks
    /// past convergence, colors recorded beyond those holding contacts).
    pub empty_dispatches_per_step: f64,
    /// See `dispatches_per_step`.
    pub submissions_per_step: f64,
    /// See `dispatches_per_step`.
    pub readbacks_per_step: f64,
    /// GPU: blocking waits for the device per window (0 on the CPU).
    pub readbacks_per_window: f64,
    /// GPU: host time recording and submitting the steps, per step (ms; 0 on the CPU).
    pub host_record_ms_per_step: f64,
    /// GPU: device time per step from its first dispatch to its last (ms), where the
    /// adapter has timestamps; none on the CPU or without them.
    pub device_ms_per_step: Option<f64>,
    /// GPU: device time of the solver iterations per step (ms), as `device_ms_per_step`.
    pub device_solve_ms_per_step: Option<f64>,
    /// GPU: device time of the other phases per step (ms), as `device_ms_per_step`:
    /// detection, coloring, local updates of deep contacts, integration. With the solve
    /// they add up to the step.
    pub device_phases_ms_per_step: Option<DevicePhases>,
    /// Solver method.
    pub method: String,
    /// GPU: dispatches per step beyond one per color per solver iteration and one
    /// convergence reduction per check (the fixed phases of a step); constant across sizes
    /// and iteration counts when each iteration costs one dispatch per color.
    pub fixed_dispatches_per_step: f64,
    /// GPU: bytes the dispatches read and write per step (MB), by the per-kernel table of
    /// `gpu::traffic` (0 on the CPU).
    pub traffic_mb_per_step: f64,
    /// Peak resident memory of the process so far (MiB, VmHWM).
    pub host_peak_mib: f64,
    /// Device buffers (MiB; 0 on the CPU).
    pub device_mib: f64,
    /// CPU: where a step's time went, per step ([`CpuPhases`]); none on the GPU.
    pub cpu_phases: Option<CpuPhases>,
    /// Round of the measurement (1 to `cdlab bench --rounds`): each round measures every
    /// case again in the same order, so that sizes are compared within a round, on the
    /// machine as it was then.
    pub round: u32,
    /// The machine as [`super::machine::probe`] found it before the case's round (`cdlab
    /// bench` probes it once per round); none where nothing probed it.
    pub machine: Option<super::machine::Machine>,
}

/// Wall time of a CPU step's phases, per measured step (ms), from
/// [`crate::engine::PhaseTimes`].
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct CpuPhases {
    /// Contact detection (pair list and records).
    pub detect_ms: f64,
    /// Velocities, law offsets, warm start, overlap check.
    pub contacts_ms: f64,
    /// Solver setup: rows, parking, coloring, order, packing.
    pub setup_ms: f64,
    /// Solver iterations.
    pub sweeps_ms: f64,
    /// Deep contacts.
    pub deep_ms: f64,
    /// Impulses written back.
    pub store_ms: f64,
    /// Integration, warm-start list, wall impulses.
    pub integrate_ms: f64,
    /// Everything but the sweeps: the step's fixed part.
    pub fixed_ms: f64,
    /// The fixed part per disk (ns): flat when it scales linearly with the sample.
    pub fixed_ns_per_disk: f64,
}

impl CpuPhases {
    /// The phases of `t` per step, for a sample of `disks` disks.
    pub fn of(t: &crate::engine::PhaseTimes, disks: usize) -> CpuPhases {
        let per = |s: f64| s * 1e3 / t.steps.max(1) as f64;
        CpuPhases {
            detect_ms: per(t.detect),
            contacts_ms: per(t.contacts),
            setup_ms: per(t.setup),
            sweeps_ms: per(t.sweeps),
            deep_ms: per(t.deep),
            store_ms: per(t.store),
            integrate_ms: per(t.integrate),
            fixed_ms: per(t.fixed()),
            fixed_ns_per_disk: per(t.fixed()) * 1e6 / disks.max(1) as f64,
        }
    }
}

/// A confined dense sample under shear: the deposit of `n` disks, walls closed, the top
/// wall moving down at 0.5 m/s, friction 0.3, no gravity.
pub fn sheared_sample(n: usize) -> Result<Scene> {
    let (mut s, _) = prepare::deposit_scene(&crate::config::Config::with_disks(n).protocol())?;
    s.material.mu_disk = 0.3;
    s.material.mu_wall = 0.3;
    s.walls[walls::RIGHT].drive = WallDrive::Kinematic;
    s.walls[walls::TOP].vel = DVec2::new(0.0, -0.5);
    Ok(s)
}

fn host_peak_mib() -> f64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|t| t.lines().find(|l| l.starts_with("VmHWM:")).map(str::to_string))
        .and_then(|l| l.split_whitespace().nth(1).and_then(|v| v.parse::<f64>().ok()))
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

/// GPU counters and device memory of a backend, when it has them.
struct Probe<B> {
    counters: fn(&B) -> Option<crate::gpu::backend::GpuCounters>,
    device_mib: fn(&B) -> f64,
    check_every: fn(&B) -> u32,
    record_threads: fn(&B) -> u32,
    phases: fn(&B) -> Option<crate::engine::PhaseTimes>,
}

/// The steps of a window of `window` steps: `steps` steps in windows of `window`, as a test
/// runs them between its series rows.
fn windows(steps: u32, window: u32) -> impl Iterator<Item = u32> {
    let w = window.max(1);
    (0..steps.div_ceil(w)).map(move |k| w.min(steps - k * w))
}

/// Runs `steps` steps in windows of `window` and sums their reductions' step counts,
/// iterations and colors.
fn run_windows<B: Backend>(backend: &mut B, steps: u32, window: u32) -> Result<(u64, u64, f64, u32)> {
    let (mut n, mut it, mut colors, mut candidates) = (0u64, 0u64, 0.0, 0);
    for w in windows(steps, window) {
        let red = backend.run(w, &Loading::default())?;
        n += red.steps as u64;
        it += red.iterations_sum;
        colors += red.colors_mean * red.steps as f64;
        candidates = red.candidates;
    }
    Ok((n, it, colors / n.max(1) as f64, candidates))
}

fn measure<B: Backend>(backend: &mut B, probe: &Probe<B>, n: usize, run: Run) -> Result<Case> {
    run_windows(backend, run.warmup, run.window)?;
    let before = (probe.counters)(backend);
    let phases_before = (probe.phases)(backend);
    let t0 = Instant::now();
    let (done, iterations_sum, colors_mean, candidates) = run_windows(backend, run.steps, run.window)?;
    let secs = t0.elapsed().as_secs_f64();
    let after = (probe.counters)(backend);
    let cpu_phases = match (phases_before, (probe.phases)(backend)) {
        (Some(a), Some(b)) => Some(CpuPhases::of(&b.since(&a), n)),
        _ => None,
    };
    let every = (probe.check_every)(backend);
    let record_threads = (probe.record_threads)(backend);
    let steps = done.max(1) as f64;
    let n_windows = windows(run.steps, run.window).count().max(1) as f64;
    let iterations = iterations_sum as f64 / steps;
    let mut device = (None, None, None);
    let (rounds, redone, traffic, dispatches, empty, submissions, readbacks, fixed, record) =
        match (before, after) {
            (Some(a), Some(b)) => {
                let k = b - a;
                if k.timed_steps > 0 {
                    let per = |ns: u64| ns as f64 / 1e6 / k.timed_steps as f64;
                    let phases = DevicePhases {
                        detection: per(k.device_detect_ns),
                        coloring: per(k.device_color_ns),
                        deep_updates: per(k.device_deep_ns),
                        integration: per(k.device_integrate_ns),
                    };
                    device = (
                        Some(per(k.device_step_ns)),
                        Some(per(k.device_solve_ns)),
                        Some(phases),
                    );
                }
                let d = k.dispatches as f64 / steps;
                // Less the sweeps (counted by the backend: one per large color and one for
                // the small ones per iteration, or Jacobi's three) and one convergence test
                // every `every` iterations, what remains per step is a constant set of fixed
                // dispatches, whatever the sample size.
                let it = k.iterations as f64 / steps;
                let sweeps = if k.sweep_dispatches > 0 {
                    k.sweep_dispatches as f64 / steps
                } else {
                    colors_mean * it
                };
                let solver = sweeps + it / every.max(1) as f64;
                (
                    k.color_rounds as f64 / steps,
                    k.redone,
                    (k.bytes_read + k.bytes_written) as f64 / steps / 1e6,
                    d,
                    k.empty_dispatches as f64 / steps,
                    k.submissions as f64 / steps,
                    k.readbacks as f64,
                    d - solver,
                    k.record_ns as f64 / 1e6 / steps,
                )
            }
            _ => (0.0, 0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
        };
    Ok(Case {
        backend: backend.name(),
        disks: n,
        contacts: candidates,
        iterations_per_step: iterations,
        ms_per_step: secs / steps * 1e3,
        ns_per_contact_update: secs * 1e9 / (iterations_sum.max(1) as f64 * candidates.max(1) as f64),
        colors_per_step: colors_mean,
        color_rounds_per_step: rounds,
        redone_steps: redone,
        window: run.window,
        check_every: every,
        dispatches_per_step: dispatches,
        empty_dispatches_per_step: empty,
        submissions_per_step: submissions,
        readbacks_per_step: readbacks / steps,
        readbacks_per_window: readbacks / n_windows,
        host_record_ms_per_step: record,
        record_threads,
        sweep_all: run.sweep_all,
        device_ms_per_step: device.0,
        device_solve_ms_per_step: device.1,
        device_phases_ms_per_step: device.2,
        method: backend.params().solver.method.name().to_string(),
        fixed_dispatches_per_step: fixed,
        traffic_mb_per_step: traffic,
        host_peak_mib: host_peak_mib(),
        device_mib: (probe.device_mib)(backend),
        cpu_phases,
        round: 1,
        machine: None,
    })
}

/// How a case is run: `warmup` steps (warm start, buffer growth), then `steps` timed
/// ones, in windows of `window` steps (the series interval of a test).
#[derive(Clone, Copy, Debug)]
pub struct Run {
    /// Steps before the timed ones.
    pub warmup: u32,
    /// Timed steps.
    pub steps: u32,
    /// Steps per window.
    pub window: u32,
    /// GPU: host threads recording a window (`GpuBackend::record_threads`, 0 for its
    /// choice).
    pub record_threads: u32,
    /// GPU: `GpuBackend::overflow_sweeps`.
    pub sweep_all: bool,
}

/// Measures the CPU backend on `scene` as `run` says; `n` is the sample's size as reported.
pub fn measure_cpu(scene: Scene, params: StepParams, n: usize, run: Run) -> Result<Case> {
    let probe = Probe {
        counters: |_: &CpuBackend| None,
        device_mib: |_: &CpuBackend| 0.0,
        check_every: |c: &CpuBackend| c.params().solver.check_interval(false),
        record_threads: |_: &CpuBackend| 0,
        phases: |c: &CpuBackend| Some(c.engine().phase_times()),
    };
    measure(&mut CpuBackend::new(scene, params)?, &probe, n, run)
}

/// Measures the GPU backend as [`measure_cpu`] does the CPU's. `Err(Error::Gpu(GpuError::NoAdapter))`
/// when the machine has no adapter (a caller may skip), any other error when opening it
/// or stepping fails.
///
/// [`Error::NoAdapter`]: crate::error::GpuError::NoAdapter
pub fn measure_gpu(scene: Scene, params: StepParams, n: usize, run: Run) -> Result<Case> {
    let probe = Probe {
        counters: |g: &GpuBackend| Some(g.counters()),
        device_mib: |g: &GpuBackend| g.device_bytes() as f64 / (1024.0 * 1024.0),
        check_every: |g: &GpuBackend| g.conv_every,
        record_threads: |g: &GpuBackend| g.recording_threads(),
        phases: |_: &GpuBackend| None,
    };
    let mut g = GpuBackend::new(scene, params)?;
    g.record_threads = run.record_threads;
    g.overflow_sweeps = run.sweep_all;
    measure(&mut g, &probe, n, run)
}
