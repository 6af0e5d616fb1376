//! The GPU backend: the same time step as the CPU engine, phase by phase, in WGSL compute
//! shaders (`shaders/`) driven through wgpu.
//!
//! - [`device`]: adapter selection and listing;
//! - [`buffers`]: `#[repr(C)]` Pod records (f32) and the device buffers with their capacities;
//! - [`pipeline`]: shader composition and the compute pipelines;
//! - [`backend`]: [`GpuBackend`], the [`crate::backend::Backend`] the protocol drives.

pub mod backend;
pub mod buffers;
pub mod device;
pub mod pipeline;
mod step;

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

/// A phase shader with the shared WGSL in front of it (plain concatenation: WGSL has no
/// includes, and one shared prefix is all the composition the phases need).
pub fn compose(phase: &str) -> String {
    format!("{COMMON_WGSL}\n{phase}")
}
