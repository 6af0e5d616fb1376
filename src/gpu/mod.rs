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
    ("integrate.wgsl", include_str!("../../shaders/integrate.wgsl")),
    ("reduce.wgsl", include_str!("../../shaders/reduce.wgsl")),
];

/// Threads per workgroup of the kernels that run one thread per item (disk, body, contact):
/// the host's dispatch counts and the shaders' `@workgroup_size(WG)` both use this value.
pub const WG: u32 = 64;

/// The constants the shaders share with Rust, as `(WGSL name, value)`: body kinds, the
/// "not glued" sentinel, the status-word indices read back by the host, the slots of the
/// float regions it reads back (`FR_*`, `FG_*`, `FC_*`), the warm-start
/// record stride and the workgroup size. `shaders/common.wgsl` declares each of them (it
/// must parse on its own), and tests/gpu_layout.rs checks every declaration against this
/// table, so the Rust constants stay the one source of these values.
pub fn wgsl_constants() -> Vec<(&'static str, u32)> {
    use crate::model::{BodyKind, NOT_GLUED};
    use buffers::{PREV_STRIDE, disp, float_slot as fs, status};
    vec![
        ("WG", WG),
        ("KIND_FREE", BodyKind::Free as u32),
        ("KIND_KINEMATIC", BodyKind::Kinematic as u32),
        ("NOT_GLUED", NOT_GLUED),
        ("PREV_STRIDE", PREV_STRIDE),
        ("ST_CONTACTS", status::CONTACTS as u32),
        ("ST_SLOTS_NEED", status::SLOTS_NEED as u32),
        ("ST_COLORS", status::COLORS as u32),
        ("ST_OVERLAP", status::OVERLAP as u32),
        ("ST_ROUNDS", status::ROUNDS as u32),
        ("ST_LEFT", status::LEFT as u32),
        ("ST_ARGS", status::ARGS as u32),
        ("ST_DEEP", status::DEEP as u32),
        ("ST_NONEMPTY", status::NONEMPTY as u32),
        ("ST_BIG", status::BIG as u32),
        ("ST_TAIL", status::TAIL as u32),
        ("ST_BAD", status::BAD as u32),
        ("ST_ITERS", status::ITERS as u32),
        ("ST_CONVERGED", status::CONVERGED as u32),
        ("ST_RESIDUAL", status::RESIDUAL as u32),
        ("ST_LIVE", status::LIVE as u32),
        ("ST_WORDS", status::WORDS as u32),
        ("DISP_CONTACTS", disp::CONTACTS),
        ("DISP_LIVE_CONTACTS", disp::LIVE_CONTACTS),
        ("DISP_LIVE_BODIES", disp::LIVE_BODIES),
        ("DISP_LIVE_ONE", disp::LIVE_ONE),
        ("DISP_COLOR0", disp::COLOR0),
        ("FR_MEAN_RN", fs::RED_MEAN_RN as u32),
        ("FR_ROLLING", fs::RED_ROLLING as u32),
        ("FR_SLIDING", fs::RED_SLIDING as u32),
        ("FR_ZERO_FORCE", fs::RED_ZERO_FORCE as u32),
        ("FR_CONNECTED", fs::RED_CONNECTED as u32),
        ("FR_FREE", fs::RED_FREE as u32),
        ("FR_OVERLAP_COUNT", fs::RED_OVERLAP_COUNT as u32),
        ("FR_OVERLAP_SUM", fs::RED_OVERLAP_SUM as u32),
        ("FR_OVERLAP_MAX", fs::RED_OVERLAP_MAX as u32),
        ("FR_KINETIC", fs::RED_KINETIC as u32),
        ("FR_STRIP_X_LEFT", fs::RED_STRIP_X_LEFT as u32),
        ("FR_STRIP_X_RIGHT", fs::RED_STRIP_X_RIGHT as u32),
        ("FR_STRIP_N_LEFT", fs::RED_STRIP_N_LEFT as u32),
        ("FR_STRIP_N_RIGHT", fs::RED_STRIP_N_RIGHT as u32),
        ("FR_TRANSLATIONAL", fs::RED_TRANSLATIONAL as u32),
        ("FR_CONNECTED_ENERGY", fs::RED_CONNECTED_ENERGY as u32),
        ("FR_MICRO", fs::RED_MICRO as u32),
        ("FR_MICRO_SUMS", fs::RED_MICRO_SUMS as u32),
        ("FR_MICRO_COUNTS", fs::MICRO_COUNTS as u32),
        ("FR_MICRO_SUM_COUNT", fs::MICRO_SUMS as u32),
        ("FR_EDGE_LEFT", fs::RED_EDGE_LEFT as u32),
        ("FR_EDGE_RIGHT", fs::RED_EDGE_RIGHT as u32),
        ("FR_EDGE_COUNT", fs::RED_EDGE_COUNT as u32),
        ("OUTLINE_BINS", buffers::OUTLINE_BINS),
        ("FG_ORIGIN_X", fs::GRID_ORIGIN_X as u32),
        ("FG_ORIGIN_Y", fs::GRID_ORIGIN_Y as u32),
        ("FG_CELL", fs::GRID_CELL as u32),
        ("FG_NX", fs::GRID_NX as u32),
        ("FG_NY", fs::GRID_NY as u32),
        ("FC_D2", fs::CONV_D2 as u32),
        ("FC_R2", fs::CONV_R2 as u32),
        ("FC_DV", fs::CONV_DV as u32),
    ]
}

/// A phase shader with the shared WGSL in front of it (plain concatenation: WGSL has no
/// includes, and one shared prefix is all the composition the phases need).
pub fn compose(phase: &str) -> String {
    format!("{COMMON_WGSL}\n{phase}")
}
