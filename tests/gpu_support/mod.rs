//! Helpers of the GPU tests: adapter-or-skip, parameters, packings.
#![allow(dead_code)]

use cdlab::engine::StepParams;
use cdlab::gpu::GpuBackend;
use cdlab::model::Scene;
use cdlab::solver::Method;
use glam::DVec2;

use crate::common::*;

/// Whether `CDLAB_REQUIRE_GPU` asks for a GPU: unset or empty, `0`, `false`, `no`, `off`
/// mean no; `1`, `true`, `yes`, `on` mean yes (any case, surrounding blanks ignored).
/// Any other value panics naming the variable: a typo must not turn CI's check off.
pub fn require_gpu() -> bool {
    parse_require(std::env::var("CDLAB_REQUIRE_GPU").ok().as_deref())
}

/// [`require_gpu`] on a given value of the variable.
pub fn parse_require(value: Option<&str>) -> bool {
    let v = value.unwrap_or("").trim().to_ascii_lowercase();
    match v.as_str() {
        "" | "0" | "false" | "no" | "off" => false,
        "1" | "true" | "yes" | "on" => true,
        other => panic!(
            "CDLAB_REQUIRE_GPU = {other:?}: expected 1, true, yes, on (require a GPU adapter) \
             or 0, false, no, off"
        ),
    }
}

/// What a test does with the result of opening the GPU: `Some` on success; `None` with a
/// visible SKIPPED line when there is no adapter at all and no GPU is required; a panic
/// for every other GPU error (a shader the driver rejects, a buffer over the adapter's
/// limits, a failing device), required or not, and for a missing adapter when
/// `CDLAB_REQUIRE_GPU` is true (CI sets it).
pub fn skip_only_without_adapter<T>(test: &str, opened: cdlab::Result<T>) -> Option<T> {
    decide(test, opened, require_gpu())
}

/// [`skip_only_without_adapter`] with the requirement given.
pub fn decide<T>(test: &str, opened: cdlab::Result<T>, require: bool) -> Option<T> {
    // To the process's stderr directly, past the test harness's capture, so that a real
    // skip shows in a plain `cargo test`.
    decide_to(test, opened, require, &mut std::io::stderr())
}

/// [`decide`] with the SKIPPED line written to `out`: the tests of the rule itself keep
/// their made-up skips off the terminal, where they read as GPU tests not run.
pub fn decide_to<T>(
    test: &str,
    opened: cdlab::Result<T>,
    require: bool,
    out: &mut dyn std::io::Write,
) -> Option<T> {
    match opened {
        Ok(b) => Some(b),
        Err(cdlab::Error::Gpu(cdlab::error::GpuError::NoAdapter(msg))) if !require => {
            let line = format!("SKIPPED (no GPU adapter): {test}: {msg}\n");
            let _ = out.write_all(line.as_bytes());
            None
        }
        Err(e) => panic!("{test}: {e}"),
    }
}

/// Gives the process an `XDG_RUNTIME_DIR` when it has none, once, before the first wgpu
/// instance. Mesa's Vulkan device-selection layer probes for a Wayland display when an
/// instance is created, and libwayland prints "error: XDG_RUNTIME_DIR is invalid or not
/// set" to the terminal without one: two lines per GPU test. The `cdlab` binary does the
/// same at its start (`src/main.rs`); the test binaries call the library directly. The
/// temporary directory holds no display socket, so the probe fails quietly.
pub fn quiet_display_probe() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
            // SAFETY: std's own environment reads take the lock set_var takes, and every
            // GPU test reaches wgpu and Mesa (which read the environment from C) through
            // this Once, so none of them reads it while it is written.
            unsafe { std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir()) };
        }
    });
}

/// A GPU backend on `scene` (see [`skip_only_without_adapter`] for when it skips).
pub fn gpu_or_skip(test: &str, scene: &Scene, params: StepParams) -> Option<GpuBackend> {
    quiet_display_probe();
    skip_only_without_adapter(test, GpuBackend::new(scene.clone(), params))
}

/// An opened device (same rule as [`gpu_or_skip`]).
pub fn device_or_skip(test: &str) -> Option<cdlab::gpu::device::GpuDevice> {
    quiet_display_probe();
    skip_only_without_adapter(test, cdlab::gpu::device::open())
}

/// Tight solver settings for the GPU: f32 impulses stop changing at a relative 1e-7, so a
/// tolerance of 1e-6 is the tightest the convergence test can certify; iterations are
/// checked one by one so the GPU stops at the same iteration as a converged CPU run would.
pub fn gpu_params(method: Method) -> StepParams {
    let mut p = tight(method);
    p.solver.tol = 1e-6;
    p.solver.max_iter = 5000;
    p
}

/// Sorted (i, partner) pairs.
pub fn pairs(it: impl Iterator<Item = (u32, u32)>) -> Vec<(u32, u32)> {
    let mut v: Vec<_> = it.collect();
    v.sort_unstable();
    v
}

/// Near-touching disks on a jittered square lattice with random velocities (see the
/// contact-set test), in a box.
pub fn lattice(n: usize, seed: u64) -> Scene {
    let mut rng = Rng(seed);
    let mut s = scene(0.3);
    for a in 0..n {
        for b in 0..n {
            let r = 1.0 - 0.01 * rng.uniform();
            let p = DVec2::new(
                2.0 * a as f64 + rng.range(-0.004, 0.004),
                2.0 * b as f64 + rng.range(-0.004, 0.004),
            );
            let k = s.disks.push(p, r, RHO).unwrap();
            s.disks.vel[k] = DVec2::new(rng.range(-0.1, 0.1), rng.range(-0.1, 0.1));
            s.disks.spin[k] = rng.range(-0.1, 0.1);
        }
    }
    let side = 2.0 * n as f64 - 1.0;
    add_box(&mut s, -1.005, side, -1.0, side);
    s
}

/// A hexagonal packing of `rows` x `cols` equal disks (radius 0.5) in contact, on a floor.
pub fn hex(rows: usize, cols: usize) -> Scene {
    let mut s = scene(0.3);
    let r = 0.5;
    for row in 0..rows {
        for col in 0..cols {
            let x = 2.0 * r * col as f64 + r * (row % 2) as f64;
            let y = row as f64 * r * 3f64.sqrt();
            s.disks.push(DVec2::new(x, y), r, RHO).unwrap();
        }
    }
    s.walls.push(floor_at(-r));
    s
}

pub fn floor_at(y: f64) -> cdlab::model::Wall {
    cdlab::model::Wall::fixed(DVec2::new(0.0, y), DVec2::Y)
}

pub const G: f64 = 9.81;
