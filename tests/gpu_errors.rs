//! wgpu errors end a GPU run with a cdlab error, never with wgpu's default handler (which
//! panics): a shader the driver rejects, a buffer beyond the adapter's limits, inside an
//! error scope and outside one. Each error names the adapter and the way out
//! (`--backend cpu`).
//!
//! Skips visibly without an adapter, fails with `CDLAB_REQUIRE_GPU=1`.

mod common;
#[path = "gpu_support/mod.rs"]
mod gpu_support;

use gpu_support::*;

/// Checks that `e` is the GPU error of `adapter` with the advice to rerun on the CPU.
fn assert_gpu_failure(e: cdlab::Error, adapter: &str, what: &str) {
    let text = e.to_string();
    assert!(
        matches!(e, cdlab::Error::Gpu(_)),
        "{what}: not a GPU error: {text}"
    );
    assert!(
        text.contains(adapter),
        "{what}: adapter {adapter} not named: {text}"
    );
    assert!(text.contains("--backend cpu"), "{what}: no advice: {text}");
}

#[test]
fn gpu_errors_come_back_as_cdlab_errors_naming_the_adapter() {
    let Some(gpu) = device_or_skip("wgpu errors") else {
        return;
    };
    let adapter = gpu.info.name.clone();

    // A shader that does not parse: a validation error caught by the scope.
    let e = gpu
        .scoped("compiling a broken shader", |d| {
            d.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("broken"),
                source: wgpu::ShaderSource::Wgsl("fn main( {".into()),
            })
        })
        .expect_err("a broken shader must give an error");
    assert_gpu_failure(e, &adapter, "broken shader");

    // A buffer one byte beyond the adapter's largest: caught by the scope too.
    let too_big = gpu.limits.max_buffer_size + 1;
    let storage = |d: &wgpu::Device| {
        d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("too big"),
            size: too_big,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        })
    };
    let e = gpu
        .scoped("allocating an oversized buffer", storage)
        .expect_err("an oversized buffer must give an error");
    assert_gpu_failure(e, &adapter, "oversized buffer in a scope");

    // The same request outside any scope: wgpu's default handler would panic here; ours
    // keeps the error for the next check.
    let _ = storage(&gpu.device);
    let e = gpu
        .check("after an oversized buffer")
        .expect_err("the uncaptured error must be kept");
    assert_gpu_failure(e, &adapter, "oversized buffer outside a scope");

    // Each error is reported once, and valid work passes (the checks above could not pass
    // by failing on everything).
    gpu.check("after the report")
        .expect("the log is emptied by a check");
    gpu.scoped("allocating a small buffer", |d| {
        d.create_buffer(&wgpu::BufferDescriptor {
            label: Some("small"),
            size: 256,
            usage: wgpu::BufferUsages::STORAGE,
            mapped_at_creation: false,
        })
    })
    .expect("a 256-byte buffer is valid");
}
