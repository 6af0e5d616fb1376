//! The GPU backend: the same time step as the CPU engine, phase by phase, in WGSL compute
//! shaders (`shaders/`) driven through wgpu.
//!
//! - [`device`]: adapter selection and listing;
//! - [`buffers`]: `#[repr(C)]` Pod records (f32) and the device buffers with their capacities;
//! - [`pipeline`]: shader composition and the compute pipelines;
//! - [`backend`]: [`GpuBackend`], the [`crate::backend::Backend`] the protocol drives;
//! - [`traffic`]: the bytes each kernel reads and writes per item, which the counters add up.

pub mod backend;
pub mod buffers;
pub mod device;
pub mod pipeline;
mod step;
pub mod traffic;

pub use backend::{GpuBackend, GpuCounters};

/// WGSL shared by every phase (structs, bindings, contact frame, local solve).
pub const COMMON_WGSL: &str = include_str!("../../shaders/common.wgsl");

/// The phase shaders, by file name (one per phase, each composed with [`COMMON_WGSL`]).
pub const SHADERS: &[(&str, &str)] = &[
    ("scan.wgsl", include_str!("../../shaders/scan.wgsl")),
    (
        "integrate_free.wgsl",
        include_str!("../../shaders/integrate_free.wgsl"),
    ),
    ("grid.wgsl", include_str!("../../shaders/grid.wgsl")),
    ("detect.wgsl", include_str!("../../shaders/detect.wgsl")),
    ("color.wgsl", include_str!("../../shaders/color.wgsl")),
    ("solve.wgsl", include_str!("../../shaders/solve.wgsl")),
    ("sweep.wgsl", include_str!("../../shaders/sweep.wgsl")),
    ("integrate.wgsl", include_str!("../../shaders/integrate.wgsl")),
    ("reduce.wgsl", include_str!("../../shaders/reduce.wgsl")),
];

/// Threads per workgroup of the kernels that run one thread per item (disk, body, contact):
/// the host's dispatch counts and the shaders' `@workgroup_size(WG)` both use this value.
pub const WG: u32 = 64;

/// The constants the shaders share with Rust, as `(WGSL name, value, what it is)`: body
/// kinds, the "not glued" sentinel, the status-word indices read back by the host, the
/// slots of the float regions it reads back (`FR_*`, `FG_*`, `FC_*`), the warm-start record
/// stride and the workgroup size. The shaders get them from [`wgsl_prelude`], generated
/// from this table, so the Rust constants are their one source; tests/gpu_layout.rs checks
/// that no shader declares one itself.
pub fn wgsl_constants() -> Vec<(&'static str, u32, &'static str)> {
    use crate::model::{BodyKind, NOT_GLUED};
    use buffers::{PREV_STRIDE, disp, float_slot as fs, status};
    vec![
        ("WG", WG, "threads per workgroup of per-item kernels (gpu::WG)"),
        ("KIND_FREE", BodyKind::Free as u32, "model::BodyKind::Free"),
        (
            "KIND_KINEMATIC",
            BodyKind::Kinematic as u32,
            "model::BodyKind::Kinematic",
        ),
        ("NOT_GLUED", NOT_GLUED, "model::NOT_GLUED"),
        (
            "PREV_STRIDE",
            PREV_STRIDE,
            "words per warm-start record (buffers::PREV_STRIDE)",
        ),
        (
            "ST_CONTACTS",
            status::CONTACTS as u32,
            "contacts found (may exceed the capacity)",
        ),
        (
            "ST_SLOTS_NEED",
            status::SLOTS_NEED as u32,
            "largest per-disk contact count (may exceed k_slots)",
        ),
        ("ST_COLORS", status::COLORS as u32, "colors used"),
        (
            "ST_OVERLAP",
            status::OVERLAP as u32,
            "largest overlap, f32 bits (positive floats sort as u32)",
        ),
        ("ST_ROUNDS", status::ROUNDS as u32, "coloring rounds"),
        (
            "ST_LEFT",
            status::LEFT as u32,
            "contacts left uncolored after the recorded rounds",
        ),
        (
            "ST_ARGS",
            status::ARGS as u32,
            "indirect dispatch size of per-contact kernels (3 words)",
        ),
        (
            "ST_DEEP",
            status::DEEP as u32,
            "contacts marked for local updates (solve.wgsl, deep_mark)",
        ),
        (
            "ST_NONEMPTY",
            status::NONEMPTY as u32,
            "colors holding contacts (solve.wgsl, solve_args)",
        ),
        (
            "ST_BIG",
            status::BIG as u32,
            "colors of more than WG contacts, a dispatch each",
        ),
        (
            "ST_TAIL",
            status::TAIL as u32,
            "smaller colors, swept together (sweep_tail)",
        ),
        (
            "ST_BAD",
            status::BAD as u32,
            "non-finite convergence sums met (conv_check)",
        ),
        (
            "ST_ITERS",
            status::ITERS as u32,
            "solver iterations run this step (conv_check)",
        ),
        (
            "ST_CONVERGED",
            status::CONVERGED as u32,
            "1 when the solve met its tolerance or velocity test",
        ),
        (
            "ST_RESIDUAL",
            status::RESIDUAL as u32,
            "relative change of the last test, f32 bits",
        ),
        ("ST_LIVE", status::LIVE as u32, "1 while the solve goes on"),
        (
            "ST_WORDS",
            status::WORDS as u32,
            "status words (a step's row in the history)",
        ),
        ("DISP_CONTACTS", disp::CONTACTS, "per-contact kernels of the step"),
        (
            "DISP_LIVE_CONTACTS",
            disp::LIVE_CONTACTS,
            "per-contact kernels of the solve (0 once it ended)",
        ),
        (
            "DISP_LIVE_BODIES",
            disp::LIVE_BODIES,
            "per-body kernels of the solve",
        ),
        (
            "DISP_LIVE_ONE",
            disp::LIVE_ONE,
            "one workgroup while the solve goes on",
        ),
        (
            "DISP_COLOR0",
            disp::COLOR0,
            "color c's sweep is entry DISP_COLOR0 + c",
        ),
        (
            "FR_MEAN_RN",
            fs::RED_MEAN_RN as u32,
            "mean R_n of the loaded contacts",
        ),
        (
            "FR_ROLLING",
            fs::RED_ROLLING as u32,
            "rolling contacts (u32 bits)",
        ),
        (
            "FR_SLIDING",
            fs::RED_SLIDING as u32,
            "sliding contacts (u32 bits)",
        ),
        (
            "FR_ZERO_FORCE",
            fs::RED_ZERO_FORCE as u32,
            "zero-force contacts (u32 bits)",
        ),
        (
            "FR_CONNECTED",
            fs::RED_CONNECTED as u32,
            "free disks with >= 2 force-carrying contacts (u32 bits)",
        ),
        ("FR_FREE", fs::RED_FREE as u32, "free disks (u32 bits)"),
        (
            "FR_OVERLAP_COUNT",
            fs::RED_OVERLAP_COUNT as u32,
            "overlapping contacts",
        ),
        ("FR_OVERLAP_SUM", fs::RED_OVERLAP_SUM as u32, "their overlap sum"),
        ("FR_OVERLAP_MAX", fs::RED_OVERLAP_MAX as u32, "largest overlap"),
        ("FR_KINETIC", fs::RED_KINETIC as u32, "kinetic energy"),
        (
            "FR_STRIP_X_LEFT",
            fs::RED_STRIP_X_LEFT as u32,
            "x sum of the left strip",
        ),
        (
            "FR_STRIP_X_RIGHT",
            fs::RED_STRIP_X_RIGHT as u32,
            "x sum of the right strip",
        ),
        (
            "FR_STRIP_N_LEFT",
            fs::RED_STRIP_N_LEFT as u32,
            "disks of the left strip",
        ),
        (
            "FR_STRIP_N_RIGHT",
            fs::RED_STRIP_N_RIGHT as u32,
            "disks of the right strip",
        ),
        (
            "FR_TRANSLATIONAL",
            fs::RED_TRANSLATIONAL as u32,
            "translational kinetic energy",
        ),
        (
            "FR_CONNECTED_ENERGY",
            fs::RED_CONNECTED_ENERGY as u32,
            "that of the connected disks",
        ),
        (
            "FR_MICRO",
            fs::RED_MICRO as u32,
            "micromechanical counts (reduce.wgsl, micro_sums)",
        ),
        (
            "FR_MICRO_SUMS",
            fs::RED_MICRO_SUMS as u32,
            "micromechanical sums, after the counts",
        ),
        (
            "FR_MICRO_COUNTS",
            fs::MICRO_COUNTS as u32,
            "the counts: force-carrying, strong, 18 bins",
        ),
        ("FR_MICRO_SUM_COUNT", fs::MICRO_SUMS as u32, "the sums"),
        (
            "FR_EDGE_LEFT",
            fs::RED_EDGE_LEFT as u32,
            "sum of the left outline (reduce.wgsl, outline_sum)",
        ),
        (
            "FR_EDGE_RIGHT",
            fs::RED_EDGE_RIGHT as u32,
            "sum of the right outline",
        ),
        (
            "FR_EDGE_COUNT",
            fs::RED_EDGE_COUNT as u32,
            "heights where both are set (u32 bits)",
        ),
        (
            "OUTLINE_BINS",
            buffers::OUTLINE_BINS,
            "heights of the outline, at most (buffers::OUTLINE_BINS)",
        ),
        ("FG_ORIGIN_X", fs::GRID_ORIGIN_X as u32, "grid origin x"),
        ("FG_ORIGIN_Y", fs::GRID_ORIGIN_Y as u32, "grid origin y"),
        ("FG_CELL", fs::GRID_CELL as u32, "cell size"),
        ("FG_NX", fs::GRID_NX as u32, "cells along x (u32 bits)"),
        ("FG_NY", fs::GRID_NY as u32, "cells along y (u32 bits)"),
        ("FC_D2", fs::CONV_D2 as u32, "sum |dR|^2 of the last iteration"),
        ("FC_R2", fs::CONV_R2 as u32, "sum |R|^2"),
        (
            "FC_DV",
            fs::CONV_DV as u32,
            "largest velocity change since save_iterate",
        ),
    ]
}

/// The WGSL declarations of [`wgsl_constants`], one `const` per line with what it is,
/// which [`compose`] puts in front of every shader.
pub fn wgsl_prelude() -> String {
    let mut out = String::from("// Generated from cdlab::gpu::wgsl_constants (src/gpu/mod.rs).\n");
    for (name, value, what) in wgsl_constants() {
        out.push_str(&format!("const {name}: u32 = {value}u;"));
        if !what.is_empty() {
            out.push_str(&format!(" // {what}"));
        }
        out.push('\n');
    }
    out
}

/// A phase shader with the shared WGSL in front of it: the generated constants
/// ([`wgsl_prelude`]), the bindings with every buffer read-write
/// ([`pipeline::wgsl_bindings`] under [`pipeline::Binds::Shared`]), then `common.wgsl`
/// (plain concatenation: WGSL has no includes, and one shared prefix is all the
/// composition the phases need).
pub fn compose(phase: &str) -> String {
    compose_with(pipeline::Binds::Shared, phase)
}

/// [`compose`] for the phase file `file`, its buffers bound as its access says
/// ([`pipeline::Binds::of_file`]): what the pipelines compile.
pub fn compose_file(file: &str, phase: &str) -> String {
    compose_with(pipeline::Binds::of_file(file), phase)
}

fn compose_with(access: pipeline::Binds, phase: &str) -> String {
    format!(
        "{}{}{COMMON_WGSL}\n{phase}",
        wgsl_prelude(),
        pipeline::wgsl_bindings(access)
    )
}
