//! [`GpuBackend`]: the [`Backend`] the protocol drives, on a wgpu device. Upload and
//! download are plain copies of the Pod records; [`Backend::run`] records whole steps
//! (see `step.rs`) and reads back only the status words, the convergence norms every
//! `conv_every` iterations and the reductions at the end.

use glam::DVec2;

use super::buffers::{
    ARGS_STRIDE, Buffers, Capacity, GpuContact, GpuDisk, GpuWall, PREV_STRIDE, SimParams, args_slots,
    color_slot, conv_slot, round_slot,
};
use super::device::{GpuDevice, open};
use super::pipeline::Pipelines;
use super::step::{Block, schedule};
use crate::backend::reduce::{Reductions, zero_gap_tolerance};
use crate::backend::{Backend, ContactRecord, Loading};
use crate::contact::Contact;
use crate::engine::StepParams;
use crate::error::Result;
use crate::model::{BodyKind, Scene, WallDrive};
use crate::solver::Method;

/// Work counts of the GPU path since the backend was created (divide by `steps` for the
/// per-step figures).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct GpuCounters {
    /// Steps taken.
    pub steps: u64,
    /// Windows run again after a capacity grew or a margin was short (each repeats all
    /// the steps of its window).
    pub redone: u64,
    /// Windows run, those run again included.
    pub windows: u64,
    /// Steps run again (the steps of the windows run again).
    pub redone_steps: u64,
    /// Of the windows run again, those whose steps needed more solver iterations than were
    /// recorded (a window may count under several reasons).
    pub redone_iterations: u64,
    /// Those whose steps had more non-empty colors than were recorded.
    pub redone_colors: u64,
    /// Those whose coloring needed more rounds than were recorded.
    pub redone_rounds: u64,
    /// Those where a capacity (contacts, warm-start slots, colors) grew.
    pub redone_capacity: u64,
    /// Compute dispatches that did work: those of the fixed phases, and those of the
    /// solver's blocks that ran.
    pub dispatches: u64,
    /// Compute dispatches recorded that launched no workgroup: the blocks of the solve
    /// recorded past its end (the margin of [`GpuBackend::conv_every`] blocks), the colors
    /// recorded beyond those holding contacts.
    pub empty_dispatches: u64,
    /// Command buffers submitted.
    pub submissions: u64,
    /// Buffers mapped and waited for (status, convergence, reductions, downloads).
    pub readbacks: u64,
    /// Solver iterations.
    pub iterations: u64,
    /// Dispatches of Gauss-Seidel sweeps with work (counted in `dispatches` too): per
    /// iteration one per color of more than 64 contacts, and one for all the smaller
    /// colors together.
    pub sweep_dispatches: u64,
    /// Coloring rounds (Jones-Plassmann-Luby) of the steps taken.
    pub color_rounds: u64,
    /// Bytes the dispatches recorded load from device buffers, by the per-kernel table of
    /// [`super::traffic`] (its counting rules say what is left out).
    pub bytes_read: u64,
    /// Bytes the dispatches recorded store, as `bytes_read`.
    pub bytes_written: u64,
    /// Bytes copied to the host by the readbacks.
    pub readback_bytes: u64,
    /// Host time spent recording and submitting the steps' command buffers (ns): with the
    /// wall time per step, whether the host or the device sets the pace.
    pub record_ns: u64,
    /// Host time spent waiting for the device at the end of the windows (ns).
    pub wait_ns: u64,
    /// Host time between two windows, outside the backend: the protocol, the records, the
    /// downloads and uploads it asks for (ns). The device is idle then.
    pub between_ns: u64,
    /// Steps timed on the device (timestamps at their start and end, where the adapter has
    /// `TIMESTAMP_QUERY`; the first [`TIMED_STEPS`] of each window).
    pub timed_steps: u64,
    /// Device time of the timed steps, from their first dispatch to their last (ns).
    pub device_step_ns: u64,
    /// Device time of their solver iterations (ns).
    pub device_solve_ns: u64,
    /// Device time of their detection: grid, pairs, contact records, warm start (ns).
    pub device_detect_ns: u64,
    /// Device time of their coloring: incidence lists, warm-start gather, colors, the
    /// solve's dispatch arguments (ns).
    pub device_color_ns: u64,
    /// Device time of their local updates of deep contacts (ns).
    pub device_deep_ns: u64,
    /// Device time of their integration, wall impulses and warm-start records (ns).
    pub device_integrate_ns: u64,
    /// Sweeps of the local updates of deep contacts left out, summed over the steps, to
    /// keep the software adapter's loop limit (see [`DEEP_LOOP_BUDGET`]); 0 on a hardware
    /// GPU.
    pub deep_sweeps_cut: u64,
}

/// The most host threads [`GpuBackend::recording_threads`] chooses by itself: on an H200
/// two threads recorded a 5000-disk step in 4.2 ms against 7.7 ms for one, and four or
/// eight were no faster (docs/gpu.md, "Measured on hardware").
pub const RECORD_THREADS_MAX: u32 = 2;

/// Steps whose largest iterations set the iterations recorded for the next window: the
/// last windows that hold at least this many steps. The largest count of one 10-step window
/// (a compression's series row) is a poor guide to the next one's: in a 5000-disk
/// compression (24 iterations per step on average) one window in eight needed more than
/// the last window's largest with a quarter more and was run again, all its steps;
/// recording up to the largest of the last eight costs one empty dispatch per extra
/// iteration and left one in fifty, for a step 8% shorter on an H200 (docs/gpu.md, "The
/// iterations' margin, and `auto`'s threshold"). A confinement's 200-step window is guide
/// enough alone: holding its largest over more windows cost its steps 19% more there.
pub const RECENT_STEPS: u32 = 80;

/// Timestamps of a timed step: its start, the ends of detection, coloring, solve and deep
/// updates, and its end.
pub const MARKS_PER_STEP: u32 = 6;

/// Steps of a window timed on the device ([`MARKS_PER_STEP`] timestamps each; a query set
/// holds at most 4096).
pub const TIMED_STEPS: u32 = 640;

/// Loop iterations allowed to one invocation of the deep-contact kernel on a software
/// adapter (WGSL `deep_updates`): llvmpipe ends an invocation's loops after 65,535
/// iterations in all and goes on silently, so the kernel sweeps only as many times as fit
/// in this budget (with a margin for its own loop overhead) and counts what it left out.
pub const DEEP_LOOP_BUDGET: u32 = 60_000;

impl std::ops::Sub for GpuCounters {
    type Output = GpuCounters;
    /// The work counted between two readings of the counters (`later - earlier`).
    fn sub(self, earlier: GpuCounters) -> GpuCounters {
        GpuCounters {
            steps: self.steps - earlier.steps,
            redone: self.redone - earlier.redone,
            windows: self.windows - earlier.windows,
            redone_steps: self.redone_steps - earlier.redone_steps,
            redone_iterations: self.redone_iterations - earlier.redone_iterations,
            redone_colors: self.redone_colors - earlier.redone_colors,
            redone_rounds: self.redone_rounds - earlier.redone_rounds,
            redone_capacity: self.redone_capacity - earlier.redone_capacity,
            dispatches: self.dispatches - earlier.dispatches,
            empty_dispatches: self.empty_dispatches - earlier.empty_dispatches,
            submissions: self.submissions - earlier.submissions,
            readbacks: self.readbacks - earlier.readbacks,
            iterations: self.iterations - earlier.iterations,
            sweep_dispatches: self.sweep_dispatches - earlier.sweep_dispatches,
            color_rounds: self.color_rounds - earlier.color_rounds,
            bytes_read: self.bytes_read - earlier.bytes_read,
            bytes_written: self.bytes_written - earlier.bytes_written,
            readback_bytes: self.readback_bytes - earlier.readback_bytes,
            record_ns: self.record_ns - earlier.record_ns,
            wait_ns: self.wait_ns - earlier.wait_ns,
            between_ns: self.between_ns - earlier.between_ns,
            timed_steps: self.timed_steps - earlier.timed_steps,
            device_step_ns: self.device_step_ns - earlier.device_step_ns,
            device_solve_ns: self.device_solve_ns - earlier.device_solve_ns,
            device_detect_ns: self.device_detect_ns - earlier.device_detect_ns,
            device_color_ns: self.device_color_ns - earlier.device_color_ns,
            device_deep_ns: self.device_deep_ns - earlier.device_deep_ns,
            device_integrate_ns: self.device_integrate_ns - earlier.device_integrate_ns,
            deep_sweeps_cut: self.deep_sweeps_cut - earlier.deep_sweeps_cut,
        }
    }
}

/// Rejects the solver methods that have no GPU form (`Method::on_gpu`),
/// naming `solver.method`.
fn refuse_cpu_only(params: &StepParams) -> Result<()> {
    let m = params.solver.method;
    if !m.on_gpu() {
        return Err(crate::error::Error::invalid(
            "solver.method",
            m.name(),
            "the GPU backend runs colored-gs, gs or jacobi; this method runs with backend = \"cpu\"",
        ));
    }
    Ok(())
}

/// The GPU backend (f32 kernels, positions relative to the sample centre).
///
/// Differences from the CPU backend, by design: `Method::Gs` (sequential order) has no
/// parallel form and runs as colored Gauss-Seidel; the coloring is Jones-Plassmann-Luby
/// seeded with the last step's colors (persisting contacts keep theirs, so a color can
/// stay empty; empty colors cost no dispatch and are not counted);
/// convergence is checked every [`GpuBackend::conv_every`] iterations, so iteration counts
/// are multiples of it (set it to 1 for CPU-comparable counts); a capacity growth drops
/// nothing (the window of steps is redone from its start) and keeps the warm start.
pub struct GpuBackend {
    pub(super) gpu: GpuDevice,
    pub(super) pipes: Pipelines,
    pub(super) bufs: Buffers,
    pub(super) bind: super::pipeline::BindGroups,
    pub(super) sim: SimParams,
    pub(super) cap: Capacity,
    pub(super) params: StepParams,
    /// Host copy of the scene; positions and velocities are stale until [`Backend::scene`].
    pub(super) scene: Scene,
    /// The sample centre subtracted from every position on upload.
    pub(super) centre: DVec2,
    /// Iterations between two convergence tests on the device (`solver.check_every`, or
    /// [`crate::solver::GPU_CHECK_EVERY`] when it is 0); may be set between runs.
    pub conv_every: u32,
    /// Loop iterations allowed to one invocation of the deep-contact kernel, 0 for no
    /// limit: [`DEEP_LOOP_BUDGET`] on a software adapter, 0 on a hardware GPU. Read at the
    /// start of every run of steps.
    pub deep_budget: u32,
    pub(super) counters: GpuCounters,
    /// Host threads that record a window's steps, 0 for [`GpuBackend::recording_threads`]'s
    /// choice. Read at every window; the commands recorded are the same whatever it is.
    pub record_threads: u32,
    /// Contacts of the last step (from the history).
    pub(super) n_contacts: u32,
    pub(super) loading: Loading,
    /// Coloring rounds recorded per step: the last window's most with a margin (rounds
    /// beyond need cost an empty dispatch each; too few redo the window with twice as many).
    pub(super) rounds_hint: u32,
    /// Colors swept per iteration, as `rounds_hint`.
    pub(super) colors_hint: u32,
    /// Iterations recorded per step (in whole blocks): the largest count of the last
    /// [`RECENT_STEPS`] steps' windows (`recent`) with a margin.
    pub(super) iters_hint: u32,
    /// The largest iterations per step of the last windows completed.
    pub(super) recent: super::step::RecentPeaks,
    /// The last window's mean iterations per step, rounded up: the blocks that cover it
    /// are swept with a dispatch per color, those after with `sweep_all`.
    pub(super) typical_iters: u32,
    /// The last window's largest iterations per step: above
    /// [`GpuBackend::one_workgroup_contacts`] contacts, the blocks that cover it are swept
    /// with a dispatch per color, those of the margin after it with `sweep_all`.
    pub(super) peak_iters: u32,
    /// Whether iterations are swept by one workgroup each (`sweep_all`) past
    /// `typical_iters` (at most [`GpuBackend::one_workgroup_contacts`] contacts) or in the
    /// margin past `peak_iters` (more contacts); the results are the same either way.
    pub overflow_sweeps: bool,
    /// The most contacts for which iterations past the typical count are swept by one
    /// workgroup (32,768, `step::ONE_WORKGROUP_CONTACTS`, unless a test lowers it to try
    /// the rule of larger samples on a small one).
    pub one_workgroup_contacts: u32,
    /// The blocks of a solve (`step::schedule`) for the parameters and `conv_every` it
    /// was made for.
    pub(super) schedule: Vec<Block>,
    schedule_for: Option<(crate::solver::SolverParams, u32)>,
    /// The mapped buffer the steps' rows and the window's reductions are copied into.
    history: Option<wgpu::Buffer>,
    /// The state at the start of the window, to run it again.
    backup: Option<Vec<wgpu::Buffer>>,
    /// Timestamps of the steps (start, solve start, solve end, end) and the buffer they
    /// are resolved into, where the device writes them.
    pub(super) timing: Option<(wgpu::QuerySet, wgpu::Buffer)>,
    /// When the last window ended (for [`GpuCounters::between_ns`]).
    pub(super) window_end: Option<std::time::Instant>,
    /// The counters at the last [`Backend::activity`].
    activity_mark: GpuCounters,
}

impl GpuBackend {
    /// Opens the best adapter (see [`super::device::open`]) and uploads `scene`.
    pub fn new(scene: Scene, params: StepParams) -> Result<Self> {
        // Before opening a device: the method is wrong whatever the adapter.
        refuse_cpu_only(&params)?;
        Self::with_device(open()?, scene, params)
    }

    /// A backend on an already opened device.
    pub fn with_device(gpu: GpuDevice, scene: Scene, params: StepParams) -> Result<Self> {
        params.validate()?;
        refuse_cpu_only(&params)?;
        scene.validate()?;
        let pipes = Pipelines::new(&gpu)?;
        let cap = Capacity::initial(scene.disks.len(), scene.walls.len());
        let mut sim = SimParams::default();
        let bufs = Buffers::new(&gpu, &mut sim, cap)?;
        let bind = pipes.bind(&gpu.device, &bufs);
        let mut b = GpuBackend {
            gpu,
            pipes,
            bufs,
            bind,
            sim,
            cap,
            params,
            scene: Scene::default(),
            centre: DVec2::ZERO,
            conv_every: params.solver.check_interval(true),
            deep_budget: 0,
            counters: GpuCounters::default(),
            record_threads: 0,
            n_contacts: 0,
            loading: Loading::default(),
            rounds_hint: 16,
            colors_hint: 16,
            iters_hint: 64,
            recent: Default::default(),
            typical_iters: 64,
            peak_iters: 64,
            overflow_sweeps: true,
            one_workgroup_contacts: super::step::ONE_WORKGROUP_CONTACTS,
            schedule: Vec::new(),
            schedule_for: None,
            history: None,
            backup: None,
            timing: None,
            window_end: None,
            activity_mark: GpuCounters::default(),
        };
        if b.gpu.timestamps {
            let q = MARKS_PER_STEP * TIMED_STEPS;
            let set = b.gpu.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("step timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: q,
            });
            let resolve = b.gpu.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("step timestamps"),
                size: 8 * q as u64,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            b.timing = Some((set, resolve));
        }
        if b.gpu.info.device_type == wgpu::DeviceType::Cpu {
            b.deep_budget = DEEP_LOOP_BUDGET;
        }
        b.set_scene(&scene)?;
        Ok(b)
    }

    /// Records at least `iterations` solver iterations, `colors` colors and `rounds`
    /// coloring rounds per step in the next run of steps (afterwards the margins follow
    /// what the steps needed). A caller that knows its steps need more spares the window
    /// being run again; capacities still grow as the steps need.
    pub fn reserve(&mut self, iterations: u32, colors: u32, rounds: u32) {
        self.iters_hint = self.iters_hint.max(iterations);
        self.colors_hint = self.colors_hint.max(colors);
        self.rounds_hint = self.rounds_hint.max(rounds);
    }

    /// Host threads recording a window's steps: `record_threads` when set; else one on a
    /// software adapter (its device work runs on the same cores) and on a host of at most
    /// three cores, and otherwise the cores less two, up to [`RECORD_THREADS_MAX`]: on a
    /// hardware GPU the host's recording of dispatches sets the pace (docs/gpu.md,
    /// "Measured on hardware").
    pub fn recording_threads(&self) -> u32 {
        if self.record_threads > 0 {
            return self.record_threads;
        }
        if self.gpu.info.device_type == wgpu::DeviceType::Cpu {
            return 1;
        }
        let cores = crate::solver::cores() as u32;
        cores.saturating_sub(2).clamp(1, RECORD_THREADS_MAX)
    }

    /// Bytes allocated on the device for this sample.
    pub fn device_bytes(&self) -> u64 {
        self.bufs.device_bytes()
    }

    /// Work counts since the backend was created.
    pub fn counters(&self) -> GpuCounters {
        self.counters
    }

    /// Adapter name and type.
    pub fn adapter(&self) -> &wgpu::AdapterInfo {
        &self.gpu.info
    }

    /// Capacities in force (they grow when a step overflows them).
    pub fn capacity(&self) -> Capacity {
        self.cap
    }

    /// Fills the physics part of the uniform parameters from the scene, the step
    /// parameters and the loading.
    pub(super) fn fill_params(&mut self) {
        let (s, p, l) = (&self.scene, &self.params, &self.loading);
        let d = &s.disks;
        let sim = &mut self.sim;
        sim.n_disks = d.len() as u32;
        sim.n_walls = s.walls.len() as u32;
        sim.n_bodies = s.n_bodies() as u32;
        sim.dt = p.dt as f32;
        sim.theta = p.theta as f32;
        sim.alert = p.alert as f32;
        sim.relax = p.solver.jacobi.relax as f32;
        sim.jacobi = (p.solver.method == Method::Jacobi) as u32;
        sim.r_max = d.radius.iter().cloned().fold(0.0, f64::max) as f32;
        sim.r_min = d.radius.iter().cloned().fold(f64::INFINITY, f64::min) as f32;
        sim.gx = s.gravity.x as f32;
        sim.gy = s.gravity.y as f32;
        sim.mu_disk = s.material.mu_disk as f32;
        sim.mu_wall = s.material.mu_wall as f32;
        sim.e_n = s.material.e_n as f32;
        sim.e_t = s.material.e_t as f32;
        sim.gap_tol = zero_gap_tolerance(s) as f32;
        sim.deep_gap = p.solver.deep_gap as f32;
        sim.deep_sweeps = p.solver.deep_sweeps;
        sim.deep_budget = self.deep_budget;
        // The relaxed blocks' sweeps move by it (their argument slots say which are).
        sim.gs_relax = p.solver.gauss_seidel.relax as f32;
        sim.max_iter = p.solver.max_iter;
        sim.tol = p.solver.tol as f32;
        // Gauss-Seidel's only, as on the CPU.
        sim.velocity_tol = if p.solver.method == Method::Jacobi {
            0.0
        } else {
            p.solver.velocity_tol as f32
        };
        sim.one = 1.0;
        let strips = !l.strip.is_empty() && l.sigma3 != 0.0;
        sim.strips = strips as u32;
        sim.sigma3 = l.sigma3 as f32;
        sim.top = l.top as u32;
        sim.bottom = l.bottom as u32;
        let mut sum_r = [0.0f64; 2];
        for (k, &st) in l.strip.iter().enumerate() {
            if st != 0 {
                sum_r[(st > 0) as usize] += d.radius[k];
            }
        }
        sim.strip_sum_r0 = sum_r[0] as f32;
        sim.strip_sum_r1 = sum_r[1] as f32;
    }

    /// Writes the uniform parameters and the per-dispatch argument table.
    pub(super) fn write_params(&mut self) {
        let q = &self.gpu.queue;
        q.write_buffer(&self.bufs.sim, 0, bytemuck::bytes_of(&self.sim));
        let s = &self.sim;
        let mut table = vec![0u32; (args_slots(self.cap) as u64 * ARGS_STRIDE / 4) as usize];
        let mut put = |slot: u32, a: u32, b: u32, c: u32, d: u32| {
            let w = slot as usize * (ARGS_STRIDE / 4) as usize;
            table[w..w + 4].copy_from_slice(&[a, b, c, d]);
        };
        put(0, 0, self.bufs.layout.clear_len, 0, 0);
        // The prefix sums: the region, then its block totals (shaders/scan.wgsl).
        let sums = self.bufs.layout.scan_sums;
        let blocks = |n: u32| n.div_ceil(super::buffers::SCAN_BLOCK);
        put(1, s.o_cell_start, s.cap_cells, sums, blocks(s.cap_cells));
        put(2, s.o_dcount, s.n_disks, sums, blocks(s.n_disks));
        put(3, s.o_inc_count, s.n_bodies, sums, blocks(s.n_bodies));
        put(super::buffers::GRID_SLOT, sums, s.n_disks, 0, 0);
        for c in 0..self.cap.colors {
            put(color_slot(self.cap, c, false), c, 0, 0, 0);
            put(color_slot(self.cap, c, true), c, 1, 0, 0);
        }
        for r in 1..=self.cap.rounds {
            put(round_slot(self.cap, r), r, 0, 0, 0);
        }
        // Each kind of block's test: its iterations, its velocity test, its relaxation.
        for b in &self.schedule {
            put(
                conv_slot(self.cap, b.slot),
                b.len,
                b.velocity_test as u32,
                b.w.to_bits(),
                0,
            );
        }
        q.write_buffer(&self.bufs.args, 0, bytemuck::cast_slice(&table));
    }

    /// Reallocates the buffers for new capacities, keeping the state, the warm-start
    /// impulses and the run's accumulators (the growing regions come after them).
    pub(super) fn grow(&mut self, cap: Capacity) -> Result<()> {
        let mut sim = self.sim;
        let bufs = Buffers::new(&self.gpu, &mut sim, cap)?;
        let mut enc = self.gpu.device.create_command_encoder(&Default::default());
        let old = &self.bufs;
        for (a, b) in [
            (&old.disks, &bufs.disks),
            (&old.walls, &bufs.walls),
            (&old.vel, &bufs.vel),
            (&old.prev, &bufs.prev),
        ] {
            enc.copy_buffer_to_buffer(a, 0, b, 0, a.size().min(b.size()));
        }
        let keep = 4 * old.layout.floats_keep as u64;
        if keep > 0 {
            enc.copy_buffer_to_buffer(&old.floats, 0, &bufs.floats, 0, keep.next_multiple_of(4));
        }
        self.submit_now(enc.finish(), "copying the state into the grown buffers")?;
        self.bufs = bufs;
        self.sim = sim;
        self.cap = cap;
        self.bind = self.pipes.bind(&self.gpu.device, &self.bufs);
        self.write_params();
        Ok(())
    }

    /// Makes the blocks of the solve for the parameters and `conv_every` in force, and
    /// writes their tests' arguments, when either changed.
    pub(super) fn refresh_schedule(&mut self) {
        let key = (self.params.solver, self.conv_every.max(1));
        if self.schedule_for != Some(key) {
            self.schedule = schedule(&self.params.solver, key.1);
            self.schedule_for = Some(key);
            self.write_params();
        }
    }

    /// The history buffer, of at least `size` bytes (mapped for reading at a window's end).
    pub(super) fn history(&mut self, size: u64) -> wgpu::Buffer {
        let size = size.max(4).next_multiple_of(4);
        if let Some(h) = &self.history
            && h.size() >= size
        {
            return h.clone();
        }
        let h = self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("history"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        self.history = Some(h.clone());
        h
    }

    /// The buffers that hold the state between steps, with the bytes of each that do: the
    /// disks, walls, velocities, warm start and the float accumulators.
    fn state_buffers(&self) -> [(&wgpu::Buffer, u64); 5] {
        let b = &self.bufs;
        [
            (&b.disks, b.disks.size()),
            (&b.walls, b.walls.size()),
            (&b.vel, b.vel.size()),
            (&b.prev, b.prev.size()),
            (&b.floats, (4 * b.layout.floats_keep as u64).max(4)),
        ]
    }

    /// Allocates the copy of the state a window starts from, when its sizes changed.
    pub(super) fn ensure_backup(&mut self) {
        let sizes: Vec<u64> = self.state_buffers().iter().map(|(_, n)| *n).collect();
        if let Some(b) = &self.backup
            && b.iter().map(|x| x.size()).eq(sizes.iter().copied())
        {
            return;
        }
        let device = &self.gpu.device;
        self.backup = Some(
            sizes
                .iter()
                .map(|&size| {
                    device.create_buffer(&wgpu::BufferDescriptor {
                        label: Some("window start"),
                        size,
                        usage: wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
                        mapped_at_creation: false,
                    })
                })
                .collect(),
        );
    }

    /// The (live, backup, bytes) pairs of the state: copied one way at a window's start,
    /// the other way to run it again.
    pub(super) fn backup_pairs(&self) -> Vec<(wgpu::Buffer, wgpu::Buffer, u64)> {
        let backup = self.backup.as_ref().expect("ensure_backup before a window");
        self.state_buffers()
            .iter()
            .zip(backup)
            .map(|((live, n), b)| ((*live).clone(), b.clone(), (*n).min(b.size())))
            .collect()
    }

    /// Puts the state of the window's start back.
    pub(super) fn restore(&mut self) -> Result<()> {
        let mut enc = self.gpu.device.create_command_encoder(&Default::default());
        for (live, backup, n) in self.backup_pairs() {
            enc.copy_buffer_to_buffer(&backup, 0, &live, 0, n.min(live.size()));
        }
        self.submit_now(enc.finish(), "putting back the state of the window's start")
    }

    /// Submits one command buffer outside the windows' steps, counted, and turns a wgpu
    /// error it raised into one that says what was being done.
    pub(super) fn submit_now(&mut self, cmd: wgpu::CommandBuffer, what: &str) -> Result<()> {
        self.gpu.queue.submit([cmd]);
        self.counters.submissions += 1;
        self.gpu.check(what)
    }

    /// Copies `size` bytes of `src` from `offset` to the host (one map-and-wait).
    pub(super) fn download(&mut self, src: &wgpu::Buffer, offset: u64, size: u64) -> Result<Vec<u8>> {
        let size = size.max(4).next_multiple_of(4);
        let staging = self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut enc = self.gpu.device.create_command_encoder(&Default::default());
        enc.copy_buffer_to_buffer(src, offset, &staging, 0, size);
        self.gpu.queue.submit([enc.finish()]);
        self.counters.submissions += 1;
        self.map_read(&staging, size)
    }

    /// Maps the first `size` bytes of a readable buffer whose copies have been submitted,
    /// waits for the device, and returns them (one wait).
    pub(super) fn map_read(&mut self, buf: &wgpu::Buffer, size: u64) -> Result<Vec<u8>> {
        let (tx, rx) = std::sync::mpsc::channel();
        buf.map_async(wgpu::MapMode::Read, ..size, move |r| {
            let _ = tx.send(r);
        });
        let gpu = &self.gpu;
        gpu.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| gpu.failure("waiting for the device", e))?;
        // Errors of the work just waited for (validation, out of memory, device lost) come
        // first: they explain a failed mapping.
        gpu.check("running the time steps")?;
        rx.recv()
            .map_err(|e| gpu.failure("reading back a result", e))?
            .map_err(|e| gpu.failure("mapping a readback buffer", e))?;
        let bytes = buf
            .get_mapped_range(..size)
            .map_err(|e| gpu.failure("reading a mapped buffer", format!("{e:?}")))?
            .to_vec();
        buf.unmap();
        self.counters.readbacks += 1;
        self.counters.readback_bytes += size;
        Ok(bytes)
    }

    fn upload(&mut self) {
        let s = &self.scene;
        let d = &s.disks;
        let c = self.centre;
        let disks: Vec<GpuDisk> = (0..d.len())
            .map(|k| {
                let (x, x_lo) = split(d.pos[k].x - c.x);
                let (y, y_lo) = split(d.pos[k].y - c.y);
                GpuDisk {
                    x,
                    y,
                    theta: d.theta[k] as f32,
                    radius: d.radius[k] as f32,
                    inv_mass: d.inv_mass[k] as f32,
                    inv_inertia: d.inv_inertia[k] as f32,
                    mass: d.mass[k] as f32,
                    kind: d.kind[k] as u32,
                    glued: d.glued_to[k],
                    strip: self.loading.strip.get(k).copied().unwrap_or(0) as i32,
                    fx: d.force[k].x as f32,
                    fy: d.force[k].y as f32,
                    torque: d.torque[k] as f32,
                    x_lo,
                    y_lo,
                    pad: 0.0,
                }
            })
            .collect();
        let walls: Vec<GpuWall> = s.walls.iter().map(|w| gpu_wall(w, c)).collect();
        let nb = s.n_bodies();
        let mut vel = vec![[0.0f32; 4]; 4 * nb];
        for (k, v) in vel.iter_mut().take(d.len()).enumerate() {
            *v = [d.vel[k].x as f32, d.vel[k].y as f32, d.spin[k] as f32, 0.0];
        }
        for (w, wall) in s.walls.iter().enumerate() {
            vel[d.len() + w] = [wall.vel.x as f32, wall.vel.y as f32, 0.0, 0.0];
        }
        let q = &self.gpu.queue;
        q.write_buffer(&self.bufs.disks, 0, bytemuck::cast_slice(&disks));
        q.write_buffer(&self.bufs.walls, 0, bytemuck::cast_slice(&walls));
        q.write_buffer(&self.bufs.vel, 0, bytemuck::cast_slice(&vel));
    }

    /// The disks as the device holds them (f32 records, positions relative to the sample
    /// centre as two floats).
    #[doc(hidden)]
    pub fn raw_disks(&mut self) -> Result<Vec<GpuDisk>> {
        let n = self.sim.n_disks as u64;
        if n == 0 {
            return Ok(Vec::new());
        }
        let disks = self.bufs.disks.clone();
        let bytes = self.download(&disks, 0, n * size_of::<GpuDisk>() as u64)?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }

    /// The cell grid of the last step as the device built it (shaders/grid.wgsl): origin x
    /// and y relative to the sample centre, cell side (f32 bits), cells along x and y.
    #[doc(hidden)]
    pub fn raw_grid(&mut self) -> Result<[u32; 5]> {
        let floats = self.bufs.floats.clone();
        let at = 4 * (self.sim.f_grid as u64 + super::buffers::float_slot::GRID_ORIGIN_X as u64);
        let bytes = self.download(&floats, at, 4 * 5)?;
        let mut words = [0u32; 5];
        words.copy_from_slice(bytemuck::cast_slice(&bytes));
        Ok(words)
    }

    /// Contacts of the last step as f32 records (key order).
    pub fn raw_contacts(&mut self) -> Result<Vec<GpuContact>> {
        let n = self.n_contacts as u64;
        if n == 0 {
            return Ok(Vec::new());
        }
        let contacts = self.bufs.contacts.clone();
        let bytes = self.download(&contacts, 0, n * size_of::<GpuContact>() as u64)?;
        Ok(bytemuck::cast_slice(&bytes).to_vec())
    }
}

/// `v` as two floats `(hi, lo)`, hi the nearest f32 and lo the nearest f32 to the rest:
/// `hi + lo` keeps about 48 bits of `v`, a few 1e-12 m at 1000 m from the sample centre
/// (the shaders' two-float positions, common.wgsl).
fn split(v: f64) -> (f32, f32) {
    let hi = v as f32;
    (hi, (v - hi as f64) as f32)
}

/// The f64 value of the two floats `(hi, lo)`.
fn join(hi: f32, lo: f32) -> f64 {
    hi as f64 + lo as f64
}

/// The absolute position of a downloaded disk, its two-float position relative to `centre`
/// plus the centre.
pub(crate) fn disk_point(g: &GpuDisk, centre: DVec2) -> DVec2 {
    DVec2::new(join(g.x, g.x_lo), join(g.y, g.y_lo)) + centre
}

/// The absolute point of a downloaded wall, its two-float point relative to `centre` plus
/// the centre (the twin of [`gpu_wall`]'s split).
pub(crate) fn wall_point(g: &GpuWall, centre: DVec2) -> DVec2 {
    DVec2::new(join(g.px, g.px_lo), join(g.py, g.py_lo)) + centre
}

fn gpu_wall(w: &crate::model::Wall, c: DVec2) -> GpuWall {
    let (px, px_lo) = split(w.point.x - c.x);
    let (py, py_lo) = split(w.point.y - c.y);
    let (inv_mass, force, forced) = match w.drive {
        WallDrive::Kinematic => (0.0, 0.0, 0),
        WallDrive::Force { mass, force } => (1.0 / mass, force, 1),
    };
    GpuWall {
        nx: w.normal.x as f32,
        ny: w.normal.y as f32,
        px,
        py,
        inv_mass: inv_mass as f32,
        force: force as f32,
        is_active: w.active as u32,
        forced,
        px_lo,
        py_lo,
        pad: [0.0; 2],
    }
}

/// The crate's contact record of a downloaded f32 contact (for classification).
pub fn to_contact(g: &GpuContact) -> Contact {
    Contact {
        i: g.i,
        j: g.j,
        disk_j: g.disk_j,
        color: g.color,
        n: DVec2::new(g.nx as f64, g.ny as f64),
        gap: g.gap as f64,
        ri: g.ri as f64,
        rj: g.rj as f64,
        mi: g.mi as f64,
        mj: g.mj as f64,
        ma: g.ma as f64,
        a: DVec2::new(g.ax as f64, g.ay as f64),
        ki: g.ki as f64,
        kj: g.kj as f64,
        wnn: g.wnn as f64,
        wtt: g.wtt as f64,
        wnt: g.wnt as f64,
        mu: g.mu as f64,
        un0: g.un0 as f64,
        ut0: g.ut0 as f64,
        bias_n: g.bias_n as f64,
        bias_t: g.bias_t as f64,
        rn: g.rn as f64,
        rt: g.rt as f64,
    }
}

impl Backend for GpuBackend {
    fn name(&self) -> String {
        format!("gpu ({}, {:?})", self.gpu.info.name, self.gpu.info.backend)
    }

    fn strip_members(&mut self, bottom: usize, top: usize, thickness: f64) -> Result<Vec<i8>> {
        match self.strip_members_on_device(bottom, top, thickness)? {
            Some(members) => Ok(members),
            None => Ok(crate::backend::reduce::strip_members(
                &self.scene()?,
                bottom,
                top,
                thickness,
            )),
        }
    }

    fn params(&self) -> StepParams {
        self.params
    }

    fn set_params(&mut self, params: StepParams) -> Result<()> {
        params.validate()?;
        refuse_cpu_only(&params)?;
        if params.solver.check_every != self.params.solver.check_every {
            self.conv_every = params.solver.check_interval(true);
        }
        self.params = params;
        self.fill_params();
        self.write_params();
        Ok(())
    }

    fn set_scene(&mut self, scene: &Scene) -> Result<()> {
        scene.validate()?;
        let same = scene.disks.len() == self.scene.disks.len() && scene.walls.len() == self.scene.walls.len();
        self.scene = scene.clone();
        if !same {
            // New bodies: fresh buffers, and no warm start (the zeroed offsets of `prev`
            // give every disk an empty list of previous contacts).
            let d = &scene.disks;
            self.centre = if d.is_empty() {
                DVec2::ZERO
            } else {
                let lo = d.pos.iter().fold(DVec2::splat(f64::INFINITY), |a, p| a.min(*p));
                let hi = d
                    .pos
                    .iter()
                    .fold(DVec2::splat(f64::NEG_INFINITY), |a, p| a.max(*p));
                0.5 * (lo + hi)
            };
            self.fill_params();
            let cap = Capacity::initial(d.len(), scene.walls.len());
            let mut sim = self.sim;
            self.bufs = Buffers::new(&self.gpu, &mut sim, cap)?;
            self.sim = sim;
            self.cap = cap;
            self.bind = self.pipes.bind(&self.gpu.device, &self.bufs);
            self.n_contacts = 0;
        }
        self.fill_params();
        self.write_params();
        self.upload();
        Ok(())
    }

    fn scene(&mut self) -> Result<Scene> {
        let nd = self.scene.disks.len();
        let nw = self.scene.walls.len();
        let (disks_buf, walls_buf, vel_buf) = (
            self.bufs.disks.clone(),
            self.bufs.walls.clone(),
            self.bufs.vel.clone(),
        );
        let disks: Vec<GpuDisk> = if nd > 0 {
            bytemuck::cast_slice(&self.download(&disks_buf, 0, (nd * size_of::<GpuDisk>()) as u64)?).to_vec()
        } else {
            Vec::new()
        };
        let walls: Vec<GpuWall> = if nw > 0 {
            bytemuck::cast_slice(&self.download(&walls_buf, 0, (nw * size_of::<GpuWall>()) as u64)?).to_vec()
        } else {
            Vec::new()
        };
        let vel: Vec<[f32; 4]> =
            bytemuck::cast_slice(&self.download(&vel_buf, 0, ((nd + nw) * 16) as u64)?).to_vec();
        let c = self.centre;
        let s = &mut self.scene;
        for (k, g) in disks.iter().enumerate() {
            s.disks.pos[k] = disk_point(g, c);
            s.disks.theta[k] = g.theta as f64;
            s.disks.force[k] = DVec2::new(g.fx as f64, g.fy as f64);
            if s.disks.kind[k] != BodyKind::Fixed {
                s.disks.vel[k] = DVec2::new(vel[k][0] as f64, vel[k][1] as f64);
                s.disks.spin[k] = vel[k][2] as f64;
            }
        }
        for (w, g) in walls.iter().enumerate() {
            s.walls[w].point = wall_point(g, c);
            s.walls[w].vel = DVec2::new(vel[nd + w][0] as f64, vel[nd + w][1] as f64);
        }
        Ok(self.scene.clone())
    }

    fn contacts(&mut self) -> Result<Vec<ContactRecord>> {
        let dt = self.params.dt;
        let gap_tol = zero_gap_tolerance(&self.scene);
        Ok(self
            .raw_contacts()?
            .iter()
            .map(|g| ContactRecord::new(&to_contact(g), dt, gap_tol))
            .collect())
    }

    fn set_warm_start(&mut self, contacts: &[ContactRecord]) -> Result<()> {
        // The next step's detection reads the warm start from `prev`, the layout save_prev
        // writes (shaders/detect.wgsl): per disk, the range of its records, then one
        // record per contact (partner, R_n bits, R_t bits, color seed), by owner and
        // partner. The records' owner is the CPU's, which is the GPU's rule too; a record
        // the detection does not own is skipped by its walk, and that contact starts from
        // zero. A resume from zero impulses would jolt a loaded packing (CHANGELOG.md).
        let nd = self.scene.disks.len();
        let partners = (nd + self.scene.walls.len()) as u32;
        let mut recs: Vec<&ContactRecord> = contacts
            .iter()
            .filter(|c| (c.i as usize) < nd && c.j < partners && c.rn.is_finite() && c.rt.is_finite())
            .collect();
        recs.sort_by_key(|c| (c.i, c.j));
        if recs.len() > self.cap.contacts as usize {
            let cap = Capacity {
                contacts: (recs.len() + recs.len() / 4) as u32,
                ..self.cap
            };
            self.grow(cap)?;
        }
        let mut words = vec![0u32; nd + 1 + PREV_STRIDE as usize * recs.len()];
        for c in &recs {
            words[c.i as usize + 1] += 1;
        }
        for k in 0..nd {
            words[k + 1] += words[k];
        }
        for (k, c) in recs.iter().enumerate() {
            let at = nd + 1 + PREV_STRIDE as usize * k;
            words[at] = c.j;
            words[at + 1] = (c.rn as f32).to_bits();
            words[at + 2] = (c.rt as f32).to_bits();
            // No color: the coloring treats the contact as new.
            words[at + 3] = u32::MAX;
        }
        self.gpu
            .queue
            .write_buffer(&self.bufs.prev, 0, bytemuck::cast_slice(&words));
        Ok(())
    }

    fn run(&mut self, steps: u32, loading: &Loading) -> Result<Reductions> {
        self.run_steps(steps, loading)
    }

    fn activity(&mut self) -> Option<String> {
        let c = self.counters - self.activity_mark;
        self.activity_mark = self.counters;
        Some(c.describe())
    }
}

impl GpuCounters {
    /// One line for the user: per step, the host's recording, its waiting and its time
    /// outside the backend, the device's time where timed, and the windows run again.
    pub fn describe(&self) -> String {
        let steps = self.steps.max(1) as f64;
        let ms = |ns: u64| ns as f64 / 1e6 / steps;
        let device = if self.timed_steps > 0 {
            let t = |ns: u64| ns as f64 / 1e6 / self.timed_steps as f64;
            format!(
                "{:.3} ms/step (detection {:.3}, coloring {:.3}, solve {:.3}, deep updates \
                 {:.3}, integration {:.3} ms/step)",
                t(self.device_step_ns),
                t(self.device_detect_ns),
                t(self.device_color_ns),
                t(self.device_solve_ns),
                t(self.device_deep_ns),
                t(self.device_integrate_ns)
            )
        } else {
            "not timed".into()
        };
        format!(
            "GPU {} steps in {} windows, {} run again ({} steps; for iterations {}, colors {}, \
             rounds {}, capacities {}); host recording {:.3} ms/step, \
             waiting {:.3} ms/step, between windows {:.3} ms/step; device {device}; {:.1} \
             iterations/step, {:.0} dispatches/step ({:.0} empty)",
            self.steps,
            self.windows,
            self.redone,
            self.redone_steps,
            self.redone_iterations,
            self.redone_colors,
            self.redone_rounds,
            self.redone_capacity,
            ms(self.record_ns),
            ms(self.wait_ns),
            ms(self.between_ns),
            self.iterations as f64 / steps,
            (self.dispatches + self.empty_dispatches) as f64 / steps,
            self.empty_dispatches as f64 / steps,
        )
    }
}
