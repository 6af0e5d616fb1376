//! Host memory of a long GPU run stays flat (issue: a biaxial run on lavapipe grew by
//! megabytes per second until it died). One test in this binary, so no other test's
//! allocations move the resident size it reads.

mod common;
mod gpu_support;

use cdlab::backend::{Backend, Loading};
use cdlab::solver::Method;

/// Resident set size of this process (kB), from /proc/self/status.
fn rss_kb() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    s.lines()
        .find(|l| l.starts_with("VmRSS:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()
}

#[test]
fn host_memory_stays_flat_over_many_gpu_steps() {
    let Some(before) = rss_kb() else {
        eprintln!("SKIPPED (no /proc/self/status): host memory of a GPU run");
        return;
    };
    // 225 disks settling on a floor under gravity: every phase runs each step (detection,
    // coloring, solver sweeps, integration), the contacts persist and warm-start.
    let scene = gpu_support::hex(15, 15);
    let mut p = gpu_support::gpu_params(Method::Gs);
    p.solver.tol = 1e-4;
    p.solver.max_iter = 200;
    let Some(mut b) = gpu_support::gpu_or_skip("host memory of a GPU run", &scene, p) else {
        return;
    };
    // Chunks of 50 steps with a scene download after each, as the protocol's output rows do.
    let chunk = |b: &mut cdlab::gpu::GpuBackend| {
        b.run(50, &Loading::default()).unwrap();
        b.scene().unwrap()
    };
    // Warm-up: buffer growth, the driver's pipeline state and the allocator's pools settle.
    for _ in 0..4 {
        chunk(&mut b);
    }
    let warm = rss_kb().unwrap();
    let steps_before = b.counters().steps;
    for _ in 0..30 {
        chunk(&mut b);
    }
    let after = rss_kb().unwrap();
    let steps = b.counters().steps - steps_before;
    let growth = after as i64 - warm as i64;
    println!(
        "resident memory: {before} kB at start, {warm} kB after the warm-up, {after} kB after \
         {steps} more steps ({growth:+} kB, {:.2} kB per step)",
        growth as f64 / steps as f64
    );
    // Bound: 16 MB over 1500 steps, about 11 kB per step. The defect this guards against
    // (Mesa lavapipe recompiling a shader specialized to the uniform buffers at every
    // dispatch, see `sim` in shaders/common.wgsl) retained about 150 kB per step on this
    // scene, over 200 MB here; with it fixed the resident size moves by about 1 MB either
    // way (allocator pools). A retention ten times smaller than the defect's still fails.
    assert_eq!(steps, 1500);
    assert!(
        growth < 16 * 1024,
        "resident memory grew by {growth} kB over {steps} GPU steps ({warm} -> {after} kB)"
    );
}
