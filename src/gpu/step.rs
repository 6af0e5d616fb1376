//! Recording of the time steps on the device, phase by phase (the order of
//! `CpuEngine::step`), and the run loop, which waits for the device once per run of steps
//! (a window: one series row of the protocol).
//!
//! Each step is one command buffer, submitted without waiting:
//!
//! 1. clear, free velocities, grid, detection with the warm start, incidence lists,
//!    warm-start gather, coloring (one dispatch per round, as many rounds as the last steps
//!    needed plus a margin), then `solve_args`, which writes the dispatch arguments of the
//!    solve: one entry per color, so that each color's sweep covers its members although
//!    the host does not know the colors' sizes;
//! 2. the solver, in blocks of [`GpuBackend::conv_every`] iterations (one indirect dispatch
//!    per color, or three for Jacobi), each closed by `conv_check`, which decides on the
//!    device whether the solve has ended and then sets the solve's dispatch arguments to
//!    zero workgroups: blocks recorded past the end dispatch nothing. The host records as
//!    many blocks as the last steps needed, with a margin;
//! 3. local updates of deep contacts (two dispatches), integration, wall impulses, the
//!    impulses kept for the warm start, and a copy of the step's status words (contacts,
//!    colors, rounds, iterations, convergence, largest overlap) into a mapped history.
//!
//! The last step of a window also reduces counts, overlaps and energies and copies them with
//! the walls into the history; the host then maps it, its one wait of the window. Capacities
//! and recording margins are thus checked a window late: when a step overflowed a capacity,
//! needed more coloring rounds, colors or iterations than were recorded, the window's state,
//! copied on the device at its start, is put back and the window is run again with room
//! to spare, so that a redone step equals one run with room from the start.

use super::WG;
use super::backend::{GpuBackend, MARKS_PER_STEP};
use super::buffers::float_slot::{
    MICRO_COUNTS, MICRO_SUMS, RED_CONNECTED, RED_CONNECTED_ENERGY, RED_EDGE_COUNT, RED_EDGE_LEFT,
    RED_EDGE_RIGHT, RED_FREE, RED_KINETIC, RED_MICRO, RED_MICRO_SUMS, RED_OVERLAP_COUNT, RED_OVERLAP_MAX,
    RED_OVERLAP_SUM, RED_ROLLING, RED_SLIDING, RED_STRIP_N_LEFT, RED_STRIP_N_RIGHT, RED_STRIP_X_LEFT,
    RED_STRIP_X_RIGHT, RED_TRANSLATIONAL, RED_ZERO_FORCE,
};
use super::buffers::{
    ARGS_STRIDE, GRID_SLOT, GpuWall, SCAN_BLOCK, color_slot, conv_slot, disp, round_slot, status,
};
use super::pipeline::{Binds, Kernel};
use super::traffic::{self, Counts};
use crate::backend::{Loading, Reductions};
use crate::error::{Error, Result};
use crate::solver::{Method, SolverParams};

fn groups(n: u32) -> u32 {
    n.div_ceil(WG)
}

/// The most contacts for which iterations past the typical count are swept by one
/// workgroup (`sweep_all`): its 256 threads walk every contact, 128 passes here, where a
/// dispatch per color costs the device a few microseconds each (docs/gpu.md). Larger
/// samples sweep one workgroup only in the margin, past the last window's largest count:
/// there an iteration is rarely run, and recorded empty it costs one dispatch instead of
/// one per color.
pub const ONE_WORKGROUP_CONTACTS: u32 = 32_768;

/// Windows of at least this many steps are probed with one step when they are a fresh
/// backend's first ([`GpuBackend::probe`]).
const PROBE_FROM: u32 = 20;

/// The largest iterations per step of the last windows completed, as many as hold at least
/// [`super::backend::RECENT_STEPS`] steps.
#[derive(Clone, Debug, Default)]
pub(super) struct RecentPeaks {
    /// (steps, largest iterations per step) of each window kept, oldest first.
    windows: std::collections::VecDeque<(u32, u32)>,
}

impl RecentPeaks {
    /// Adds a completed window of `steps` steps whose largest count was `largest`, and
    /// forgets the oldest windows the others no longer need.
    pub(super) fn push(&mut self, steps: u32, largest: u32) {
        if steps == 0 {
            return;
        }
        self.windows.push_back((steps, largest));
        while self.windows.len() > 1
            && self.windows.iter().skip(1).map(|w| w.0).sum::<u32>() >= super::backend::RECENT_STEPS
        {
            self.windows.pop_front();
        }
    }

    /// Iterations to record per step for the next window: the largest count kept, a
    /// quarter more and a block of `every`.
    pub(super) fn to_record(&self, every: u32) -> u32 {
        let most = self.windows.iter().map(|w| w.1).max().unwrap_or(0);
        most + most / 4 + every
    }
}

/// Bytes of one step's row in the history: the status words.
const ROW_BYTES: u64 = 4 * status::WORDS as u64;

/// Where a window's results lie in its history buffer: the steps' rows, then the float
/// accumulators kept for the reductions, the walls, and the timed steps' timestamps.
#[derive(Clone, Copy, Debug)]
struct HistoryLayout {
    /// Steps of the window.
    steps: u32,
    /// Offset of the float accumulators (after the rows).
    final_at: u64,
    /// Bytes of the float accumulators.
    keep: u64,
    /// Bytes of the wall records.
    walls_bytes: u64,
    /// Steps timed (the first ones), four timestamps each.
    timed: u32,
    /// Offset of the timestamps (8-byte aligned).
    times_at: u64,
    /// Bytes of the whole history (a multiple of 8: the rows and records are whole words).
    end: u64,
}

/// A block of solver iterations closed by one convergence test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Block {
    /// Iterations of the step before the block.
    pub start: u32,
    /// Iterations in the block.
    pub len: u32,
    /// Whether its Gauss-Seidel sweeps are relaxed by `solver.gs_relax`.
    pub relaxed: bool,
    /// Whether the velocity test applies at its end.
    pub velocity_test: bool,
    /// The relaxation its change is divided by in the test.
    pub w: f32,
    /// Its argument slot among the convergence tests' (`conv_slot`).
    pub slot: u32,
}

/// The blocks of a step's solve up to the cap, for tests every `every` iterations: a block
/// ends where the relaxation changes (`gs_relax_after`) and at `max_iter`, as on the CPU,
/// whose tests fall at multiples of `check_every` too. Blocks with the same length, test
/// and relaxation share an argument slot: there are at most four kinds.
pub(super) fn schedule(p: &SolverParams, every: u32) -> Vec<Block> {
    let jacobi = p.method == Method::Jacobi;
    let every = every.max(1);
    let mut blocks: Vec<Block> = Vec::new();
    let mut kinds: Vec<(u32, bool, u32)> = Vec::new();
    let mut done = 0;
    while done < p.max_iter {
        // The next test falls at the next multiple of `every`, as on the CPU.
        let mut len = (every - done % every).min(p.max_iter - done);
        if done < p.gauss_seidel.relax_after {
            len = len.min(p.gauss_seidel.relax_after - done);
        }
        let relaxed = !jacobi && done + 1 > p.gauss_seidel.relax_after;
        let velocity_test = !jacobi && p.velocity_tol > 0.0 && done + len > p.gauss_seidel.relax_after;
        let w = if jacobi {
            p.jacobi.relax
        } else {
            p.relax_at(done + 1)
        } as f32;
        let kind = (len, velocity_test, w.to_bits());
        let slot = match kinds.iter().position(|k| *k == kind) {
            Some(k) => k,
            None => {
                kinds.push(kind);
                kinds.len() - 1
            }
        } as u32;
        blocks.push(Block {
            start: done,
            len,
            relaxed,
            velocity_test,
            w,
            slot,
        });
        done += len;
    }
    blocks
}

/// How many items a logged dispatch covers, for its traffic.
#[derive(Clone, Copy, Debug)]
enum Items {
    /// A count the host knows.
    N(u32),
    /// The step's contacts (indirect, known once the row is read).
    Contacts,
}

/// A dispatch recorded, for the counters: its kernel, its items and the block of the solve
/// it belongs to (it does work only if the block ran).
#[derive(Clone, Copy, Debug)]
struct Logged {
    kernel: Kernel,
    items: Items,
    block: Option<u32>,
}

/// What the host recorded for the steps of a window: the margins the device's counts are
/// checked against.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Recorded {
    /// Coloring rounds.
    pub rounds: u32,
    /// Colors swept per iteration.
    pub colors: u32,
    /// Blocks of the solve.
    pub blocks: u32,
    /// Of those, the first ones swept with a dispatch per color; the others (past what the
    /// last steps typically needed) with one `sweep_all` per iteration.
    pub full: u32,
}

/// A command encoder with an open compute pass, the shared bind groups set, and the log of
/// its dispatches.
struct Rec<'a> {
    enc: wgpu::CommandEncoder,
    pass: Option<wgpu::ComputePass<'static>>,
    b: &'a GpuBackend,
    log: Vec<Logged>,
    block: Option<u32>,
    /// The pipeline, argument slot and group 0's access bound in the open pass: a dispatch
    /// that needs the same ones sets none again (the host's recording sets the pace of small
    /// samples, docs/gpu.md, "Measured on hardware").
    bound: (Option<Kernel>, Option<u32>, Option<Binds>),
}

impl<'a> Rec<'a> {
    fn new(b: &'a GpuBackend) -> Self {
        Rec {
            enc: b.gpu.device.create_command_encoder(&Default::default()),
            pass: None,
            b,
            log: Vec::new(),
            block: None,
            bound: (None, None, None),
        }
    }

    fn pass(&mut self) -> &mut wgpu::ComputePass<'static> {
        self.pass.get_or_insert_with(|| {
            self.enc
                .begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("cdlab step"),
                    timestamp_writes: None,
                })
                .forget_lifetime()
        })
    }

    fn end_pass(&mut self) {
        self.pass = None;
        self.bound = (None, None, None);
    }

    /// Writes timestamp `index` of the step timestamps, if the device has them (an empty
    /// pass that writes at its start).
    fn mark(&mut self, index: Option<u32>) {
        let (Some(index), Some((set, _))) = (index, &self.b.timing) else {
            return;
        };
        self.end_pass();
        let _ = self.enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("cdlab timestamp"),
            timestamp_writes: Some(wgpu::ComputePassTimestampWrites {
                query_set: set,
                beginning_of_pass_write_index: Some(index),
                end_of_pass_write_index: None,
            }),
        });
    }

    /// The command buffer and the log of its dispatches.
    fn finish(mut self) -> (wgpu::CommandBuffer, Vec<Logged>) {
        self.end_pass();
        (self.enc.finish(), self.log)
    }

    /// Copies between buffers (outside any pass).
    fn copy(&mut self, src: &wgpu::Buffer, from: u64, dst: &wgpu::Buffer, to: u64, size: u64) {
        self.end_pass();
        self.enc.copy_buffer_to_buffer(src, from, dst, to, size);
    }

    fn bind_args(&mut self, kernel: Kernel, slot: u32) {
        let b = self.b;
        let (kernel_was, slot_was, access_was) = self.bound;
        let access = Binds::of_file(kernel.file());
        let pass = self.pass();
        if access_was != Some(access) {
            pass.set_bind_group(0, &b.bind.group0[access as usize], &[]);
        }
        if kernel_was != Some(kernel) {
            pass.set_pipeline(b.pipes.get(kernel));
        }
        if slot_was != Some(slot) {
            pass.set_bind_group(1, &b.bind.args, &[(slot as u64 * ARGS_STRIDE) as u32]);
        }
        self.bound = (Some(kernel), Some(slot), Some(access));
    }

    /// Dispatches `x` workgroups of `kernel` with argument slot `slot`, over `items` items
    /// (the count its per-item traffic is multiplied by, see [`super::traffic`]).
    fn go(&mut self, kernel: Kernel, slot: u32, x: u32, items: u32) {
        self.go_over(kernel, slot, x, Items::N(items));
    }

    /// The exclusive prefix sum of the `n` words of the region of argument slot `slot`, in
    /// place (shaders/scan.wgsl): a workgroup per block, one for the blocks' totals, a
    /// thread per word.
    fn scan(&mut self, slot: u32, n: u32) {
        let blocks = n.div_ceil(SCAN_BLOCK);
        self.go(Kernel::ScanBlocks, slot, blocks, n);
        self.go(Kernel::ScanSums, slot, 1, blocks);
        self.go(Kernel::ScanAdd, slot, blocks.max(1), n);
    }

    /// [`Rec::go`] over `items` of any kind.
    fn go_over(&mut self, kernel: Kernel, slot: u32, x: u32, items: Items) {
        if x == 0 {
            return;
        }
        self.bind_args(kernel, slot);
        self.pass().dispatch_workgroups(x, 1, 1);
        let block = self.block;
        self.log.push(Logged { kernel, items, block });
    }

    /// Dispatches `kernel` with the workgroups of entry `entry` of the dispatch arguments
    /// (indirect: the count is on the device), over `items`.
    fn go_indirect(&mut self, kernel: Kernel, slot: u32, entry: u32, items: Items) {
        self.bind_args(kernel, slot);
        let ind = &self.b.bufs.indirect;
        self.pass().dispatch_workgroups_indirect(ind, 12 * entry as u64);
        let block = self.block;
        self.log.push(Logged { kernel, items, block });
    }

    /// Copies the dispatch arguments the device wrote (entries `0..entries`) into the
    /// indirect buffer.
    fn publish_args(&mut self, entries: u32) {
        let b = self.b;
        self.copy(
            &b.bufs.ints,
            4 * b.sim.o_disp as u64,
            &b.bufs.indirect,
            0,
            12 * entries as u64,
        );
    }
}

/// One step's row of the history, as the device left it.
#[derive(Clone, Copy, Debug)]
struct Row {
    words: [u32; status::WORDS],
}

impl Row {
    fn get(&self, k: usize) -> u32 {
        self.words[k]
    }
}

/// Why a window is run again.
enum Redo {
    /// Capacities to grow to, and the margins to record with.
    Grow(super::buffers::Capacity, Recorded),
    /// Margins to record with.
    Record(Recorded),
}

impl GpuBackend {
    /// Runs `steps` steps under `loading` and returns the reductions.
    pub(super) fn run_steps(&mut self, steps: u32, loading: &Loading) -> Result<Reductions> {
        self.apply_loading(loading)?;
        self.refresh_schedule();
        if self.sim.deep_budget != self.deep_budget {
            self.sim.deep_budget = self.deep_budget;
            self.write_params();
        }
        if self.counters.windows == 0 && steps >= PROBE_FROM {
            self.probe(loading)?;
        }
        // A window run again has put its state back; the host's clock moves only when one
        // is taken.
        loop {
            if let Some(red) = self.window(steps, loading)? {
                return Ok(red);
            }
        }
    }

    /// A fresh backend's first long window starts with small capacities and margins, and
    /// each shortfall runs the whole window again (six times, 1200 steps, for the first 200
    /// steps of a 50,000-disk compaction on an H200: docs/gpu.md). One step run first finds
    /// them at the cost of a step; its state is then put back, so that the window starts from
    /// the same state with the room that step needed (the steps equal steps with room to
    /// spare, as any window run again). Counted as a window run again.
    fn probe(&mut self, loading: &Loading) -> Result<()> {
        let before = self.counters;
        let (time, step) = (self.scene.time, self.scene.step);
        while self.window(1, loading)?.is_none() {}
        self.restore()?;
        self.scene.time = time;
        self.scene.step = step;
        let c = &mut self.counters;
        c.steps = before.steps;
        c.iterations = before.iterations;
        c.color_rounds = before.color_rounds;
        c.redone += 1;
        c.redone_steps += 1;
        Ok(())
    }

    /// Takes a new loading: the wall forces alone are written into the wall records; new
    /// members of the same strips (a refresh) are written into the disk records' tags; a
    /// new set of strips (other walls or pressure, or strips put on or off) goes through
    /// the scene.
    fn apply_loading(&mut self, loading: &Loading) -> Result<()> {
        if *loading == self.loading {
            return Ok(());
        }
        let frame_same = loading.sigma3 == self.loading.sigma3
            && loading.top == self.loading.top
            && loading.bottom == self.loading.bottom;
        let members_new = loading.strip != self.loading.strip;
        let refresh = frame_same
            && members_new
            && !loading.strip.is_empty()
            && !self.loading.strip.is_empty()
            && loading.strip.len() == self.scene.disks.len();
        if !frame_same || (members_new && !refresh) {
            let mut scene = crate::backend::Backend::scene(self)?;
            self.loading = loading.clone();
            loading.apply_wall_forces(&mut scene);
            return crate::backend::Backend::set_scene(self, &scene);
        }
        if refresh {
            self.set_strips(&loading.strip)?;
        }
        self.loading = loading.clone();
        if refresh {
            // The strips' sums of radii, which share out their loads, follow the members.
            self.fill_params();
            self.write_params();
        }
        loading.apply_wall_forces(&mut self.scene);
        let at = std::mem::offset_of!(GpuWall, force) as u64;
        for &(w, _) in &loading.wall_forces {
            if let crate::model::WallDrive::Force { force, .. } = self.scene.walls[w].drive {
                let o = w as u64 * size_of::<GpuWall>() as u64 + at;
                self.gpu
                    .queue
                    .write_buffer(&self.bufs.walls, o, bytemuck::bytes_of(&(force as f32)));
            }
        }
        Ok(())
    }

    /// Writes new strip members into the disk records' tags, through the per-disk scratch
    /// (one word per disk up, no scene round trip).
    fn set_strips(&mut self, strip: &[i8]) -> Result<()> {
        let tags: Vec<u32> = strip.iter().map(|&t| t as i32 as u32).collect();
        let at = 4 * self.sim.o_per_disk as u64;
        self.gpu
            .queue
            .write_buffer(&self.bufs.ints, at, bytemuck::cast_slice(&tags));
        let mut r = Rec::new(self);
        let nd = self.sim.n_disks;
        r.go(Kernel::SetStrips, 0, groups(nd), nd);
        let (cmd, _) = r.finish();
        self.submit_now(cmd, "writing the strips' members")
    }

    /// The strips' members found on the device (shaders/reduce.wgsl, `free_outline` and
    /// `strip_classify`) and read back, one word per disk: what
    /// [`crate::backend::reduce::strip_members`] finds in the scene, but for a disk within
    /// the device's rounding of a strip's inner boundary. `None` when the walls asked for
    /// are not those of the loading in force (the device's heights come from those).
    pub(super) fn strip_members_on_device(
        &mut self,
        bottom: usize,
        top: usize,
        thickness: f64,
    ) -> Result<Option<Vec<i8>>> {
        let nd = self.sim.n_disks;
        let nw = self.sim.n_walls as usize;
        if nd == 0
            || bottom != self.sim.bottom as usize
            || top != self.sim.top as usize
            || bottom.max(top) >= nw
        {
            return Ok(None);
        }
        let slot = super::buffers::STRIP_SLOT as u64 * ARGS_STRIDE;
        let t = thickness as f32;
        self.gpu
            .queue
            .write_buffer(&self.bufs.args, slot, bytemuck::bytes_of(&t.to_bits()));
        let mut r = Rec::new(self);
        let bins = super::buffers::OUTLINE_BINS;
        let strip = super::buffers::STRIP_SLOT;
        r.go(Kernel::OutlineClear, 0, groups(bins), bins);
        r.go(Kernel::FreeOutline, 0, groups(nd), nd);
        r.go(Kernel::StripClassify, strip, groups(nd), nd);
        let (cmd, _) = r.finish();
        self.submit_now(cmd, "finding the strips' members")?;
        let ints = self.bufs.ints.clone();
        let bytes = self.download(&ints, 4 * self.sim.o_per_disk as u64, 4 * nd as u64)?;
        let words: &[u32] = bytemuck::cast_slice(&bytes);
        Ok(Some(
            words[..nd as usize].iter().map(|&w| w as i32 as i8).collect(),
        ))
    }

    /// Adds the work of a step's logged dispatches to the counters, from its row: the
    /// dispatches of blocks that ran do work, the others are empty launches.
    fn charge(&mut self, log: &[Logged], row: &Row, rec: Recorded) {
        let n = row.get(status::CONTACTS).min(self.cap.contacts);
        let iters = row.get(status::ITERS);
        let ran = |b: Option<u32>| b.is_none_or(|b| self.schedule[b as usize].start < iters);
        let walls = self.sim.n_walls as u64;
        let tail = row.get(status::TAIL);
        for l in log {
            let sweep_tail = l.kernel == Kernel::SweepTail;
            if !ran(l.block) || (sweep_tail && tail == 0) {
                self.counters.empty_dispatches += 1;
                continue;
            }
            self.counters.dispatches += 1;
            if sweep_tail || l.kernel == Kernel::SweepAll {
                // Its traffic is in the sweeps' below.
                self.counters.sweep_dispatches += 1;
                continue;
            }
            let items = match l.items {
                Items::N(k) => k,
                Items::Contacts => n,
            };
            let b = traffic::bytes(
                l.kernel,
                Counts {
                    items: items as u64,
                    contacts: n as u64,
                    walls,
                },
            );
            self.counters.bytes_read += b.read;
            self.counters.bytes_written += b.written;
        }
        // The sweeps: one dispatch per recorded large color per iteration run, of which
        // those of the step's large colors do work, and the small colors' one (logged);
        // together one pass over the contacts.
        if self.params.solver.method != Method::Jacobi && n > 0 {
            let nonempty = row.get(status::BIG).min(rec.colors) as u64;
            let full = &self.schedule[..rec.full.min(rec.blocks) as usize];
            let recorded: u64 = full.iter().map(|b| b.len as u64).sum();
            let run = iters as u64;
            // The iterations run with a dispatch per color (the others' sweep_all is logged).
            let run_full = run.min(recorded);
            self.counters.dispatches += nonempty * run_full;
            self.counters.sweep_dispatches += nonempty * run_full;
            self.counters.empty_dispatches += rec.colors as u64 * recorded - nonempty * run_full;
            let b = traffic::bytes(
                Kernel::SweepColor,
                Counts {
                    items: n as u64,
                    contacts: n as u64,
                    walls,
                },
            );
            self.counters.bytes_read += b.read * run;
            self.counters.bytes_written += b.written * run;
        }
    }

    /// Of `blocks` blocks, those swept with a dispatch per color: all of them with
    /// `overflow_sweeps` off; else those that cover the last window's mean iterations per
    /// step (at most [`GpuBackend::one_workgroup_contacts`] contacts) or its largest (more
    /// contacts), the rest with `sweep_all`.
    fn full_blocks(&self, blocks: u32) -> u32 {
        if !self.overflow_sweeps {
            return blocks;
        }
        let per_color = if self.n_contacts > self.one_workgroup_contacts {
            self.peak_iters
        } else {
            self.typical_iters
        };
        self.blocks_for(per_color).min(blocks)
    }

    /// The blocks recorded for a solve expected to take `iters` iterations.
    fn blocks_for(&self, iters: u32) -> u32 {
        let k = self.schedule.partition_point(|b| b.start < iters);
        (k as u32).max(1).min(self.schedule.len() as u32)
    }

    /// Runs one window of `steps` steps: `Ok(None)` when it must be run again (its state
    /// has been put back), else its reductions.
    fn window(&mut self, steps: u32, loading: &Loading) -> Result<Option<Reductions>> {
        let nw = self.scene.walls.len();
        if nw > 0 {
            self.gpu
                .queue
                .write_buffer(&self.bufs.floats, 4 * self.sim.f_wall as u64, &vec![0u8; 8 * nw]);
        }
        self.gpu
            .queue
            .write_buffer(&self.bufs.floats, 4 * self.sim.f_deep as u64, &[0u8; 8]);
        let blocks = self.blocks_for(self.iters_hint);
        let rec = Recorded {
            rounds: self.rounds_hint.clamp(1, self.cap.rounds),
            colors: self.colors_hint.min(self.cap.colors),
            blocks,
            full: self.full_blocks(blocks),
        };
        let at = self.history_layout(steps);
        if let Some(t) = self.window_end.take() {
            self.counters.between_ns += t.elapsed().as_nanos() as u64;
        }
        self.counters.windows += 1;
        let history = self.history(at.end);
        self.ensure_backup();
        let recording = std::time::Instant::now();
        let logs = self.record_window(rec, at, &history, loading)?;
        // One command buffer per step, and one for a run of no steps.
        self.counters.submissions += logs.len() as u64;
        self.counters.record_ns += recording.elapsed().as_nanos() as u64;
        let waiting = std::time::Instant::now();
        let bytes = self.map_read(&history, at.end)?;
        self.counters.wait_ns += waiting.elapsed().as_nanos() as u64;
        self.window_end = Some(std::time::Instant::now());
        if at.timed > 0 {
            let t: &[u64] = bytemuck::cast_slice(&bytes[at.times_at as usize..at.end as usize]);
            let period = self.gpu.queue.get_timestamp_period() as f64;
            let ns = |a: u64, b: u64| (b.saturating_sub(a) as f64 * period) as u64;
            for q in t.chunks_exact(MARKS_PER_STEP as usize) {
                let c = &mut self.counters;
                c.device_step_ns += ns(q[0], q[5]);
                c.device_detect_ns += ns(q[0], q[1]);
                c.device_color_ns += ns(q[1], q[2]);
                c.device_solve_ns += ns(q[2], q[3]);
                c.device_deep_ns += ns(q[3], q[4]);
                c.device_integrate_ns += ns(q[4], q[5]);
            }
            self.counters.timed_steps += at.timed as u64;
        }
        let rows: Vec<Row> = (0..steps as usize)
            .map(|s| {
                let mut words = [0u32; status::WORDS];
                words.copy_from_slice(bytemuck::cast_slice(
                    &bytes[s * ROW_BYTES as usize..(s + 1) * ROW_BYTES as usize],
                ));
                Row { words }
            })
            .collect();
        for (log, row) in logs.iter().zip(&rows) {
            self.charge(log, row, rec);
        }
        // The first step that needs more room decides: the steps after it ran from a
        // wrong state. A step in error before it ends the run.
        let mut redo = None;
        let mut red = Reductions::default();
        let mut colors = 0u64;
        for (s, row) in rows.iter().enumerate() {
            let step = self.scene.step + s as u64;
            if let Some(r) = self.needs_redo(row, rec) {
                redo = Some(r);
                break;
            }
            if row.get(status::BAD) != 0 {
                return Err(Error::Numerical {
                    step,
                    message: "non-finite impulses in the GPU solver".into(),
                });
            }
            let overlap = f32::from_bits(row.get(status::OVERLAP)) as f64;
            if overlap > self.params.overlap_limit {
                return Err(Error::Numerical {
                    step,
                    message: format!(
                        "overlap {overlap:.3e} m exceeds the limit {:.3e} m. {}",
                        self.params.overlap_limit,
                        crate::engine::overlap_advice(self.params.solver.max_iter)
                    ),
                });
            }
            let it = row.get(status::ITERS);
            red.steps += 1;
            red.iterations_sum += it as u64;
            red.iterations_max = red.iterations_max.max(it);
            red.capped_steps += (row.get(status::CONVERGED) == 0) as u32;
            colors += if self.params.solver.method == Method::Jacobi {
                0
            } else {
                row.get(status::NONEMPTY) as u64
            };
        }
        if let Some(redo) = redo {
            self.counters.redone += 1;
            self.counters.redone_steps += steps as u64;
            self.restore()?;
            let more = match redo {
                Redo::Grow(cap, more) => {
                    self.counters.redone_capacity += 1;
                    self.grow(cap)?;
                    more
                }
                Redo::Record(more) => more,
            };
            let c = &mut self.counters;
            c.redone_iterations += (more.blocks != rec.blocks) as u64;
            c.redone_colors += (more.colors != rec.colors) as u64;
            c.redone_rounds += (more.rounds != rec.rounds) as u64;
            self.rounds_hint = more.rounds;
            self.colors_hint = more.colors;
            let last = self.schedule[(more.blocks as usize).clamp(1, self.schedule.len()) - 1];
            self.iters_hint = last.start + last.len;
            return Ok(None);
        }
        let max = |k: usize| rows.iter().map(|r| r.get(k)).max().unwrap_or(0);
        // Margins for the next window: the counts these steps needed, and some room.
        let rounds = max(status::ROUNDS);
        self.rounds_hint = rounds + rounds / 4 + 4;
        // A dispatch costs about as much recorded empty as with work on a hardware GPU
        // (docs/gpu.md, "Measured on hardware"): margins are kept small, a window that
        // needs more is run again.
        let c = max(status::BIG);
        self.colors_hint = c + 1;
        let it = max(status::ITERS);
        self.recent.push(steps, it);
        self.iters_hint = self.recent.to_record(self.conv_every);
        self.peak_iters = it;
        self.typical_iters = red.iterations_sum.div_ceil(red.steps.max(1) as u64) as u32;
        self.counters.steps += steps as u64;
        self.counters.iterations += red.iterations_sum;
        self.counters.color_rounds += rows.iter().map(|r| r.get(status::ROUNDS) as u64).sum::<u64>();
        if let Some(r) = rows.last() {
            self.n_contacts = r.get(status::CONTACTS).min(self.cap.contacts);
        }
        self.scene.time += steps as f64 * self.params.dt;
        self.scene.step += steps as u64;
        red.colors_mean = colors as f64 / red.steps.max(1) as f64;
        let tail = &bytes[at.final_at as usize..];
        self.finish_reductions(red, loading, tail).map(Some)
    }

    /// The history's layout for a window of `steps` steps.
    fn history_layout(&self, steps: u32) -> HistoryLayout {
        let keep = 4 * self.bufs.layout.floats_keep as u64;
        let walls_bytes = (self.scene.walls.len() * size_of::<GpuWall>()) as u64;
        let final_at = steps as u64 * ROW_BYTES;
        let timed = if self.timing.is_some() {
            steps.min(super::backend::TIMED_STEPS)
        } else {
            0
        };
        let times_at = (final_at + keep + walls_bytes).next_multiple_of(8);
        HistoryLayout {
            steps,
            final_at,
            keep,
            walls_bytes,
            timed,
            times_at,
            end: times_at + 8 * (MARKS_PER_STEP * timed) as u64,
        }
    }

    /// Records the window's command buffers, one per step, and submits them in order; with
    /// several recording threads ([`GpuBackend::recording_threads`]) the steps are recorded
    /// side by side (each is its own encoder, and none depends on another's recording) and
    /// submitted as they come in order, so that the device starts on the first step while
    /// the later ones are still being recorded. Returns the dispatch logs of the command
    /// buffers submitted, in order.
    fn record_window(
        &self,
        rec: Recorded,
        at: HistoryLayout,
        history: &wgpu::Buffer,
        loading: &Loading,
    ) -> Result<Vec<Vec<Logged>>> {
        let HistoryLayout {
            steps,
            final_at,
            keep,
            walls_bytes,
            timed,
            times_at,
            ..
        } = at;
        let n = steps.max(1);
        // A run of no steps still reduces the state as it stands: one command buffer holding
        // the reductions alone.
        let record = |s: u32| -> (wgpu::CommandBuffer, Vec<Logged>) {
            let mut r = Rec::new(self);
            if s == 0 {
                for (live, backup, n) in self.backup_pairs() {
                    r.copy(&live, 0, &backup, 0, n);
                }
            }
            if s < steps {
                self.record_step(&mut r, rec, (s < timed).then_some(MARKS_PER_STEP * s));
                let st = 4 * self.sim.o_status as u64;
                r.copy(&self.bufs.ints, st, history, s as u64 * ROW_BYTES, ROW_BYTES);
            }
            if s + 1 >= steps {
                r.block = None;
                r.go(Kernel::ReduceFinal, 0, 1, self.sim.n_disks);
                if !loading.strip.is_empty() {
                    let (bins, nd) = (super::buffers::OUTLINE_BINS, self.sim.n_disks);
                    r.go(Kernel::OutlineClear, 0, groups(bins), bins);
                    r.go(Kernel::StripOutline, 0, groups(nd), nd);
                    r.go(Kernel::OutlineSum, 0, 1, bins);
                }
                r.copy(&self.bufs.floats, 0, history, final_at, keep);
                if walls_bytes > 0 {
                    r.copy(&self.bufs.walls, 0, history, final_at + keep, walls_bytes);
                }
                if let Some((set, resolve)) = &self.timing
                    && timed > 0
                {
                    r.end_pass();
                    let marks = MARKS_PER_STEP * timed;
                    r.enc.resolve_query_set(set, 0..marks, resolve, 0);
                    r.copy(resolve, 0, history, times_at, 8 * marks as u64);
                }
            }
            r.finish()
        };
        let mut logs = Vec::with_capacity(n as usize);
        let submit = |cmd: wgpu::CommandBuffer| -> Result<()> {
            self.gpu.queue.submit([cmd]);
            self.gpu.check("submitting the time step")
        };
        let threads = self.recording_threads().min(n);
        if threads <= 1 {
            for s in 0..n {
                let (cmd, log) = record(s);
                logs.push(log);
                submit(cmd)?;
            }
            return Ok(logs);
        }
        std::thread::scope(|scope| -> Result<()> {
            let (tx, rx) = std::sync::mpsc::channel();
            for t in 0..threads {
                let tx = tx.clone();
                let record = &record;
                scope.spawn(move || {
                    for s in (t..n).step_by(threads as usize) {
                        // The receiver is gone only after an error: stop recording.
                        if tx.send((s, record(s))).is_err() {
                            break;
                        }
                    }
                });
            }
            drop(tx);
            let mut waiting = std::collections::BTreeMap::new();
            for (s, out) in rx {
                waiting.insert(s, out);
                while let Some((cmd, log)) = waiting.remove(&(logs.len() as u32)) {
                    logs.push(log);
                    submit(cmd)?;
                }
            }
            Ok(())
        })?;
        Ok(logs)
    }

    /// What a step's row asks of the window: larger capacities, or more coloring rounds,
    /// colors or iterations recorded.
    fn needs_redo(&self, row: &Row, rec: Recorded) -> Option<Redo> {
        let mut cap = self.cap;
        let n = row.get(status::CONTACTS);
        if n > cap.contacts {
            cap.contacts = n + n / 4 + 64;
        }
        if row.get(status::SLOTS_NEED) > cap.k_slots {
            cap.k_slots = row.get(status::SLOTS_NEED) + 4;
        }
        let colors = row.get(status::COLORS);
        if colors > cap.colors {
            cap.colors = 2 * colors;
        }
        let big = row.get(status::BIG);
        let left = n <= cap.contacts && row.get(status::LEFT) > 0;
        let mut more = rec;
        if left {
            more.rounds = 2 * rec.rounds;
            cap.rounds = cap.rounds.max(more.rounds);
        }
        if big > rec.colors {
            more.colors = big + big / 4 + 2;
        }
        // Iterations ran out before a test or the cap ended the solve.
        if row.get(status::LIVE) != 0 {
            more.blocks = (2 * rec.blocks).min(self.schedule.len() as u32);
        }
        if cap != self.cap {
            return Some(Redo::Grow(cap, more));
        }
        (more != rec).then_some(Redo::Record(more))
    }

    /// Records one step into `r` with the margins `rec`, and its timestamps from index
    /// `times` on when given ([`MARKS_PER_STEP`]: start, detection end, solve start, solve
    /// end, deep updates end, end).
    fn record_step(&self, r: &mut Rec<'_>, rec: Recorded, times: Option<u32>) {
        let at = |k: u32| times.map(|t| t + k);
        r.mark(at(0));
        let nd = self.sim.n_disks;
        let nb = self.sim.n_bodies;
        let clear = self.bufs.layout.clear_len;
        r.block = None;
        r.go(Kernel::ClearInts, 0, groups(clear), clear);
        r.go(Kernel::FreeVelocity, 0, groups(nb), nb);
        let boxes = nd.div_ceil(SCAN_BLOCK);
        r.go(Kernel::GridPartial, GRID_SLOT, boxes, nd);
        r.go(Kernel::GridBounds, GRID_SLOT, 1, boxes);
        r.go(Kernel::GridCount, 0, groups(nd), nd);
        r.scan(1, self.sim.cap_cells);
        r.go(Kernel::GridScatter, 0, groups(nd), nd);
        r.go(Kernel::Detect, 0, groups(nd), nd);
        r.scan(2, nd);
        r.go(Kernel::ContactArgs, 0, 1, 1);
        let o = 4 * (self.sim.o_status as u64 + status::ARGS as u64);
        r.copy(
            &self.bufs.ints,
            o,
            &self.bufs.indirect,
            12 * disp::CONTACTS as u64,
            12,
        );
        let all = Items::Contacts;
        r.go(Kernel::BuildContacts, 0, groups(nd), nd);
        r.mark(at(1));
        r.go_indirect(Kernel::IncidenceCount, 0, disp::CONTACTS, all);
        r.scan(3, nb);
        r.go_indirect(Kernel::IncidenceFill, 0, disp::CONTACTS, all);
        r.go_indirect(Kernel::IncidenceRank, 0, disp::CONTACTS, all);
        r.go(Kernel::Gather, 0, groups(nb), nb);
        r.go_indirect(Kernel::ColorSeed, 0, disp::CONTACTS, all);
        for k in 1..=rec.rounds {
            r.go_indirect(Kernel::ColorRound, round_slot(self.cap, k), disp::CONTACTS, all);
        }
        r.go_indirect(Kernel::ColorCount, 0, disp::CONTACTS, all);
        r.go(Kernel::ColorOffsets, round_slot(self.cap, rec.rounds), 1, 1);
        r.go_indirect(Kernel::ColorScatter, 0, disp::CONTACTS, all);
        r.go(Kernel::SolveArgs, 0, 1, 1);
        let entries = disp::entries(rec.colors);
        r.publish_args(entries);
        r.mark(at(2));
        let jacobi = self.params.solver.method == Method::Jacobi;
        for (k, b) in self.schedule[..rec.blocks as usize].iter().enumerate() {
            r.block = Some(k as u32);
            for i in 0..b.len {
                if b.velocity_test && i + 1 == b.len {
                    r.go_indirect(Kernel::SaveIterate, 0, disp::LIVE_BODIES, Items::N(nb));
                }
                if jacobi {
                    r.go_indirect(Kernel::JacobiSolve, 0, disp::LIVE_CONTACTS, all);
                    r.go_indirect(Kernel::JacobiCommit, 0, disp::LIVE_CONTACTS, all);
                    r.go_indirect(Kernel::Gather, 0, disp::LIVE_BODIES, Items::N(nb));
                } else if k as u32 >= rec.full {
                    let slot = color_slot(self.cap, 0, b.relaxed);
                    r.go_indirect(Kernel::SweepAll, slot, disp::LIVE_ONE, all);
                } else {
                    for c in 0..rec.colors {
                        // Not logged: charge() counts the sweeps from the row.
                        r.bind_args(Kernel::SweepColor, color_slot(self.cap, c, b.relaxed));
                        let ind = &self.bufs.indirect;
                        r.pass()
                            .dispatch_workgroups_indirect(ind, 12 * (disp::COLOR0 + c) as u64);
                    }
                    // The small colors, in one workgroup (its slot's b: the relaxation).
                    let slot = color_slot(self.cap, 0, b.relaxed);
                    r.go_indirect(Kernel::SweepTail, slot, disp::LIVE_ONE, all);
                }
            }
            if b.velocity_test {
                r.go_indirect(Kernel::VelocityChange, 0, disp::LIVE_ONE, Items::N(nb));
            }
            r.go_over(Kernel::ConvCheck, conv_slot(self.cap, b.slot), 1, all);
            // The test's verdict, as dispatch arguments for the blocks after it.
            r.publish_args(entries);
        }
        r.block = None;
        r.mark(at(3));
        let p = self.params.solver;
        if p.deep_updates() {
            // Local updates of deep contacts: the selection, then every sweep over the
            // colors in one workgroup, so that the phase costs two dispatches whatever
            // deep_sweeps and the colors.
            r.go_indirect(Kernel::DeepMark, 0, disp::CONTACTS, all);
            r.go(Kernel::DeepUpdates, 0, 1, 1);
        }
        r.mark(at(4));
        r.go(Kernel::Integrate, 0, groups(nb), nb);
        let nw = self.sim.n_walls;
        r.go(Kernel::WallImpulse, 0, nw, nw);
        let save = self.cap.contacts.max(nd + 1);
        r.go(Kernel::SavePrev, 0, groups(save), nd + 1);
        r.mark(at(5));
    }

    /// The end-of-run reductions from the history's tail (the float accumulators, then the
    /// walls).
    fn finish_reductions(
        &mut self,
        mut red: Reductions,
        loading: &Loading,
        tail: &[u8],
    ) -> Result<Reductions> {
        let keep = self.bufs.layout.floats_keep as usize;
        let f: Vec<f32> = bytemuck::cast_slice(&tail[..4 * keep]).to_vec();
        let nw = self.scene.walls.len();
        if nw > 0 {
            let walls: Vec<GpuWall> =
                bytemuck::pod_collect_to_vec(&tail[4 * keep..4 * keep + nw * size_of::<GpuWall>()]);
            for (w, g) in walls.iter().enumerate() {
                self.scene.walls[w].point = super::backend::wall_point(g, self.centre);
            }
        }
        let dt = self.params.dt;
        let steps = red.steps.max(1) as f64;
        let fw = self.sim.f_wall as usize;
        red.wall_force = (0..nw)
            .map(|w| glam::DVec2::new(f[fw + 2 * w] as f64, f[fw + 2 * w + 1] as f64) / (steps * dt))
            .collect();
        red.wall_point = self.scene.walls.iter().map(|w| w.point).collect();
        red.time = self.scene.time;
        red.step = self.scene.step;
        red.candidates = self.n_contacts;
        let r = self.sim.f_red as usize;
        let u = |k: usize| f[r + k].to_bits();
        red.rolling = u(RED_ROLLING);
        red.sliding = u(RED_SLIDING);
        red.zero_force = u(RED_ZERO_FORCE);
        red.force_carrying = red.rolling + red.sliding;
        let (connected, free) = (u(RED_CONNECTED) as f64, u(RED_FREE) as f64);
        red.coordination = if connected > 0.0 {
            2.0 * red.force_carrying as f64 / connected
        } else {
            0.0
        };
        red.isolated_fraction = if free > 0.0 { 1.0 - connected / free } else { 0.0 };
        let n_ov = f[r + RED_OVERLAP_COUNT] as f64;
        red.overlap_mean = if n_ov > 0.0 {
            f[r + RED_OVERLAP_SUM] as f64 / n_ov
        } else {
            0.0
        };
        red.overlap_max = f[r + RED_OVERLAP_MAX] as f64;
        red.deep_sum = f[self.sim.f_deep as usize].to_bits() as u64;
        let cut = f[self.sim.f_deep as usize + 1].to_bits() as u64;
        if cut > 0 && self.counters.deep_sweeps_cut == 0 {
            // Once per backend, as the adapter warning of gpu::device::open.
            // A warning that cannot be shown (stderr closed or full) must not stop the work.
            use std::io::Write as _;
            let _ = writeln!(
                std::io::stderr(),
                "warning: the software GPU adapter's loop limit cut the local updates of deep \
                 contacts short ({cut} sweeps left out over the last {} steps); fewer deep \
                 contacts (a smaller time step) or solver.deep_sweeps below {} avoid it",
                red.steps,
                self.params.solver.deep_sweeps
            );
        }
        self.counters.deep_sweeps_cut += cut;
        red.kinetic_energy = f[r + RED_KINETIC] as f64;
        red.translational_energy = f[r + RED_TRANSLATIONAL] as f64;
        red.connected_energy = f[r + RED_CONNECTED_ENERGY] as f64;
        red.micro = micro_sums(&f[r + RED_MICRO..r + RED_MICRO_SUMS + MICRO_SUMS], dt);
        let has = |s: i8| loading.strip.contains(&s);
        // The outer edges from the outline the device sampled (reduce.wgsl, outline_sum).
        let m = u(RED_EDGE_COUNT) as f64;
        red.strip_edges = if !loading.strip.is_empty() && m > 0.0 {
            [RED_EDGE_LEFT, RED_EDGE_RIGHT].map(|k| f[r + k] as f64 / m + self.centre.x)
        } else {
            [f64::NAN; 2]
        };

        red.strip_mean_x = [
            (-1i8, RED_STRIP_X_LEFT, RED_STRIP_N_LEFT),
            (1, RED_STRIP_X_RIGHT, RED_STRIP_N_RIGHT),
        ]
        .map(|(s, sx, sc)| {
            if has(s) && f[r + sc] > 0.0 {
                f[r + sx] as f64 / f[r + sc] as f64 + self.centre.x
            } else {
                f64::NAN
            }
        });
        Ok(red)
    }
}

/// The micromechanical sums as `reduce_final` leaves them (reduce.wgsl, `micro_sums`):
/// counts as u32 bits, sums of impulses turned into forces with `dt`.
fn micro_sums(m: &[f32], dt: f64) -> crate::measure::micro::MicroSums {
    use crate::measure::micro::{MicroSums, ROSE_BINS, Sym2};
    let sym = |k: usize, scale: f64| Sym2 {
        xx: m[k] as f64 * scale,
        xy: m[k + 1] as f64 * scale,
        yy: m[k + 2] as f64 * scale,
    };
    let per_dt = 1.0 / dt;
    let mut rose = [0u32; ROSE_BINS];
    for (b, r) in rose.iter_mut().enumerate() {
        *r = m[2 + b].to_bits();
    }
    // The sums follow the counts, in the order micro_sums writes them.
    let k = MICRO_COUNTS;
    MicroSums {
        n_force: m[0].to_bits(),
        nn: sym(k, 1.0),
        f_n: m[k + 3] as f64 * per_dt,
        fnn: sym(k + 4, per_dt),
        ftn: sym(k + 7, per_dt),
        stress: sym(k + 10, per_dt),
        stress_dd: sym(k + 13, per_dt),
        n_strong: m[1].to_bits(),
        stress_strong: sym(k + 16, per_dt),
        rose,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(max_iter: u32, after: u32, velocity_tol: f64, method: Method) -> SolverParams {
        SolverParams {
            method,
            max_iter,
            gauss_seidel: crate::solver::GaussSeidelSettings {
                relax_after: after,
                ..SolverParams::default().gauss_seidel
            },
            velocity_tol,
            ..SolverParams::default()
        }
    }

    #[test]
    fn blocks_tile_the_iterations_and_end_where_the_cpu_tests() {
        let p = params(45, 10, 1e-5, Method::ColoredGs);
        let s = schedule(&p, 8);
        // Tests at multiples of 8, at the relaxation's change (10) and at the cap (45).
        let ends: Vec<u32> = s.iter().map(|b| b.start + b.len).collect();
        assert_eq!(ends, [8, 10, 16, 24, 32, 40, 45]);
        assert!(s.windows(2).all(|w| w[0].start + w[0].len == w[1].start));
        for b in &s {
            // Iteration b.start + 1 is relaxed past gs_relax_after, as relax_at says.
            assert_eq!(b.relaxed, b.start + 1 > 10);
            assert_eq!(b.w, p.relax_at(b.start + 1) as f32);
            assert_eq!(b.velocity_test, b.start + b.len > 10);
            assert!(b.slot < crate::gpu::buffers::CONV_SLOTS);
        }
        // Same length, test and relaxation: same slot.
        assert_eq!(s[3].slot, s[4].slot);
        assert_ne!(s[0].slot, s[3].slot);
    }

    #[test]
    fn jacobi_blocks_have_no_velocity_test_and_divide_by_its_relaxation() {
        let p = params(20, 0, 1e-5, Method::Jacobi);
        let s = schedule(&p, 6);
        assert_eq!(s.iter().map(|b| b.len).collect::<Vec<_>>(), [6, 6, 6, 2]);
        assert!(
            s.iter()
                .all(|b| !b.velocity_test && !b.relaxed && b.w == p.jacobi.relax as f32)
        );
    }

    #[test]
    fn the_margin_follows_the_largest_count_of_the_last_eighty_steps() {
        // Windows of 10 steps (a compression's rows): one window of a spike (96 iterations)
        // among windows of 24 sets the next eight windows' margin, then 24 does again.
        let mut recent = RecentPeaks::default();
        let largest = |k: usize| if k == 0 { 96 } else { 24 };
        let recorded: Vec<u32> = (0..16)
            .map(|k| {
                recent.push(10, largest(k));
                recent.to_record(8)
            })
            .collect();
        assert!(recorded[..8].iter().all(|&r| r == 96 + 24 + 8), "{recorded:?}");
        assert!(recorded[8..].iter().all(|&r| r == 24 + 6 + 8), "{recorded:?}");
        // Windows of 200 steps (a confinement's rows): each is enough alone.
        recent.push(200, 96);
        recent.push(200, 16);
        assert_eq!(recent.to_record(8), 16 + 4 + 8);
        // A run of no steps changes nothing.
        recent.push(0, 0);
        assert_eq!(recent.to_record(8), 16 + 4 + 8);
    }
}
