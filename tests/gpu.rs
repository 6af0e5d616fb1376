//! GPU path checks (docs/validation.md, "Cross-checks between the two backends").
//!
//! The shader test needs no adapter. The others run on any adapter wgpu finds
//! (`Backends::all()`; set `WGPU_BACKEND=vulkan` to pick Mesa's lavapipe on a machine
//! without a GPU) and skip with a visible `SKIPPED (no GPU adapter)` line otherwise,
//! unless `CDLAB_REQUIRE_GPU` is true (`1`, `true`, `yes`, `on`: CI), in which case a
//! missing adapter fails the test. Any other GPU error fails the test in every case.

use std::path::Path;

mod common;
#[path = "gpu_support/mod.rs"]
mod gpu_support;

use cdlab::backend::reduce::strip_members;
use cdlab::backend::{Backend, CpuBackend, Loading};
use cdlab::engine::CpuEngine;
use cdlab::model::Scene;
use cdlab::solver::Method;
use common::*;
use glam::DVec2;
use gpu_support::*;

/// Every WGSL file in `shaders/` parses and validates through naga, composed the way the
/// pipelines compose it (`common.wgsl` first). Iterates the directory, so a new shader is
/// covered without touching this test.
#[test]
fn every_shader_parses_and_validates() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
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
        // common.wgsl is composed with no phase after it: it needs the generated constants
        // in front of it, as every phase does.
        let source = cdlab::gpu::compose(if name == "common.wgsl" { "" } else { &own });
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

/// The random cloud of the contact-set and grid tests: near-touching disks on a jittered
/// square lattice (gpu_support::lattice), gaps spread over [-0.01, 0.03] m around the alert
/// distance (0.01 m), some overlapping, some beyond it. 576 disks: each prefix sum of the
/// detection and coloring (cells, disks, bodies) and the grid's bounds span several blocks
/// of 256, the pieces shaders/scan.wgsl and shaders/grid.wgsl cut them into.
fn random_cloud() -> Scene {
    lattice(24, 7)
}

#[test]
fn gpu_contact_set_equals_cpu_on_a_random_cloud() {
    compare_contact_sets("random cloud", &random_cloud());
}

#[test]
fn gpu_grid_bounds_every_disk_centre() {
    // The grid's box is the centres' box, to the bit: the origin at the lowest x and y of
    // the high words the device holds, and as many cells as the highest need at the
    // sizing rule of shaders/grid.wgsl (the cell is the largest diameter plus the alert
    // distance here: the capacity, four cells per disk, leaves room).
    let s = random_cloud();
    let params = gpu_params(Method::ColoredGs);
    let Some(mut g) = gpu_or_skip("grid bounds", &s, params) else {
        return;
    };
    let disks = g.raw_disks().unwrap();
    g.run(1, &Loading::default()).unwrap();
    let [ox, oy, cell, nx, ny] = g.raw_grid().unwrap();
    let (ox, oy, cell) = (f32::from_bits(ox), f32::from_bits(oy), f32::from_bits(cell));
    let lo = |f: fn(&cdlab::gpu::buffers::GpuDisk) -> f32| disks.iter().map(f).fold(f32::INFINITY, f32::min);
    let hi =
        |f: fn(&cdlab::gpu::buffers::GpuDisk) -> f32| disks.iter().map(f).fold(f32::NEG_INFINITY, f32::max);
    assert_eq!((ox, oy), (lo(|d| d.x), lo(|d| d.y)), "grid origin");
    let r_max = disks.iter().map(|d| d.radius).fold(0.0f32, f32::max);
    let expected_cell = 2.0 * r_max + params.alert as f32;
    assert_eq!(cell, expected_cell, "cell side");
    let count = |ext: f32| (ext / cell) as u32 + 1;
    assert_eq!(nx, count(hi(|d| d.x) - ox), "cells along x");
    assert_eq!(ny, count(hi(|d| d.y) - oy), "cells along y");
}

#[test]
fn gpu_contact_set_equals_cpu_on_a_dense_packing() {
    // A hexagonal packing of equal disks in contact (every pair at gap 0 or 2 r (sqrt3-1)),
    // with glued and fixed disks so that every ownership rule is exercised.
    let mut s = hex(12, 14);
    for k in 0..14 {
        s.disks.glue(k, 0);
    }
    s.disks.set_kind(20, cdlab::model::BodyKind::Fixed);
    compare_contact_sets("dense packing", &s);
}

#[test]
fn gpu_step_matches_cpu_impulses_and_velocities() {
    for method in [Method::ColoredGs, Method::Jacobi] {
        step_matches_cpu(method);
    }
}

fn step_matches_cpu(method: Method) {
    let s = lattice(12, 11);
    let params = gpu_params(method);
    let Some(mut g) = gpu_or_skip("one step", &s, params) else {
        return;
    };
    g.conv_every = 1;
    let red = g.run(1, &Loading::default()).unwrap();
    let mut cpu = CpuEngine::new(tight(Method::ColoredGs)).unwrap();
    let mut sc = s.clone();
    let cpu_stats = cpu.step(&mut sc).unwrap();
    let mut want: Vec<_> = cpu
        .contacts()
        .iter()
        .map(|c| ((c.i, c.disk_j), (c.rn, c.rt)))
        .collect();
    want.sort_by_key(|e| e.0);
    let got = g.contacts().unwrap();
    let dt = params.dt;
    let r_scale = want.iter().map(|e| e.1.0).fold(0.0, f64::max);
    assert!(r_scale > 0.0, "no impulse to compare");
    // Per contact, each component within a band relative to its own value: both solve the
    // same contact problem, the CPU to 1e-12 in f64, the GPU to a relative change of 1e-6
    // in f32. Measured (lavapipe) on the loaded contacts (impulses 7 to 335 N s/m, the
    // smallest 7% of the largest): worst relative error 1.1e-7 colored GS, 6.1e-7 Jacobi
    // (normal 5.5e-7, tangential 6.1e-7); band 5e-6, 8 times Jacobi's. The absolute floor,
    // 1e-7 of the largest impulse (f32 round-off at that scale), is where a relative error
    // stops meaning anything: the open contacts, exactly 0 on both sides here.
    let (rel, floor) = (5e-6, 1e-7 * r_scale);
    assert_eq!(got.len(), want.len());
    let (mut worst, mut worst_rel, mut loaded) = (0.0f64, 0.0f64, 0);
    for (c, ((i, j), (rn, rt))) in got.iter().zip(&want) {
        assert_eq!((c.i, c.j), (*i, *j));
        let (gn, gt) = (c.f_n * dt, c.f_t * dt);
        for (g, r) in [(gn, *rn), (gt, *rt)] {
            let e = (g - r).abs();
            worst = worst.max(e);
            if r.abs() > floor {
                worst_rel = worst_rel.max(e / r.abs());
            }
            assert!(
                e <= rel * r.abs() + floor,
                "contact {i}-{j}: GPU ({gn}, {gt}) CPU ({rn}, {rt})"
            );
        }
        loaded += usize::from(rn.abs() > floor);
    }
    // Not vacuous: the step loads 4 contacts (the rest stay open). A GPU friction of 0.2999
    // instead of 0.3 (a scratch edit, run once) moves a sliding contact's tangential
    // impulse by 0.017 of 49.9 and fails here; the old band, 1e-4 of the largest impulse
    // (0.034), let it pass.
    assert!(loaded >= 4, "only {loaded} loaded contacts");
    let out = g.scene().unwrap();
    let v_scale = sc.disks.vel.iter().map(|v| v.length()).fold(0.0, f64::max);
    let mut worst_v = 0.0f64;
    for k in 0..s.disks.len() {
        let dv = (out.disks.vel[k] - sc.disks.vel[k]).length();
        let dw = (out.disks.spin[k] - sc.disks.spin[k]).abs();
        worst_v = worst_v.max(dv).max(dw);
        // Same reasoning, on velocities of order 0.1 m/s.
        assert!(
            dv < 1e-4 * v_scale && dw < 1e-4 * v_scale,
            "disk {k}: dv {dv}, dw {dw}"
        );
    }
    eprintln!(
        "one step ({method:?}): {} contacts ({loaded} loaded), {} iterations (CPU {}), worst impulse \
         error {:.2e} of {:.2e} (relative {:.2e}), worst velocity error {:.2e} of {:.2e}",
        got.len(),
        red.iterations_sum,
        cpu_stats.solve.iterations,
        worst,
        r_scale,
        worst_rel,
        worst_v,
        v_scale
    );
}

/// The GPU's Jacobi stops on the same test as the CPU's: the change divided by
/// `jacobi_relax` (docs/method.md, "Jacobi"). At tolerance 1e-4 and relaxation 0.2,
/// checked every iteration, both stop within one iteration of each other (f32 against f64
/// round-off near the threshold); a GPU testing the relaxed change (0.2 times the
/// unrelaxed one) stops several iterations sooner.
#[test]
fn gpu_jacobi_stops_on_the_cpus_test() {
    let s = lattice(12, 11);
    let mut params = gpu_params(Method::Jacobi);
    params.solver.tol = 1e-4;
    params.solver.jacobi.relax = 0.2;
    let Some(mut g) = gpu_or_skip("jacobi stopping test", &s, params) else {
        return;
    };
    g.conv_every = 1;
    let red = g.run(1, &Loading::default()).unwrap();
    let mut cpu = CpuEngine::new(params).unwrap();
    let mut sc = s.clone();
    let cpu_it = cpu.step(&mut sc).unwrap().solve.iterations as i64;
    let gpu_it = red.iterations_sum as i64;
    eprintln!("jacobi to 1e-4: GPU {gpu_it} iterations, CPU {cpu_it}");
    assert!(
        cpu_it > 10,
        "too easy a problem to tell the tests apart: {cpu_it} iterations"
    );
    assert!(
        (gpu_it - cpu_it).abs() <= 1,
        "GPU {gpu_it} iterations, CPU {cpu_it}"
    );
}

#[test]
fn gpu_reductions_equal_cpu_sums_of_the_same_contacts() {
    // A hexagonal pile under gravity between side walls: every contact carries force.
    let mut s = hex(8, 10);
    s.gravity = DVec2::new(0.0, -G);
    s.walls
        .push(cdlab::model::Wall::fixed(DVec2::new(-0.5, 0.0), DVec2::X));
    s.walls
        .push(cdlab::model::Wall::fixed(DVec2::new(10.0, 0.0), -DVec2::X));
    let Some(mut g) = gpu_or_skip("reductions", &s, gpu_params(Method::ColoredGs)) else {
        return;
    };
    let red = g.run(5, &Loading::default()).unwrap();
    let out = g.scene().unwrap();
    let raw = g.raw_contacts().unwrap();
    let contacts: Vec<_> = raw.iter().map(cdlab::gpu::backend::to_contact).collect();
    // The CPU reduction of the GPU's own last state and contacts.
    let dt = g.params().dt;
    let cpu = {
        let mut acc = cdlab::backend::reduce::Accumulator::new(&out);
        acc.add_step(&Default::default(), &vec![DVec2::ZERO; out.walls.len()]);
        acc.finish(&out, &contacts, dt, &Loading::default())
    };
    assert_eq!(red.candidates, cpu.candidates);
    assert_eq!(red.rolling, cpu.rolling);
    assert_eq!(red.sliding, cpu.sliding);
    assert_eq!(red.zero_force, cpu.zero_force);
    assert!((red.coordination - cpu.coordination).abs() < 1e-12);
    assert!((red.isolated_fraction - cpu.isolated_fraction).abs() < 1e-12);
    // Float sums: f32 tree sums of O(100) terms, relative error ~ 1e-6.
    let close = |a: f64, b: f64, what: &str| {
        assert!(
            (a - b).abs() <= 1e-5 * b.abs().max(1e-30),
            "{what}: GPU {a}, CPU {b}"
        )
    };
    close(red.overlap_mean, cpu.overlap_mean, "overlap mean");
    close(red.overlap_max, cpu.overlap_max, "overlap max");
    close(red.kinetic_energy, cpu.kinetic_energy, "kinetic energy");
    close(
        red.translational_energy,
        cpu.translational_energy,
        "translational kinetic energy",
    );
    close(
        red.connected_energy,
        cpu.connected_energy,
        "kinetic energy of connected disks",
    );
    assert!(cpu.connected_energy > 0.0 && cpu.connected_energy <= cpu.translational_energy);
    // Wall force of the last step: the run's average differs, so compare the last step's
    // impulse on a one-step run from the same state.
    let mut g1 = gpu_or_skip("reductions", &out, gpu_params(Method::ColoredGs)).unwrap();
    let red1 = g1.run(1, &Loading::default()).unwrap();
    let c1: Vec<_> = g1
        .raw_contacts()
        .unwrap()
        .iter()
        .map(cdlab::gpu::backend::to_contact)
        .collect();
    let nd = out.disks.len();
    for (w, f) in red1.wall_force.iter().enumerate() {
        let mut p = DVec2::ZERO;
        for c in c1.iter().filter(|c| c.j as usize == nd + w) {
            p -= c.rn * c.n + c.rt * cdlab::contact::tangent(c.n);
        }
        let want = p / dt;
        assert!(
            (*f - want).length() <= 1e-5 * want.length().max(1.0),
            "wall {w}: {f} vs {want}"
        );
    }
    assert!(red.candidates > 100 && red.rolling + red.sliding > 10, "{red:?}");
}

#[test]
fn gpu_confined_run_wall_forces_follow_the_cpu_curve() {
    // 196 disks in a box under gravity, settling: the floor's reaction rises to the weight,
    // and disks thrown against the side walls (walls 2 and 3) slide down them, each impact
    // a reaction whose tangential component is friction (mu = 0.3 times the normal one).
    let mut s = lattice(14, 5);
    s.gravity = DVec2::new(0.0, -G);
    let weight: f64 = s.disks.mass.iter().sum::<f64>() * G;
    let mut p = tight(Method::ColoredGs);
    p.solver.tol = 1e-4;
    p.solver.max_iter = 1000;
    let Some(mut g) = gpu_or_skip("confined run", &s, p) else {
        return;
    };
    let mut c = CpuBackend::new(s.clone(), p).unwrap();
    let t0 = std::time::Instant::now();
    let (chunks, per) = (10, 20u32);
    let mut curves = Vec::new();
    for _ in 0..chunks {
        let rg = g.run(per, &Loading::default()).unwrap();
        let rc = c.run(per, &Loading::default()).unwrap();
        curves.push((rg.wall_force, rc.wall_force));
    }
    let elapsed = t0.elapsed();
    let k = g.counters();
    eprintln!(
        "confined run: {} steps, per step {:.1} dispatches, {:.2} submissions, {:.2} readbacks, \
         {:.1} iterations; GPU+CPU wall time {:.2?}",
        k.steps,
        k.dispatches as f64 / k.steps as f64,
        k.submissions as f64 / k.steps as f64,
        k.readbacks as f64 / k.steps as f64,
        k.iterations as f64 / k.steps as f64,
        elapsed
    );
    // Every wall's mean reaction over each chunk of 20 steps, both components (N/m), the
    // GPU's against the CPU's. The floor's normal component alone is fixed by momentum
    // balance whatever the contact law; the tangential components (the side walls' vertical
    // ones above all: 1.8e3 to 4.6e4 N/m here, 0.300 of their normal component in every
    // chunk) are friction, and the side walls' normal ones the pile's lateral push.
    // Measured (lavapipe, f32 colored GS against f64 colored GS): worst 20.4 N/m on a
    // side wall (its normal component in chunks 0 and 1, one impulse counted in
    // neighbouring chunks: +20.4 then -20.4) and 64.7 N/m on the floor's normal component
    // (4e-6 of the weight, 1.55e7 N/m; 6e-6 of that chunk's 1.09e7 N/m). Band: 100 N/m plus
    // 2e-5 of the wall's CPU reaction, about 5 times either. A GPU friction of 0.29 instead
    // of 0.3 (a scratch edit, run once) puts the floor's tangential reaction 132 N/m and the
    // side walls' 67 to 1520 N/m off (0.2: 1320 N/m, 615 to 15,200 N/m) and fails it.
    let mut worst = 0.0f64;
    for (kk, (fg, fc)) in curves.iter().enumerate() {
        assert_eq!(fg.len(), 4);
        for (w, (a, b)) in fg.iter().zip(fc).enumerate() {
            let d = *a - *b;
            worst = worst.max(d.x.abs()).max(d.y.abs());
            let band = 100.0 + 2e-5 * b.length();
            assert!(
                d.x.abs() < band && d.y.abs() < band,
                "chunk {kk}, wall {w}: GPU {a}, CPU {b} (band {band:.0} N/m)"
            );
        }
        eprintln!(
            "  chunk {kk}: floor {:.4e}, side walls ({:.4e}, {:.4e}) ({:.4e}, {:.4e}) N/m on \
             the GPU (weight {weight:.4e})",
            fg[0].y, fg[2].x, fg[2].y, fg[3].x, fg[3].y
        );
    }
    // Not vacuous: both side walls are hit and carry friction during the run.
    for w in [2, 3] {
        let t = curves.iter().map(|(_, fc)| fc[w].y.abs()).fold(0.0, f64::max);
        assert!(t > 1e4, "side wall {w}: largest tangential reaction {t} N/m");
    }
    // The pile's final positions: measured 7.2e-7 m apart at most (lavapipe); band 5e-6 m,
    // 7 times that. A GPU friction of 0.29 moves them up to 7.3e-5 m apart, 0.2 7.3e-4 m.
    let (sg, sc) = (g.scene().unwrap(), c.scene().unwrap());
    let dx = (0..sg.disks.len())
        .map(|k| (sg.disks.pos[k] - sc.disks.pos[k]).length())
        .fold(0.0, f64::max);
    eprintln!("  worst wall force difference {worst:.3e} N/m, worst position difference {dx:.3e} m");
    assert!(dx < 5e-6, "positions differ by up to {dx} m");
}

#[test]
fn gpu_grows_an_overflowing_slot_list_and_redoes_the_step() {
    // A large disk ringed by 40 small ones within the alert distance: disk 0 owns 40
    // pairs, more than the 12 slots a disk starts with.
    let mut s = scene(0.3);
    let (big, small) = (5.0, 0.35);
    s.disks.push(DVec2::ZERO, big, RHO).unwrap();
    for k in 0..40 {
        let a = k as f64 * std::f64::consts::TAU / 40.0;
        let d = big + small + 0.002;
        s.disks
            .push(d * DVec2::new(a.cos(), a.sin()), small, RHO)
            .unwrap();
        s.disks.vel[k + 1] = -0.1 * DVec2::new(a.cos(), a.sin());
    }
    let params = gpu_params(Method::ColoredGs);
    let Some(mut g) = gpu_or_skip("overflow", &s, params) else {
        return;
    };
    let k0 = g.capacity().k_slots;
    g.run(1, &Loading::default()).unwrap();
    assert!(g.capacity().k_slots >= 40 && k0 < 40, "{:?}", g.capacity());
    assert!(g.counters().redone >= 1);
    assert!(g.counters().redone_capacity >= 1, "{:?}", g.counters());
    let gpu = pairs(g.contacts().unwrap().iter().map(|c| (c.i, c.j)));
    let mut cpu = CpuEngine::new(params).unwrap();
    let mut sc = s.clone();
    cpu.step(&mut sc).unwrap();
    let cpu = pairs(cpu.contacts().iter().map(|c| (c.i, c.disk_j)));
    // Expected: nothing dropped, the same 80 pairs (ring neighbours and spokes) as the CPU.
    assert_eq!(gpu, cpu);
}

#[test]
fn gpu_runs_are_reproducible() {
    // Every sum on the device runs in a fixed order (sorted incidence lists, per-contact
    // norms reduced by index): two runs from the same state agree bit for bit.
    let mut s = lattice(8, 9);
    s.gravity = DVec2::new(0.0, -G);
    let params = gpu_params(Method::ColoredGs);
    let Some(mut a) = gpu_or_skip("reproducible", &s, params) else {
        return;
    };
    let mut b = gpu_or_skip("reproducible", &s, params).unwrap();
    a.run(30, &Loading::default()).unwrap();
    b.run(30, &Loading::default()).unwrap();
    let (sa, sb) = (a.scene().unwrap(), b.scene().unwrap());
    assert_eq!(sa.disks.pos, sb.disks.pos);
    assert_eq!(sa.disks.vel, sb.disks.vel);
}

#[test]
fn gpu_overlap_limit_holds_beside_an_exactly_touching_pair() {
    // Two disks touching exactly (gap 0.0 in f32: integer coordinates once centred on
    // (-3, 5.9)) and two overlapping by 0.2 m, four times the limit (0.05 m, `tight`).
    let mut s = scene(0.3);
    for (x, y) in [(-6.0, 0.0), (-4.0, 0.0), (0.0, 10.0), (0.0, 11.8)] {
        s.disks.push(DVec2::new(x, y), 1.0, RHO).unwrap();
    }
    let Some(mut g) = gpu_or_skip("overlap limit", &s, gpu_params(Method::ColoredGs)) else {
        return;
    };
    // Expected: the step stops on the 0.2 m overlap. The zero gap's -0.0 once outranked it
    // in the device's running maximum (as u32 bits), and the step went on.
    let e = g
        .run(1, &Loading::default())
        .expect_err("a 0.2 m overlap exceeds 0.05 m");
    assert!(
        matches!(e, cdlab::Error::Numerical { .. }) && e.to_string().contains("overlap 2.0"),
        "{e}"
    );
}

/// The work of a step follows the structure documented in src/gpu/step.rs: one submission
/// per step and one wait per run of steps, whatever the iterations; dispatches with work:
/// 20 fixed ones and one per recorded coloring round before the solve, per iteration one
/// per color of more than 64 contacts and one for the smaller colors together (at most one
/// per color; one in all past the typical count), plus one convergence test per block of `conv_every` iterations that ran, 3
/// after it and 1 for the reductions. The blocks recorded past the solve's end launch
/// no workgroup and are counted apart. A step that waits on the host inside the solve, or
/// sweeps a color that is not there, fails here. Wall time is printed, not asserted.
#[test]
fn gpu_work_per_step_follows_the_step_structure() {
    let mut s = lattice(16, 13);
    s.gravity = DVec2::new(0.0, -G);
    let mut p = tight(Method::ColoredGs);
    p.solver.tol = 1e-4;
    p.solver.max_iter = 1000;
    // No change of relaxation inside the iterations, so every block but the last is
    // conv_every long (the relaxation change also ends a block).
    p.solver.gauss_seidel.relax_after = 0;
    let Some(mut g) = gpu_or_skip("work counts", &s, p) else {
        return;
    };
    let ce = g.conv_every as u64;
    assert!(ce > 1, "conv_every {ce}: the blocks would not be tested");
    g.run(5, &Loading::default()).unwrap();
    let t0 = std::time::Instant::now();
    let mut checked = 0;
    let mut blocked = 0;
    for step in 0..20 {
        let k0 = g.counters();
        let red = g.run(1, &Loading::default()).unwrap();
        let k = g.counters();
        let d = |a: u64, b: u64| a - b;
        if k.redone > k0.redone {
            continue; // a capacity or a margin grew: the step was run twice
        }
        let it = d(k.iterations, k0.iterations);
        assert!(
            it > 0 && it <= p.solver.max_iter as u64,
            "step {step}: {it} iterations"
        );
        // Convergence is tested only at the end of a block: a multiple of conv_every, or
        // the cap.
        assert!(
            it % ce == 0 || it == p.solver.max_iter as u64,
            "step {step}: {it} iterations, not a whole number of blocks of {ce}"
        );
        let blocks = it.div_ceil(ce);
        blocked += (blocks > 1) as u32;
        // One wait (the history) and one submission, whatever the blocks.
        assert_eq!(d(k.readbacks, k0.readbacks), 1, "step {step}");
        assert_eq!(d(k.submissions, k0.submissions), 1, "step {step}");
        let colors = red.colors_mean.round() as u64;
        assert_eq!(red.colors_mean, colors as f64);
        assert!(colors >= 2, "step {step}: {colors} colors for a lattice");
        let rounds = d(k.color_rounds, k0.color_rounds);
        let sweeps = d(k.sweep_dispatches, k0.sweep_dispatches);
        // Iterations past the typical count are one sweep_all each, the others one
        // dispatch per large color and one for the small ones.
        assert!(
            sweeps >= it && sweeps <= it * colors,
            "step {step}: {sweeps} sweep dispatches for {it} iterations over {colors} colors"
        );
        let recorded = d(k.dispatches, k0.dispatches) - (20 + sweeps + blocks + 3 + 1);
        // Rounds recorded: those the coloring needed and a margin (the hint), never fewer.
        assert!(
            recorded >= rounds.max(1) && recorded <= g.capacity().rounds as u64,
            "step {step}: {recorded} coloring dispatches for {rounds} rounds"
        );
        // The margin of blocks and colors recorded is launched empty.
        assert!(
            d(k.empty_dispatches, k0.empty_dispatches) > 0,
            "step {step}: no margin"
        );
        checked += 1;
    }
    assert!(checked >= 15, "only {checked} steps without a redo");
    assert!(
        blocked > 0,
        "no step needed more than one block: the blocks were not tested"
    );
    let k = g.counters();
    eprintln!(
        "{} disks: {:.2} ms per step on {} (wall time, printed only); per step {:.1} dispatches \
         ({:.1} empty), {:.2} submissions, {:.2} readbacks, {:.1} iterations",
        s.disks.len(),
        t0.elapsed().as_secs_f64() * 1e3 / 20.0,
        g.name(),
        k.dispatches as f64 / k.steps as f64,
        k.empty_dispatches as f64 / k.steps as f64,
        k.submissions as f64 / k.steps as f64,
        k.readbacks as f64 / k.steps as f64,
        k.iterations as f64 / k.steps as f64,
    );
}

/// A window of steps waits once, however many steps it holds: 10 steps, one submission
/// each, one readback.
#[test]
fn gpu_window_waits_once() {
    let mut s = lattice(16, 13);
    s.gravity = DVec2::new(0.0, -G);
    let mut p = tight(Method::ColoredGs);
    p.solver.tol = 1e-4;
    p.solver.max_iter = 1000;
    let Some(mut g) = gpu_or_skip("one wait per window", &s, p) else {
        return;
    };
    g.run(5, &Loading::default()).unwrap();
    let k0 = g.counters();
    g.run(10, &Loading::default()).unwrap();
    let k = g.counters() - k0;
    assert_eq!(k.steps, 10);
    assert_eq!((k.redone, k.readbacks, k.submissions), (0, 1, 10), "{k:?}");
}

/// Every capacity that can overflow grows, and the step redone after the growth gives the
/// CPU's contacts: a lattice of 100 disks whose alert distance (8 m, radius 1 m) makes every
/// disk a candidate partner of about 45 others, far beyond the starting capacities (12
/// slots per disk, 4 contacts per disk + 256 + 16 per wall, 64 colors, 32 coloring rounds).
/// The grid's cells do not grow: the kernel enlarges the cells to fit the capacity instead.
#[test]
fn gpu_grows_contacts_slots_colors_and_rounds_and_matches_the_cpu() {
    let s = lattice(10, 21);
    let mut p = gpu_params(Method::ColoredGs);
    p.alert = 8.0;
    p.solver.tol = 1e-4;
    p.solver.max_iter = 50;
    let Some(mut g) = gpu_or_skip("growth", &s, p) else {
        return;
    };
    let c0 = g.capacity();
    g.run(1, &Loading::default()).unwrap();
    let c1 = g.capacity();
    let gpu = pairs(g.contacts().unwrap().iter().map(|c| (c.i, c.j)));
    let mut cpu = CpuEngine::new(p).unwrap();
    let mut sc = s.clone();
    cpu.step(&mut sc).unwrap();
    let cpu = pairs(cpu.contacts().iter().map(|c| (c.i, c.disk_j)));
    eprintln!(
        "capacities {c0:?} -> {c1:?}; {} contacts, {} steps redone",
        gpu.len(),
        g.counters().redone
    );
    assert_eq!(gpu, cpu, "the GPU's candidate pairs after growth");
    assert!(
        gpu.len() as u32 > c0.contacts,
        "the scene does not overflow the contacts"
    );
    assert!(
        c1.contacts >= gpu.len() as u32 && c1.contacts > c0.contacts,
        "{c0:?} -> {c1:?}"
    );
    assert!(c1.k_slots > c0.k_slots, "slots {c0:?} -> {c1:?}");
    assert!(c1.colors > c0.colors, "colors {c0:?} -> {c1:?}");
    assert!(c1.rounds > c0.rounds, "rounds {c0:?} -> {c1:?}");
    assert!(g.counters().redone >= 1);
    // The windows run again are counted under what they lacked: capacities grew, and the
    // coloring needed more rounds than recorded.
    let k = g.counters();
    assert!(k.redone_capacity >= 1 && k.redone_rounds >= 1, "{k:?}");
    assert!(
        k.redone_capacity <= k.redone && k.redone_rounds <= k.redone,
        "{k:?}"
    );
    // A second step reuses the grown buffers: nothing redone.
    let redone = g.counters().redone;
    g.run(1, &Loading::default()).unwrap();
    assert_eq!(g.capacity(), c1);
    assert_eq!(g.counters().redone, redone, "a second step needed another growth");
}

/// A resumed run continues from the checkpoint's impulses on the GPU too
/// (`Backend::set_warm_start`, written into the layout the GPU's detection reads back,
/// shaders/detect.wgsl). A pile of 64 disks settled under gravity on the CPU: one GPU step
/// from its contacts' impulses must be the CPU's own next step from them; from zero
/// impulses (what a resumed GPU run used to do) the same step needs many more iterations.
#[test]
fn gpu_resume_continues_from_the_warm_start() {
    let mut s = cloud(8, 8, 0.0, 7);
    s.gravity = DVec2::new(0.0, -G);
    add_box(&mut s, -1.5, 17.0, -1.5, 40.0);
    let mut params = gpu_params(Method::ColoredGs);
    params.dt = 2e-3;
    params.solver.tol = 1e-4;
    let mut cpu = CpuBackend::new(s, params).unwrap();
    cpu.run(400, &Loading::default()).unwrap();
    let (settled, warm) = (cpu.scene().unwrap(), cpu.contacts().unwrap());
    let scale = warm.iter().map(|c| c.rn).fold(0.0, f64::max);
    assert!(scale > 0.0, "the pile carries its weight");
    let key = |c: &cdlab::backend::ContactRecord| (c.i, c.j);
    let before: std::collections::HashMap<_, _> = warm.iter().map(|c| (key(c), (c.rn, c.rt))).collect();
    // The largest change of an impulse over one step, relative to the largest impulse.
    let moved = |after: &[cdlab::backend::ContactRecord]| {
        after
            .iter()
            .map(|c| {
                let (rn, rt) = before.get(&key(c)).copied().unwrap_or((0.0, 0.0));
                (c.rn - rn).abs().max((c.rt - rt).abs())
            })
            .fold(0.0, f64::max)
            / scale
    };
    let step = |warm_start: bool| {
        let mut g = gpu_or_skip("resume", &settled, params)?;
        g.conv_every = 1;
        if warm_start {
            g.set_warm_start(&warm).unwrap();
        }
        let red = g.run(1, &Loading::default()).unwrap();
        Some((red.iterations_sum, moved(&g.contacts().unwrap())))
    };
    let (Some((warm_it, warm_moved)), Some((cold_it, cold_moved))) = (step(true), step(false)) else {
        return;
    };
    cpu.set_warm_start(&warm).unwrap();
    let cpu_red = cpu.run(1, &Loading::default()).unwrap();
    let cpu_moved = moved(&cpu.contacts().unwrap());
    eprintln!(
        "one step after the settled state: GPU with the warm start {warm_it} iterations, moved {warm_moved:.2e}; \
         from zero {cold_it} iterations, moved {cold_moved:.2e}; CPU {} iterations, moved {cpu_moved:.2e}",
        cpu_red.iterations_sum
    );
    // The same step as the CPU's from the same warm start: as many iterations (within one,
    // f32 round-off at the threshold) and the same largest change of an impulse (within
    // 10%: the f32 solve against the f64 one, both at tolerance 1e-4).
    let cpu_it = cpu_red.iterations_sum;
    assert!(
        warm_it.abs_diff(cpu_it) <= 1,
        "GPU {warm_it} iterations, CPU {cpu_it}"
    );
    assert!(
        (warm_moved - cpu_moved).abs() <= 0.1 * cpu_moved,
        "GPU moved {warm_moved:.2e}, CPU {cpu_moved:.2e}"
    );
    assert!(
        cold_it > 2 * warm_it,
        "from zero: {cold_it} iterations; warm: {warm_it}"
    );
}

/// The strips' outer edges come from the device (reduce.wgsl, `outline_sum`) and equal the
/// CPU twin's (`backend::reduce::strip_outer_edges`) on the same positions: a jittered
/// lattice with its two outer columns as strips, one step, then the CPU's edges of the
/// positions the GPU reached. The window waits once: no scene download for the edges.
#[test]
fn gpu_strip_members_found_on_the_device_equal_the_scenes() {
    // A refresh of the strips on the GPU reads back one word per disk, not the scene, and
    // must find the members backend::reduce::strip_members finds in the scene: an
    // irregular side (radii 0.4 to 0.7 m on a lattice of pitch 2 m, centres moved by up to
    // 0.3 m), a strip 2.6 m thick that cuts through the second column and the second last.
    let mut rng = Rng(11);
    let mut s = scene(0.3);
    let n = 20;
    for a in 0..n {
        for b in 0..n {
            let p = DVec2::new(
                2.0 * a as f64 + rng.range(-0.3, 0.3),
                2.0 * b as f64 + rng.range(-0.3, 0.3),
            );
            s.disks.push(p, rng.range(0.4, 0.7), RHO).unwrap();
        }
    }
    add_box(&mut s, -1.0, 2.0 * n as f64 - 1.0, -1.0, 2.0 * n as f64 - 1.0);
    let t = 2.6;
    let (bottom, top) = (0, 1);
    let params = gpu_params(Method::ColoredGs);
    let Some(mut g) = gpu_or_skip("strip members", &s, params) else {
        return;
    };
    let first = strip_members(&s, bottom, top, t);
    let loading = Loading {
        sigma3: 1.0e3,
        strip: first.clone(),
        top,
        bottom,
        wall_forces: Vec::new(),
    };
    g.run(3, &loading).unwrap();
    let k0 = g.counters();
    let device = g.strip_members(bottom, top, t).unwrap();
    assert_eq!((g.counters() - k0).readbacks, 1, "a refresh reads back once");
    let scene = g.scene().unwrap();
    let cpu = strip_members(&scene, bottom, top, t);
    let side = |m: &[i8], v: i8| m.iter().filter(|&&x| x == v).count();
    // Both strips hold the first or last column and part of the next one.
    for v in [-1, 1] {
        assert!(
            side(&cpu, v) > n && side(&cpu, v) < 2 * n,
            "{} disks in strip {v}",
            side(&cpu, v)
        );
    }
    assert_eq!(device, cpu, "members found on the device and in the scene");
    // The new members go into the disk records' tags, without a scene round trip.
    let mut refreshed = loading.clone();
    refreshed.strip = device.clone();
    refreshed.strip.swap(0, n * n / 2);
    let k1 = g.counters();
    g.run(1, &refreshed).unwrap();
    assert_eq!((g.counters() - k1).readbacks, 1, "the refresh needs no download");
    let tags: Vec<i8> = g.raw_disks().unwrap().iter().map(|d| d.strip as i8).collect();
    assert_eq!(tags, refreshed.strip, "the disk records' tags");
}

#[test]
fn gpu_strip_edges_equal_the_cpu_outline_of_the_same_positions() {
    let n = 14;
    let s = lattice(n, 5);
    let mut p = tight(Method::ColoredGs);
    p.solver.tol = 1e-4;
    p.solver.max_iter = 500;
    let Some(mut g) = gpu_or_skip("strip edges", &s, p) else {
        return;
    };
    // Disks are pushed column by column (a x n + b): the first and last columns.
    let strip: Vec<i8> = (0..n * n)
        .map(|k| match k / n {
            0 => -1,
            a if a == n - 1 => 1,
            _ => 0,
        })
        .collect();
    let loading = Loading {
        sigma3: 1.0e3,
        strip,
        top: 1,
        bottom: 0,
        wall_forces: Vec::new(),
    };
    g.run(2, &loading).unwrap();
    let k0 = g.counters();
    let red = g.run(3, &loading).unwrap();
    assert_eq!((g.counters() - k0).readbacks, 1, "the edges need no download");
    let cpu = cdlab::backend::reduce::strip_outer_edges(&g.scene().unwrap(), &loading);
    // The left strip's disks sit in a column at x = 0, touching, radius about 1: the mean
    // of -sqrt(1 - dy^2) over the heights is -pi/4; the right ones at x = 2 (n - 1).
    let q = std::f64::consts::FRAC_PI_4;
    let right = 2.0 * (n - 1) as f64 + q;
    assert!(
        (cpu[0] + q).abs() < 0.05 && (cpu[1] - right).abs() < 0.05,
        "{cpu:?}"
    );
    for side in 0..2 {
        // f32 positions and outline: a few 1e-6 m here.
        assert!(
            (red.strip_edges[side] - cpu[side]).abs() < 1e-4,
            "side {side}: GPU {:?}, CPU {cpu:?}",
            red.strip_edges
        );
    }
}

/// A window run again after its steps outgrew what was recorded equals the same steps
/// recorded with room to spare, bit for bit: a fresh backend starts with small margins
/// (64 iterations) and runs its first window again on a loaded column of 60 disks, whose
/// steps need hundreds of iterations; one told to reserve enough (`GpuBackend::reserve`)
/// does not; the states after 10 steps agree.
#[test]
fn gpu_window_run_again_equals_one_with_room_to_spare() {
    let s = column(60, 0.5, G, Some(-2.0e4));
    let mut p = tight(Method::ColoredGs);
    p.solver.tol = 1e-6;
    p.solver.max_iter = 2000;
    let Some(mut tight_margins) = gpu_or_skip("window run again", &s, p) else {
        return;
    };
    let mut roomy = gpu_or_skip("window run again", &s, p).unwrap();
    roomy.reserve(2000, 64, 32);
    tight_margins.run(10, &Loading::default()).unwrap();
    roomy.run(10, &Loading::default()).unwrap();
    let (kt, kr) = (tight_margins.counters(), roomy.counters());
    assert!(
        kt.redone >= 1,
        "the small margins were enough: nothing was run again ({kt:?})"
    );
    assert_eq!(kr.redone, 0, "room to spare, yet run again ({kr:?})");
    assert_eq!(kt.iterations, kr.iterations);
    let (a, b) = (tight_margins.scene().unwrap(), roomy.scene().unwrap());
    assert_eq!(a.disks.pos, b.disks.pos);
    assert_eq!(a.disks.vel, b.disks.vel);
    assert_eq!(a.disks.spin, b.disks.spin);
}

/// Two fresh GPU backends on a loaded column of 60 disks whose steps need hundreds of
/// iterations (tolerance 1e-6, cap 2000): more than a fresh backend's margins, so that its
/// windows are run again. `None` without an adapter (the test is skipped).
fn loaded_column_pair(what: &str) -> Option<(cdlab::gpu::GpuBackend, cdlab::gpu::GpuBackend)> {
    let s = column(60, 0.5, G, Some(-2.0e4));
    let mut p = tight(Method::ColoredGs);
    p.solver.tol = 1e-6;
    p.solver.max_iter = 2000;
    let a = gpu_or_skip(what, &s, p)?;
    let b = gpu_or_skip(what, &s, p).unwrap();
    Some((a, b))
}

/// Asserts that two backends hold the same disks, bit for bit.
fn same_disks(a: &mut cdlab::gpu::GpuBackend, b: &mut cdlab::gpu::GpuBackend) {
    let (a, b) = (a.scene().unwrap(), b.scene().unwrap());
    assert_eq!((a.step, a.time), (b.step, b.time));
    assert_eq!(a.disks.pos, b.disks.pos);
    assert_eq!(a.disks.vel, b.disks.vel);
    assert_eq!(a.disks.spin, b.disks.spin);
}

/// Steps recorded by several host threads (`GpuBackend::record_threads`) are the same
/// commands submitted in the same order: three threads, with margins small enough that a
/// window is run again, end in the state of one thread, bit for bit, after windows of 7
/// and 5 steps (more steps than threads, and fewer than two per thread). The backend's
/// account of its activity counts the windows run, run again included.
#[test]
fn gpu_steps_recorded_on_several_threads_equal_one_thread() {
    let Some((mut one, mut three)) = loaded_column_pair("recording threads") else {
        return;
    };
    one.record_threads = 1;
    three.record_threads = 3;
    assert_eq!(three.recording_threads(), 3);
    for steps in [7, 5] {
        one.run(steps, &Loading::default()).unwrap();
        three.run(steps, &Loading::default()).unwrap();
    }
    let (k1, k3) = (one.counters(), three.counters());
    assert!(k3.redone >= 1, "nothing was run again ({k3:?})");
    assert_eq!(k1.iterations, k3.iterations);
    assert_eq!(k3.windows, 2 + k3.redone, "{k3:?}");
    let text = three.activity().unwrap();
    assert!(
        text.contains(&format!("{} windows, {} run again", k3.windows, k3.redone)),
        "{text}"
    );
    same_disks(&mut one, &mut three);
}

/// Iterations past the typical count swept by one workgroup each (`sweep_all`, the
/// default) are the same sweeps as one dispatch per color: on a loaded column whose steps
/// need hundreds of iterations, more than the first window's 64 typical ones, the states
/// agree bit for bit after three windows, with fewer dispatches recorded.
#[test]
fn gpu_sweeps_in_one_workgroup_equal_a_dispatch_per_color() {
    let Some((mut per_color, mut one)) = loaded_column_pair("one-workgroup sweeps") else {
        return;
    };
    per_color.overflow_sweeps = false;
    assert!(one.overflow_sweeps, "sweep_all is not the default");
    for _ in 0..3 {
        per_color.run(6, &Loading::default()).unwrap();
        one.run(6, &Loading::default()).unwrap();
    }
    let (ka, kb) = (per_color.counters(), one.counters());
    assert!(
        kb.iterations > 64 * 18,
        "too few iterations to need sweep_all ({kb:?})"
    );
    assert_eq!(ka.iterations, kb.iterations);
    let recorded = |k: cdlab::gpu::backend::GpuCounters| k.dispatches + k.empty_dispatches;
    assert!(
        recorded(kb) < recorded(ka),
        "sweep_all recorded no fewer dispatches: {} against {}",
        recorded(kb),
        recorded(ka)
    );
    same_disks(&mut per_color, &mut one);
}

/// A fresh backend's first long window is probed with one step whose state is put back
/// (`GpuBackend::probe`): 30 steps in one window end in the state of 10 then 20 steps
/// (windows too short to be probed), bit for bit, at the same time and step, with the
/// probe counted as a window run again and not as a step.
#[test]
fn gpu_margin_swept_in_one_workgroup_equals_a_dispatch_per_color() {
    // The rule of samples above step::ONE_WORKGROUP_CONTACTS (tried here on a small one):
    // a dispatch per color up to the last window's largest count, sweep_all in the margin
    // after it. Bit for bit the sweeps of a dispatch per color, with fewer dispatches.
    let Some((mut per_color, mut margin)) = loaded_column_pair("margin in one workgroup") else {
        return;
    };
    let Some((mut typical, _)) = loaded_column_pair("margin in one workgroup") else {
        return;
    };
    per_color.overflow_sweeps = false;
    margin.one_workgroup_contacts = 0;
    for _ in 0..3 {
        per_color.run(6, &Loading::default()).unwrap();
        margin.run(6, &Loading::default()).unwrap();
        typical.run(6, &Loading::default()).unwrap();
    }
    let (ka, kb, kc) = (per_color.counters(), margin.counters(), typical.counters());
    assert_eq!(ka.iterations, kb.iterations);
    // Fewer dispatches than a dispatch per color everywhere, and no fewer than the small
    // samples' rule, whose sweep_all starts at the mean count (here every step of a window
    // takes the same blocks, so the two rules record the same).
    let recorded = |k: cdlab::gpu::backend::GpuCounters| k.dispatches + k.empty_dispatches;
    assert!(
        recorded(kc) <= recorded(kb) && recorded(kb) < recorded(ka),
        "dispatches recorded: {} (from the mean), {} (from the largest), {} (none in one workgroup)",
        recorded(kc),
        recorded(kb),
        recorded(ka)
    );
    same_disks(&mut per_color, &mut margin);
}

#[test]
fn gpu_first_window_probed_with_one_step_equals_short_windows() {
    let Some((mut probed, mut short)) = loaded_column_pair("probe") else {
        return;
    };
    probed.run(30, &Loading::default()).unwrap();
    short.run(10, &Loading::default()).unwrap();
    short.run(20, &Loading::default()).unwrap();
    let (kp, ks) = (probed.counters(), short.counters());
    assert_eq!(kp.steps, 30, "{kp:?}");
    assert!(kp.redone >= 1 && kp.redone_steps >= 1, "no probe: {kp:?}");
    assert_eq!(kp.iterations, ks.iterations);
    same_disks(&mut probed, &mut short);
}

/// `solver.backend = "auto"` takes the GPU path only on a hardware adapter, only for a
/// method the GPU runs and only from `AUTO_GPU_FROM_DISKS` disks (below, the CPU is faster:
/// docs/gpu.md): on a machine whose only adapter is a software one (CI's lavapipe) it runs
/// on the CPU, on one with a GPU a large sample runs on the GPU and a small one on the CPU
/// with a note naming the GPU; `apgd` runs on the CPU everywhere, without a note.
#[test]
fn auto_backend_takes_the_gpu_only_on_hardware_and_for_large_samples() {
    let hardware = cdlab::gpu::device::list_adapters()
        .iter()
        .any(|a| a.device_type != "Cpu");
    let side = (cdlab::run::AUTO_GPU_FROM_DISKS as f64).sqrt().ceil() as usize;
    let (small, large) = (lattice(4, 3), lattice(side, 3));
    assert!(large.disks.len() >= cdlab::run::AUTO_GPU_FROM_DISKS);
    for (method, gpu_method) in [("colored-gs", true), ("apgd", false)] {
        let text = format!("[solver]\nbackend = \"auto\"\nmethod = \"{method}\"\n");
        let config = cdlab::config::Config::from_toml_str(&text).unwrap();
        let mut p = gpu_params(Method::ColoredGs);
        p.solver.method = method.parse().unwrap();
        for (scene, large_sample) in [(&small, false), (&large, true)] {
            let (b, note) = cdlab::run::open_backend_noted(&config, scene.clone(), p).unwrap();
            let on_gpu = b.name().starts_with("gpu");
            let what = format!(
                "{method}, {} disks: auto chose {} with hardware adapter: {hardware}",
                scene.disks.len(),
                b.name()
            );
            assert_eq!(on_gpu, hardware && gpu_method && large_sample, "{what}");
            // The note is given exactly where a hardware GPU was left unused for size.
            let declined = hardware && gpu_method && !large_sample;
            assert_eq!(note.is_some(), declined, "{what}; note {note:?}");
            if let Some(n) = note {
                assert!(
                    n.contains("--backend gpu") && n.contains(&scene.disks.len().to_string()),
                    "{n}"
                );
            }
        }
    }
}

/// The GPU works relative to the sample's centre: the same sample 500 m from the origin
/// takes the same steps. A settled lattice under gravity, and the same shifted by (500,
/// 500) m with its walls, 30 steps each: the positions differ by the shift to 1e-9 m,
/// the velocities agree to f32 round-off.
#[test]
fn gpu_sample_far_from_the_origin_moves_as_at_the_origin() {
    let mut s = lattice(8, 4);
    s.gravity = DVec2::new(0.0, -G);
    let shift = DVec2::new(500.0, 500.0);
    let mut far = s.clone();
    for p in far.disks.pos.iter_mut() {
        *p += shift;
    }
    for w in far.walls.iter_mut() {
        w.point += shift;
    }
    let p = gpu_params(Method::ColoredGs);
    let Some(mut a) = gpu_or_skip("far from the origin", &s, p) else {
        return;
    };
    let mut b = gpu_or_skip("far from the origin", &far, p).unwrap();
    a.run(30, &Loading::default()).unwrap();
    b.run(30, &Loading::default()).unwrap();
    let (sa, sb) = (a.scene().unwrap(), b.scene().unwrap());
    let moved = (0..sa.disks.len())
        .map(|k| (sa.disks.pos[k] - s.disks.pos[k]).length())
        .fold(0.0, f64::max);
    assert!(
        moved > 1e-3,
        "the lattice did not move ({moved} m): nothing is tested"
    );
    for k in 0..sa.disks.len() {
        let d = (sb.disks.pos[k] - shift - sa.disks.pos[k]).length();
        assert!(d < 1e-9, "disk {k}: {d} m apart after the shift is taken off");
        let dv = (sb.disks.vel[k] - sa.disks.vel[k]).length();
        assert!(dv < 1e-6, "disk {k}: velocities {dv} m/s apart");
    }
}

/// A run of no steps reduces the state as it stands: the same counts and overlaps as the
/// run before it left, and no step taken.
#[test]
fn gpu_run_of_no_steps_reduces_the_state_as_it_stands() {
    let s = column(20, 0.5, G, None);
    let Some(mut g) = gpu_or_skip("no steps", &s, gpu_params(Method::ColoredGs)) else {
        return;
    };
    let last = g.run(5, &Loading::default()).unwrap();
    let none = g.run(0, &Loading::default()).unwrap();
    assert_eq!((none.steps, none.step), (0, last.step));
    assert!(
        last.force_carrying > 0,
        "nothing carries force: nothing is compared"
    );
    assert_eq!(
        (none.force_carrying, none.rolling, none.sliding, none.candidates),
        (last.force_carrying, last.rolling, last.sliding, last.candidates)
    );
    assert_eq!(none.overlap_max, last.overlap_max);
    assert_eq!(none.wall_point, last.wall_point);
}
