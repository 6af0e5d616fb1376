//! GPU path checks (validation.md, "Cross-checks between the two backends").
//!
//! The shader test needs no adapter. The others run on any adapter wgpu finds
//! (`Backends::all()`; set `WGPU_BACKEND=vulkan` to pick Mesa's lavapipe on a machine
//! without a GPU) and skip with a visible `SKIPPED (no GPU adapter)` line otherwise,
//! unless `CDLAB_REQUIRE_GPU=1` (CI), in which case a missing adapter fails the test.

use std::path::Path;

/// Every WGSL file in `shaders/` parses and validates through naga, composed the way the
/// pipelines compose it (`common.wgsl` first). Iterates the directory, so a new shader is
/// covered without touching this test.
#[test]
fn every_shader_parses_and_validates() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let common = std::fs::read_to_string(dir.join("common.wgsl")).expect("common.wgsl");
    let mut checked = 0;
    let mut entries: Vec<_> = std::fs::read_dir(&dir)
        .expect("shaders/")
        .map(|e| e.expect("entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "wgsl"))
        .collect();
    entries.sort();
    for path in entries {
        let own = std::fs::read_to_string(&path).expect("shader");
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        let source = if name == "common.wgsl" {
            own
        } else {
            cdlab::gpu::compose(&own)
        };
        let module = naga::front::wgsl::parse_str(&source)
            .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&source)));
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::empty(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&source)));
        checked += 1;
    }
    assert!(checked >= 8, "only {checked} shaders found");
}

mod common;

use cdlab::backend::{Backend, CpuBackend, Loading};
use cdlab::engine::{CpuEngine, StepParams};
use cdlab::gpu::GpuBackend;
use cdlab::model::Scene;
use cdlab::solver::Method;
use common::*;
use glam::DVec2;

/// A GPU backend on `scene`, or `None` with a visible SKIPPED line when no adapter exists.
/// With `CDLAB_REQUIRE_GPU=1` a missing adapter panics instead (CI sets it).
fn gpu_or_skip(test: &str, scene: &Scene, params: StepParams) -> Option<GpuBackend> {
    match GpuBackend::new(scene.clone(), params) {
        Ok(b) => Some(b),
        Err(cdlab::Error::Gpu(msg)) if std::env::var("CDLAB_REQUIRE_GPU").as_deref() != Ok("1") => {
            eprintln!("SKIPPED (no GPU adapter): {test}: {msg}");
            None
        }
        Err(e) => panic!("{test}: {e}"),
    }
}

/// Tight solver settings for the GPU: f32 impulses stop changing at a relative 1e-7, so a
/// tolerance of 1e-6 is the tightest the convergence test can certify; iterations are
/// checked one by one so the GPU stops at the same iteration as a converged CPU run would.
fn gpu_params(method: Method) -> StepParams {
    let mut p = tight(method);
    p.solver.tol = 1e-6;
    p.solver.max_iter = 5000;
    p
}

/// Sorted (i, partner) pairs.
fn pairs(it: impl Iterator<Item = (u32, u32)>) -> Vec<(u32, u32)> {
    let mut v: Vec<_> = it.collect();
    v.sort_unstable();
    v
}

fn compare_contact_sets(test: &str, s: &Scene) {
    let params = gpu_params(Method::ColoredGs);
    let Some(mut g) = gpu_or_skip(test, s, params) else {
        return;
    };
    g.run(1, &Loading::default()).unwrap();
    let gpu = pairs(g.contacts().unwrap().iter().map(|c| (c.i, c.j)));
    let mut cpu = CpuEngine::new(params).unwrap();
    let mut sc = s.clone();
    cpu.step(&mut sc).unwrap();
    let cpu = pairs(cpu.contacts().iter().map(|c| (c.i, c.disk_j)));
    // Expected: the same pairs. A pair whose gap lies within f32 round-off of the alert
    // distance could legitimately differ; the packings below have none, so the sets must
    // be equal exactly.
    assert!(!cpu.is_empty(), "{test}: no contacts to compare");
    assert_eq!(gpu, cpu, "{test}: contact sets differ");
}

#[test]
fn gpu_contact_set_equals_cpu_on_a_random_cloud() {
    // Near-touching disks on a jittered square lattice: gaps spread over [-0.01, 0.03] m
    // around the alert distance (0.01 m), some overlapping, some beyond it.
    let mut rng = Rng(7);
    let mut s = scene(0.3);
    for a in 0..16 {
        for b in 0..16 {
            let r = 1.0 - 0.01 * rng.uniform();
            let p = DVec2::new(
                2.0 * a as f64 + rng.range(-0.004, 0.004),
                2.0 * b as f64 + rng.range(-0.004, 0.004),
            );
            let k = s.disks.push(p, r, RHO).unwrap();
            s.disks.vel[k] = DVec2::new(rng.range(-0.1, 0.1), rng.range(-0.1, 0.1));
        }
    }
    add_box(&mut s, -1.005, 31.0, -1.0, 31.0);
    compare_contact_sets("random cloud", &s);
}

#[test]
fn gpu_contact_set_equals_cpu_on_a_dense_packing() {
    // A hexagonal packing of equal disks in contact (every pair at gap 0 or 2 r (sqrt3-1)),
    // with a few glued and fixed disks so that every ownership rule is exercised.
    let mut s = scene(0.3);
    let r = 0.5;
    for row in 0..12 {
        for col in 0..14 {
            let x = 2.0 * r * col as f64 + r * (row % 2) as f64;
            let y = row as f64 * r * 3f64.sqrt();
            s.disks.push(DVec2::new(x, y), r, RHO).unwrap();
        }
    }
    s.walls.push(floor_at(-r));
    for k in 0..14 {
        s.disks.glue(k, 0);
    }
    s.disks.set_kind(20, cdlab::model::BodyKind::Fixed);
    compare_contact_sets("dense packing", &s);
}

fn floor_at(y: f64) -> cdlab::model::Wall {
    cdlab::model::Wall::fixed(DVec2::new(0.0, y), DVec2::Y)
}

#[test]
fn gpu_head_on_inelastic_collision_gives_the_mean_velocity() {
    for method in [Method::ColoredGs, Method::Jacobi] {
        let mut s = scene(0.0);
        s.disks.push(DVec2::new(-1.0, 0.0), 1.0, RHO).unwrap();
        s.disks.push(DVec2::new(1.0, 0.0), 1.0, RHO).unwrap();
        s.disks.vel[0] = DVec2::new(2.0, 0.0);
        s.disks.vel[1] = DVec2::new(-1.0, 0.0);
        let Some(mut g) = gpu_or_skip("head-on", &s, gpu_params(method)) else {
            return;
        };
        g.run(1, &Loading::default()).unwrap();
        let out = g.scene().unwrap();
        // Expected 0.5 m/s; f32 arithmetic on O(1) velocities: a few ulp (6e-8) plus the
        // solver's 1e-6 relative stop.
        for k in 0..2 {
            let v = out.disks.vel[k];
            assert!((v.x - 0.5).abs() < 1e-5, "{method:?}: v{k} = {v}");
            assert_eq!(v.y, 0.0);
        }
    }
}
