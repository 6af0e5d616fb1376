//! Device-side records and buffers.
//!
//! The records are `#[repr(C)]` bytemuck `Pod` structs in f32 with the exact field order of
//! the WGSL structs in `shaders/common.wgsl`, so upload and readback are plain copies.
//! Positions are relative to the sample centre (see [`crate::model`]) and stored as two
//! floats, `hi + lo` (see [`GpuDisk`]). Integer and float
//! scratch live in two buffers cut into regions ([`Layout`]); capacities that can overflow
//! (contact slots per disk, contacts, colors) are checked by the kernels, reported in the
//! status words, and grown by the host, which then redoes the step.

use bytemuck::{Pod, Zeroable};

use super::device::GpuDevice;
use crate::error::{Error, Result};

/// A disk (64 bytes).
///
/// Its position relative to the sample centre is `x + x_lo`, `y + y_lo`: two floats
/// (double-single), because a single f32 far from the centre rounds away the few
/// micrometres a disk moves per step (about 7.6e-6 m of spacing at 107 m, where the paper's
/// 5000-disk sample has its walls). `x`, `y` alone are the position to f32 precision.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
#[allow(missing_docs)]
pub struct GpuDisk {
    pub x: f32,
    pub y: f32,
    pub theta: f32,
    pub radius: f32,
    pub inv_mass: f32,
    pub inv_inertia: f32,
    pub mass: f32,
    pub kind: u32,
    pub glued: u32,
    pub strip: i32,
    pub fx: f32,
    pub fy: f32,
    pub torque: f32,
    pub x_lo: f32,
    pub y_lo: f32,
    pub pad: f32,
}

/// A plane wall (48 bytes); its velocity is in the velocity buffer. Its point relative to
/// the sample centre is `px + px_lo`, `py + py_lo`, two floats as for [`GpuDisk`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
#[allow(missing_docs)]
pub struct GpuWall {
    pub nx: f32,
    pub ny: f32,
    pub px: f32,
    pub py: f32,
    pub inv_mass: f32,
    pub force: f32,
    pub is_active: u32,
    pub forced: u32,
    pub px_lo: f32,
    pub py_lo: f32,
    pub pad: [f32; 2],
}

/// A contact (112 bytes), the f32 twin of [`crate::contact::Contact`].
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
#[allow(missing_docs)]
pub struct GpuContact {
    pub i: u32,
    pub j: u32,
    pub disk_j: u32,
    pub color: u32,
    pub nx: f32,
    pub ny: f32,
    pub gap: f32,
    pub ri: f32,
    pub rj: f32,
    pub mi: f32,
    pub mj: f32,
    pub ma: f32,
    pub ax: f32,
    pub ay: f32,
    pub ki: f32,
    pub kj: f32,
    pub wnn: f32,
    pub wtt: f32,
    pub wnt: f32,
    pub mu: f32,
    pub un0: f32,
    pub ut0: f32,
    pub bias_n: f32,
    pub bias_t: f32,
    pub rn: f32,
    pub rt: f32,
    /// 1 while the contact is given local updates after the iterations (WGSL `deep_mark`).
    pub deep: u32,
    pub pad: f32,
}

/// The uniform parameters of the kernels (WGSL `Sim`): sizes, region offsets, physics.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
#[allow(missing_docs)]
pub struct SimParams {
    pub n_disks: u32,
    pub n_walls: u32,
    pub n_bodies: u32,
    pub k_slots: u32,
    pub cap_contacts: u32,
    pub cap_cells: u32,
    pub max_colors: u32,
    pub strips: u32,
    pub top: u32,
    pub bottom: u32,
    pub o_cell_start: u32,
    pub o_cell_fill: u32,
    pub o_items: u32,
    pub o_cell_of: u32,
    pub o_dcount: u32,
    pub o_slots: u32,
    pub o_inc_count: u32,
    pub o_inc_fill: u32,
    pub o_inc_list: u32,
    pub o_status: u32,
    pub o_color_count: u32,
    pub o_color_fill: u32,
    pub o_order: u32,
    pub o_per_disk: u32,
    pub f_d2: u32,
    pub f_r2: u32,
    pub f_fresh: u32,
    pub f_wall: u32,
    pub f_red: u32,
    pub f_grid: u32,
    pub f_conv: u32,
    pub jacobi: u32,
    pub dt: f32,
    pub theta: f32,
    pub alert: f32,
    pub r_max: f32,
    pub gx: f32,
    pub gy: f32,
    pub mu_disk: f32,
    pub mu_wall: f32,
    pub e_n: f32,
    pub e_t: f32,
    pub sigma3: f32,
    pub relax: f32,
    pub strip_sum_r0: f32,
    pub strip_sum_r1: f32,
    pub gap_tol: f32,
    /// Gauss-Seidel relaxation of the iterations being recorded (written per batch).
    pub gs_relax: f32,
    pub o_color: u32,
    pub o_left: u32,
    pub max_rounds: u32,
    pub o_inc_tmp: u32,
    /// Contacts given local updates, then the sweeps of them left out to keep within
    /// `deep_budget`, each summed over the steps since the last reduction (u32 bits).
    pub f_deep: u32,
    /// Overlap beyond which a loaded contact gets local updates (m; 0: none).
    pub deep_gap: f32,
    /// Local updates of each deep contact per step (solve.wgsl, `deep_updates`).
    pub deep_sweeps: u32,
    /// Loop iterations one invocation of `deep_updates` may run (0: no limit): the
    /// software adapter ends an invocation's loops after 65,535 iterations in all, so on it
    /// the sweeps are cut to fit and the cut is counted.
    pub deep_budget: u32,
    /// Offset of the dispatch arguments the device writes for the solver's indirect
    /// dispatches (`disp::*` entries of 3 words, copied into the indirect buffer).
    pub o_disp: u32,
    /// Iteration cap of a step (the device ends the solver loop at it).
    pub max_iter: u32,
    /// Tolerance of the relative change of the impulses (`solver.tol`).
    pub tol: f32,
    /// Velocity test (m/s; 0: off), as `SolverParams::velocity_tol`.
    pub velocity_tol: f32,
    /// Smallest disk radius (m): the strips' outline is sampled every `r_min / 2`.
    pub r_min: f32,
    /// Offset of the strips' outline: [`OUTLINE_BINS`] words of the left outline, then as
    /// many of the right one (order-preserving bits of f32, reduce.wgsl `strip_outline`).
    pub o_outline: u32,
    /// 1.0, read from memory: a factor the shader compilers cannot see through, which keeps
    /// them from simplifying the rounding errors of the two-float positions to zero
    /// (common.wgsl, `two_sum`).
    pub one: f32,
    /// Offset of the colors in the order the solver sweeps them (`cap.colors` words): the
    /// colors with more than [`super::WG`] contacts first, each swept by a dispatch of its
    /// own, then the smaller ones, swept together by one workgroup (solve.wgsl `solve_args`,
    /// sweep.wgsl `sweep_tail`).
    pub o_color_map: u32,
}

/// Heights at which the strips' outline is sampled, at most (the CPU's
/// `backend::reduce::strip_outer_edges` clamps its count to the same).
pub const OUTLINE_BINS: u32 = 65_536;

/// The per-dispatch arguments (WGSL `Args`, 16 bytes), one per [`ARGS_STRIDE`] slot of the
/// argument table: the region a scan works on, the color a sweep updates.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
#[allow(missing_docs)]
pub struct GpuArgs {
    pub a: u32,
    pub b: u32,
    pub c: u32,
    pub d: u32,
}

/// Words per contact in the warm-start records of `prev`: partner, R_n bits, R_t bits,
/// color (WGSL `PREV_STRIDE`, checked against this constant).
pub const PREV_STRIDE: u32 = 4;

/// Status words read back after detection and coloring (indices into the status region;
/// the shaders' `ST_*` constants are checked against these, see [`super::wgsl_constants`]).
pub mod status {
    /// Contacts found (may exceed the capacity).
    pub const CONTACTS: usize = 0;
    /// Largest per-disk partner count (may exceed the slots).
    pub const SLOTS_NEED: usize = 1;
    /// Colors used.
    pub const COLORS: usize = 3;
    /// Largest overlap, f32 bits.
    pub const OVERLAP: usize = 4;
    /// Coloring rounds.
    pub const ROUNDS: usize = 5;
    /// Contacts left uncolored after the recorded coloring rounds.
    pub const LEFT: usize = 7;
    /// Contacts marked for local updates this step.
    pub const DEEP: usize = 11;
    /// Indirect dispatch size of per-contact kernels (3 words).
    pub const ARGS: usize = 8;
    /// Colors holding contacts (`solve_args`).
    pub const NONEMPTY: usize = 2;
    /// Colors with more than `WG` contacts, each swept by a dispatch of its own
    /// (`solve_args`); the others are swept together by `sweep_tail`.
    pub const BIG: usize = 16;
    /// Colors swept by `sweep_tail`.
    pub const TAIL: usize = 17;
    /// Non-finite convergence sums met (solve.wgsl `conv_check`; 1 ends the step's solve).
    pub const BAD: usize = 6;
    /// Solver iterations run this step (`conv_check`).
    pub const ITERS: usize = 12;
    /// 1 when the step's solve met its tolerance or velocity test.
    pub const CONVERGED: usize = 13;
    /// Relative change of the last test, f32 bits.
    pub const RESIDUAL: usize = 14;
    /// 1 while the solve goes on: still 1 at the end of a step whose recorded iterations
    /// ran out before a test or the cap ended it (the host redoes the window).
    pub const LIVE: usize = 15;
    /// Words of the status region; also the words of a step's row in the history.
    pub const WORDS: usize = 20;
}

/// Entries (3 words each: workgroups x, y, z) of the dispatch arguments that `solve_args`
/// writes after the coloring and `conv_check` zeroes once the solve has ended, so that the
/// iterations recorded past convergence dispatch no workgroup.
pub mod disp {
    /// Per-contact kernels (the contacts that fit), for the whole step.
    pub const CONTACTS: u32 = 0;
    /// Per-contact kernels of the solve (Jacobi): zero once the solve ended.
    pub const LIVE_CONTACTS: u32 = 1;
    /// Per-body kernels of the solve (Jacobi's gather, the velocity test's copy).
    pub const LIVE_BODIES: u32 = 2;
    /// One workgroup while the solve goes on (the velocity test's reduction).
    pub const LIVE_ONE: u32 = 3;
    /// Color `c` of a Gauss-Seidel sweep is entry `COLOR0 + c`.
    pub const COLOR0: u32 = 4;
    /// Entries for `colors` colors.
    pub fn entries(colors: u32) -> u32 {
        COLOR0 + colors
    }
}

/// Slots of the float regions that survive a growth (`floats[f_red ..]`, `floats[f_grid ..]`,
/// `floats[f_conv ..]`), written by the shaders and read back by the host (the shaders'
/// `FR_*`, `FG_*` and `FC_*` constants are checked against these, see
/// [`super::wgsl_constants`]).
pub mod float_slot {
    /// `reduce_final`'s mean normal impulse of the contacts (the force-carrying threshold).
    pub const RED_MEAN_RN: usize = 0;
    /// Rolling contacts (u32 bits).
    pub const RED_ROLLING: usize = 1;
    /// Sliding contacts (u32 bits).
    pub const RED_SLIDING: usize = 2;
    /// Zero-force contacts (u32 bits).
    pub const RED_ZERO_FORCE: usize = 3;
    /// Free disks with two or more force-carrying contacts (u32 bits).
    pub const RED_CONNECTED: usize = 4;
    /// Free disks (u32 bits).
    pub const RED_FREE: usize = 5;
    /// Contacts that overlap.
    pub const RED_OVERLAP_COUNT: usize = 6;
    /// Sum of their overlaps relative to r_min.
    pub const RED_OVERLAP_SUM: usize = 7;
    /// Largest overlap relative to r_min.
    pub const RED_OVERLAP_MAX: usize = 8;
    /// Kinetic energy of the free disks (J/m).
    pub const RED_KINETIC: usize = 9;
    /// Sum of x of the left strip's disks (centred frame).
    pub const RED_STRIP_X_LEFT: usize = 10;
    /// Sum of x of the right strip's disks (centred frame).
    pub const RED_STRIP_X_RIGHT: usize = 11;
    /// Disks of the left strip.
    pub const RED_STRIP_N_LEFT: usize = 12;
    /// Disks of the right strip.
    pub const RED_STRIP_N_RIGHT: usize = 13;
    /// Translational kinetic energy of the free disks (J/m).
    pub const RED_TRANSLATIONAL: usize = 14;
    /// Translational kinetic energy of the connected disks (J/m).
    pub const RED_CONNECTED_ENERGY: usize = 15;
    /// The micromechanical counts (force-carrying, strong, then the orientation bins,
    /// u32 bits; reduce.wgsl `micro_sums`).
    pub const RED_MICRO: usize = 16;
    /// The micromechanical counts: force-carrying, strong, and 18 orientation bins.
    pub const MICRO_COUNTS: usize = 20;
    /// The micromechanical sums (19 values) after the counts.
    pub const RED_MICRO_SUMS: usize = RED_MICRO + MICRO_COUNTS;
    /// Values of the micromechanical sums.
    pub const MICRO_SUMS: usize = 19;
    /// Sum of the left strip's outline over the heights where both outlines are set
    /// (centred frame; reduce.wgsl `outline_sum`).
    pub const RED_EDGE_LEFT: usize = 56;
    /// Sum of the right strip's outline, as `RED_EDGE_LEFT`.
    pub const RED_EDGE_RIGHT: usize = 57;
    /// Heights where both outlines are set (u32 bits).
    pub const RED_EDGE_COUNT: usize = 58;
    /// Words of the `f_red` region.
    pub const RED_WORDS: usize = 60;
    /// The grid's origin x (m, centred frame).
    pub const GRID_ORIGIN_X: usize = 0;
    /// The grid's origin y.
    pub const GRID_ORIGIN_Y: usize = 1;
    /// The grid's cell size (m).
    pub const GRID_CELL: usize = 2;
    /// Cells along x (u32 bits).
    pub const GRID_NX: usize = 3;
    /// Cells along y (u32 bits).
    pub const GRID_NY: usize = 4;
    /// Words of the `f_grid` region.
    pub const GRID_WORDS: usize = 8;
    /// Sum of the squared impulse changes of the last iteration.
    pub const CONV_D2: usize = 0;
    /// Sum of the squared impulses.
    pub const CONV_R2: usize = 1;
    /// Largest change of a body's velocity since the saved iterate (m/s).
    pub const CONV_DV: usize = 2;
    /// Words of the `f_conv` region.
    pub const CONV_WORDS: usize = 4;
}

/// Stride of the per-dispatch argument table (the largest dynamic-offset alignment any
/// adapter asks for).
pub const ARGS_STRIDE: u64 = 256;

/// Capacities of the buffers that can overflow.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Capacity {
    /// Contact slots per disk.
    pub k_slots: u32,
    /// Contacts.
    pub contacts: u32,
    /// Grid cells.
    pub cells: u32,
    /// Colors.
    pub colors: u32,
    /// Coloring rounds that can be recorded in one step (one argument slot and one
    /// counter each).
    pub rounds: u32,
}

impl Capacity {
    /// Starting capacities for `nd` disks: 12 slots (a dense packing of similar disks owns
    /// about 3-4 pairs per disk), 4 contacts per disk, as many cells as the CPU grid allows.
    pub fn initial(nd: usize, nw: usize) -> Self {
        Capacity {
            k_slots: 12,
            contacts: (4 * nd + nw * 16 + 256) as u32,
            cells: (4 * nd + 1024) as u32,
            colors: 64,
            rounds: 32,
        }
    }
}

/// Region offsets (in words) of the scratch buffers, and their sizes.
#[derive(Clone, Copy, Debug, Default)]
pub struct Layout {
    /// Words of `ints`.
    pub ints_len: u32,
    /// Words of `ints` cleared at the start of each step (from 0).
    pub clear_len: u32,
    /// Words of `floats`.
    pub floats_len: u32,
    /// Words of `floats` that survive a growth (wall accumulator, reductions, grid, conv).
    pub floats_keep: u32,
    /// Words of `prev`.
    pub prev_len: u32,
    /// Offset in `ints` of the block totals of the prefix sums (shaders/scan.wgsl): one
    /// word per [`SCAN_BLOCK`] words of the largest region scanned, and its total. The
    /// grid's partial bounds (four words per [`SCAN_BLOCK`] disks, shaders/grid.wgsl) use it
    /// before the first prefix sum of a step: the cells are more than four per disk.
    pub scan_sums: u32,
}

/// Words of a region each workgroup of a prefix sum takes (shaders/scan.wgsl).
pub const SCAN_BLOCK: u32 = 256;

/// Fills the region offsets of `p` for the given sizes and returns the buffer sizes.
/// Counters cleared every step come first so one dispatch clears them all; the float
/// accumulators come first in `floats` so they survive a reallocation.
pub fn layout(p: &mut SimParams, cap: Capacity) -> Layout {
    let (nd, nb) = (p.n_disks, p.n_bodies);
    fn take(o: &mut u32, n: u32) -> u32 {
        let at = *o;
        *o += n;
        at
    }
    let mut o = 0u32;
    p.o_status = take(&mut o, status::WORDS as u32);
    p.o_color_count = take(&mut o, cap.colors + 1);
    p.o_color_fill = take(&mut o, cap.colors);
    p.o_cell_start = take(&mut o, cap.cells + 1);
    p.o_cell_fill = take(&mut o, cap.cells);
    p.o_dcount = take(&mut o, nd + 1);
    p.o_inc_count = take(&mut o, nb + 1);
    p.o_inc_fill = take(&mut o, nb);
    p.o_left = take(&mut o, cap.rounds + 1);
    let clear_len = o;
    p.o_disp = take(&mut o, 3 * disp::entries(cap.colors));
    p.o_items = take(&mut o, nd);
    p.o_cell_of = take(&mut o, nd);
    p.o_slots = take(&mut o, nd * cap.k_slots);
    p.o_inc_list = take(&mut o, 2 * cap.contacts);
    // Also the deep contacts' scratch after the coloring (solve.wgsl, `deep_list`).
    p.o_inc_tmp = take(&mut o, 2 * cap.contacts);
    p.o_order = take(&mut o, cap.contacts);
    p.o_color = take(&mut o, cap.contacts);
    p.o_per_disk = take(&mut o, nd);
    p.o_outline = take(&mut o, 2 * OUTLINE_BINS);
    p.o_color_map = take(&mut o, cap.colors);
    let scanned = cap.cells.max(nd).max(nb);
    let scan_sums = take(
        &mut o,
        (scanned.div_ceil(SCAN_BLOCK) + 1).max(4 * nd.div_ceil(SCAN_BLOCK)),
    );
    let ints_len = o.max(1);
    let mut f = 0u32;
    p.f_wall = take(&mut f, 2 * p.n_walls);
    // 16 counts and energies, then 20 micromechanical counts and 19 sums (reduce.wgsl).
    const _: () = assert!(float_slot::RED_MICRO_SUMS + float_slot::MICRO_SUMS <= float_slot::RED_WORDS);
    p.f_red = take(&mut f, float_slot::RED_WORDS as u32);
    p.f_grid = take(&mut f, float_slot::GRID_WORDS as u32);
    p.f_conv = take(&mut f, float_slot::CONV_WORDS as u32);
    p.f_deep = take(&mut f, 2);
    let floats_keep = f;
    p.f_d2 = take(&mut f, cap.contacts);
    p.f_r2 = take(&mut f, cap.contacts);
    p.f_fresh = take(&mut f, 2 * cap.contacts);
    p.k_slots = cap.k_slots;
    p.cap_contacts = cap.contacts;
    p.cap_cells = cap.cells;
    p.max_colors = cap.colors;
    p.max_rounds = cap.rounds;
    Layout {
        ints_len,
        clear_len,
        floats_len: f,
        floats_keep,
        prev_len: nd + 1 + PREV_STRIDE * cap.contacts,
        scan_sums,
    }
}

/// The device buffers of a scene.
pub struct Buffers {
    /// Uniform parameters.
    pub sim: wgpu::Buffer,
    /// Per-dispatch arguments (dynamic offsets of [`ARGS_STRIDE`]).
    pub args: wgpu::Buffer,
    /// Disks.
    pub disks: wgpu::Buffer,
    /// Walls.
    pub walls: wgpu::Buffer,
    /// Generalized velocities (4 regions).
    pub vel: wgpu::Buffer,
    /// Integer scratch.
    pub ints: wgpu::Buffer,
    /// Contacts.
    pub contacts: wgpu::Buffer,
    /// Float scratch.
    pub floats: wgpu::Buffer,
    /// Previous step's impulses.
    pub prev: wgpu::Buffer,
    /// Indirect dispatch arguments of the per-contact kernels.
    pub indirect: wgpu::Buffer,
    /// Sizes and offsets.
    pub layout: Layout,
}

/// Argument slots of the convergence tests: one per distinct block of iterations (its
/// length, velocity test, relaxation) in a step's schedule, which has at most four.
pub const CONV_SLOTS: u32 = 8;

/// The fixed argument slots: 0 the cleared counters, 1 to 3 the prefix sums (cells, disks,
/// bodies: the region, then its block totals), [`GRID_SLOT`] the grid's bounds,
/// [`STRIP_SLOT`] the strips' thickness.
pub const FIXED_SLOTS: u32 = 6;

/// Argument slot of the grid's bounds: the scratch of its partial bounds, and the disks.
pub const GRID_SLOT: u32 = 4;

/// Argument slot of the strips' refresh on the device: its `a` is the thickness (f32 bits),
/// written when a refresh is asked for.
pub const STRIP_SLOT: u32 = 5;

/// Number of per-dispatch argument slots: [`FIXED_SLOTS`], two per color (unrelaxed and
/// relaxed sweeps), one per coloring round, [`CONV_SLOTS`] for the convergence tests.
pub fn args_slots(cap: Capacity) -> u32 {
    FIXED_SLOTS + 2 * cap.colors + cap.rounds + CONV_SLOTS
}

/// Argument slot of color `c`'s sweep at relaxation 1 (`relaxed` false) or
/// `solver.gs_relax` (its `a` is `c`, its `b` the relaxation's f32 bits).
pub fn color_slot(cap: Capacity, c: u32, relaxed: bool) -> u32 {
    FIXED_SLOTS + c + if relaxed { cap.colors } else { 0 }
}

/// Argument slot of coloring round `r` (1-based; its `a` is `r`).
pub fn round_slot(cap: Capacity, r: u32) -> u32 {
    FIXED_SLOTS + 2 * cap.colors + r - 1
}

/// Argument slot of convergence test `k` (`k < CONV_SLOTS`).
pub fn conv_slot(cap: Capacity, k: u32) -> u32 {
    FIXED_SLOTS + 2 * cap.colors + cap.rounds + k
}

/// Checks one buffer size against the adapter's limits; the error ([`GpuError::Limit`](crate::error::GpuError::Limit))
/// names the limit, the need and an estimate of the largest sample that fits (sizes grow
/// linearly with disks).
pub fn check_size(
    what: &str,
    bytes: u64,
    n_disks: usize,
    limits: &wgpu::Limits,
    storage: bool,
) -> Result<()> {
    let (limit, name) = if storage {
        (
            limits.max_storage_buffer_binding_size.min(limits.max_buffer_size),
            "max_storage_buffer_binding_size",
        )
    } else {
        (limits.max_buffer_size, "max_buffer_size")
    };
    if bytes > limit {
        return Err(Error::Gpu(crate::error::GpuError::Limit {
            what: what.to_string(),
            bytes,
            limit_name: name,
            limit,
            fits_disks: (n_disks as f64 * limit as f64 / bytes as f64) as u64,
        }));
    }
    Ok(())
}

fn storage(device: &wgpu::Device, label: &str, bytes: u64, extra: wgpu::BufferUsages) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(256).next_multiple_of(16),
        usage: wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST
            | extra,
        mapped_at_creation: false,
    })
}

impl Buffers {
    /// Bytes allocated on the device by these buffers.
    pub fn device_bytes(&self) -> u64 {
        [
            &self.sim,
            &self.args,
            &self.disks,
            &self.walls,
            &self.vel,
            &self.ints,
            &self.contacts,
            &self.floats,
            &self.prev,
            &self.indirect,
        ]
        .iter()
        .map(|b| b.size())
        .sum()
    }

    /// Allocates every buffer for `p` (whose offsets [`layout`] fills) after checking the
    /// sizes against the device's limits, inside error scopes (a device out of memory gives
    /// [`Error::Gpu`] naming the adapter).
    pub fn new(gpu: &GpuDevice, p: &mut SimParams, cap: Capacity) -> Result<Self> {
        let limits = &gpu.limits;
        let layout = layout(p, cap);
        let nd = p.n_disks as usize;
        let sizes = [
            ("disk", (nd * size_of::<GpuDisk>()) as u64),
            ("velocity", 80 * p.n_bodies as u64),
            ("integer scratch", 4 * layout.ints_len as u64),
            ("contact", cap.contacts as u64 * size_of::<GpuContact>() as u64),
            ("float scratch", 4 * layout.floats_len as u64),
            ("warm-start", 4 * layout.prev_len as u64),
        ];
        for (what, bytes) in sizes {
            check_size(what, bytes, nd, limits, true)?;
        }
        let none = wgpu::BufferUsages::empty();
        gpu.scoped("allocating the sample's buffers", |device| Buffers {
            sim: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("sim"),
                size: size_of::<SimParams>() as u64,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            args: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("args"),
                size: args_slots(cap) as u64 * ARGS_STRIDE,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            disks: storage(device, "disks", sizes[0].1, none),
            walls: storage(
                device,
                "walls",
                (size_of::<GpuWall>() as u64) * p.n_walls as u64,
                none,
            ),
            vel: storage(device, "vel", sizes[1].1, none),
            ints: storage(device, "ints", sizes[2].1, none),
            contacts: storage(device, "contacts", sizes[3].1, none),
            floats: storage(device, "floats", sizes[4].1, none),
            prev: storage(device, "prev", sizes[5].1, none),
            indirect: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("indirect"),
                size: 12 * disp::entries(cap.colors) as u64,
                usage: wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            layout,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_buffer_over_the_binding_limit_is_a_limit_error_with_the_sample_that_fits() {
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: 1000,
            max_buffer_size: 4000,
            ..wgpu::Limits::default()
        };
        check_size("disk", 1000, 100, &limits, true).expect("at the limit fits");
        match check_size("disk", 4000, 100, &limits, true) {
            // 100 disks need 4000 bytes, 1000 fit: about 25 disks.
            Err(Error::Gpu(crate::error::GpuError::Limit {
                limit_name,
                limit,
                fits_disks,
                ..
            })) => {
                assert_eq!(limit_name, "max_storage_buffer_binding_size");
                assert_eq!((limit, fits_disks), (1000, 25));
            }
            other => panic!("expected GpuError::Limit, got {other:?}"),
        }
        // A non-binding buffer is held to max_buffer_size only.
        check_size("indirect", 4000, 100, &limits, false).expect("within max_buffer_size");
        assert!(matches!(
            check_size("indirect", 4001, 100, &limits, false),
            Err(Error::Gpu(crate::error::GpuError::Limit { limit: 4000, .. }))
        ));
    }
}
