//! The WGSL local law, normal offset and Delassus block, run on the device over thousands
//! of random inputs (edge cases included), against their CPU twins `solver::law`,
//! `engine::normal_bias` and `contact::Contact::compute_delassus`. The kernels are the
//! test-only entry points of tests/gpu_kernels.wgsl, composed with the shared shader code
//! and detect.wgsl (where the Delassus block is) exactly as the phase shaders are. Skips
//! visibly without an adapter (see `gpu_support::device_or_skip`).
//!
//! Inputs are drawn in f32 and widened, so both sides see the same numbers and every
//! difference comes from the GPU's f32 arithmetic. Tolerances, with u = 2^-24 the f32 unit
//! round-off: the free velocity `U + bias - W R` is a sum of about six rounded terms, so its
//! error is a few u times the sum of their magnitudes S; solving the 2x2 law multiplies an
//! error in the velocity by at most |W^-1| (max row sum), and a relative error in W by its
//! condition number k; a sliding R_t = mu R_n carries mu times the error of R_n. The bound
//! used is 32 u (S |W^-1| + k |R|) (+ mu times that of R_n for R_t near or at sliding): a
//! factor 4-8 over the worst case of the round-off count, which lavapipe's fused
//! multiply-adds and division stay well inside, while a wrong sign, a wrong case or a
//! swapped field gives errors of order |R| itself.

mod common;
#[path = "gpu_support/mod.rs"]
mod gpu_support;

use cdlab::contact::Contact;
use cdlab::engine::normal_bias;
use cdlab::gpu::buffers::GpuContact;
use cdlab::gpu::device::GpuDevice;
use cdlab::solver::law;
use common::Rng;
use glam::{DVec2, DVec3};
use gpu_support::device_or_skip;

/// f32 unit round-off.
const U: f64 = 1.0 / (1u64 << 24) as f64;

/// A value drawn in f32 (what the device stores), widened for the CPU side.
fn f(x: f64) -> f64 {
    x as f32 as f64
}

/// Runs the probe entry point `entry` over `n` items with the given buffers bound (binding
/// of group 0, bytes) and returns the bytes of binding `out` after the dispatch.
fn run(gpu: &GpuDevice, entry: &str, n: u32, bindings: &[(u32, Vec<u8>)], out: u32) -> Vec<u8> {
    use wgpu::util::DeviceExt;
    let detect = cdlab::gpu::SHADERS
        .iter()
        .find(|(name, _)| *name == "detect.wgsl")
        .expect("detect.wgsl is a phase shader")
        .1;
    let source = cdlab::gpu::compose(&format!("{detect}\n{}", include_str!("gpu_kernels.wgsl")));
    let d = &gpu.device;
    let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("probe"),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    // The layout is derived from the bindings the entry point uses.
    let pipeline = d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: None,
        module: &module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    });
    let buffers: Vec<(u32, wgpu::Buffer)> = bindings
        .iter()
        .map(|(b, bytes)| {
            let buf = d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("probe data"),
                contents: bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            });
            (*b, buf)
        })
        .collect();
    let entries: Vec<_> = buffers
        .iter()
        .map(|(b, buf)| wgpu::BindGroupEntry {
            binding: *b,
            resource: buf.as_entire_binding(),
        })
        .collect();
    let group = d.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("probe"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &entries,
    });
    let src = &buffers.iter().find(|(b, _)| *b == out).expect("output binding").1;
    let staging = d.create_buffer(&wgpu::BufferDescriptor {
        label: Some("probe readback"),
        size: src.size(),
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut enc = d.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(n.div_ceil(cdlab::gpu::WG), 1, 1);
    }
    enc.copy_buffer_to_buffer(src, 0, &staging, 0, src.size());
    gpu.queue.submit([enc.finish()]);
    let (tx, rx) = std::sync::mpsc::channel();
    staging.map_async(wgpu::MapMode::Read, .., move |r| {
        let _ = tx.send(r);
    });
    d.poll(wgpu::PollType::wait_indefinitely()).expect("device poll");
    gpu.check("running a probe kernel").unwrap();
    rx.recv().unwrap().expect("mapping the probe's output");
    let bytes = staging.get_mapped_range(..).unwrap().to_vec();
    staging.unmap();
    bytes
}

/// One local-law case: the contact (CPU form) and the two bodies' velocities.
struct LawCase {
    c: Contact,
    vi: DVec3,
    vj: DVec3,
}

/// Random contacts covering the law's cases: separation, sticking and sliding, diagonal
/// and full Delassus blocks, disk-wall contacts, mu = 0 and mu = 1000, zero velocities and
/// zero previous impulses.
fn law_cases(n: usize, rng: &mut Rng) -> Vec<LawCase> {
    (0..n)
        .map(|k| {
            let cat = k % 8;
            let block = k % 3 == 0;
            let mut c = Contact::default();
            let angle = rng.range(0.0, std::f64::consts::TAU);
            c.n = DVec2::new(f(angle.cos()), f(angle.sin()));
            c.mi = f(rng.range(0.2, 2.0));
            c.ri = f(rng.range(0.5, 1.5));
            c.ki = f(c.ri * rng.range(1.0, 3.0));
            if cat != 2 {
                // Disk-disk; cat 2 is a disk against a kinematic wall (nothing on side j).
                c.mj = f(rng.range(0.2, 2.0));
                c.rj = f(rng.range(0.5, 1.5));
                c.kj = f(c.rj * rng.range(1.0, 3.0));
            }
            if block {
                // A body translating along an oblique axis: W_nt != 0.
                let b = rng.range(0.0, std::f64::consts::TAU);
                c.ma = f(rng.range(0.2, 2.0));
                c.a = DVec2::new(f(b.cos()), f(b.sin()));
            }
            c.compute_delassus();
            (c.wnn, c.wtt, c.wnt) = (f(c.wnn), f(c.wtt), f(c.wnt));
            // Large friction only with the diagonal block: the full block comes from a disk
            // glued to a force-driven wall, with mu <= 1 in every configuration.
            c.mu = match cat {
                0 => 0.0,
                1 if !block => 1000.0,
                _ => f(rng.range(0.05, 1.0)),
            };
            let mut v = || {
                DVec3::new(
                    f(rng.range(-1.0, 1.0)),
                    f(rng.range(-1.0, 1.0)),
                    f(rng.range(-2.0, 2.0)),
                )
            };
            let (vi, vj) = if cat == 3 {
                (DVec3::ZERO, DVec3::ZERO)
            } else {
                (v(), v())
            };
            if cat != 4 {
                c.rn = f(rng.range(0.0, 1.0));
                c.rt = f(rng.range(-1.0, 1.0) * c.mu.min(1.0) * c.rn);
            }
            c.bias_n = if cat == 6 { 5.0 } else { f(rng.range(-1.0, 0.5)) };
            c.bias_t = f(rng.range(-0.5, 0.5));
            LawCase { c, vi, vj }
        })
        .collect()
}

/// The CPU's new impulses for a case: the free velocity as solver/update.rs forms it, then
/// `law::solve`.
fn cpu_law(case: &LawCase) -> (f64, f64) {
    let c = &case.c;
    let (un, ut) = c.relative_velocity_of(case.vi, case.vj);
    let ufn = un - c.wnn * c.rn - c.wnt * c.rt + c.bias_n;
    let uft = ut - c.wnt * c.rn - c.wtt * c.rt + c.bias_t;
    law::solve(c.wnn, c.wtt, c.wnt, ufn, uft, c.mu)
}

fn gpu_contact(c: &Contact) -> GpuContact {
    let g = |x: f64| x as f32;
    GpuContact {
        i: 0,
        j: 1,
        nx: g(c.n.x),
        ny: g(c.n.y),
        ri: g(c.ri),
        rj: g(c.rj),
        mi: g(c.mi),
        mj: g(c.mj),
        ma: g(c.ma),
        ax: g(c.a.x),
        ay: g(c.a.y),
        ki: g(c.ki),
        kj: g(c.kj),
        wnn: g(c.wnn),
        wtt: g(c.wtt),
        wnt: g(c.wnt),
        mu: g(c.mu),
        rn: g(c.rn),
        rt: g(c.rt),
        bias_n: g(c.bias_n),
        bias_t: g(c.bias_t),
        ..Default::default()
    }
}

/// The tolerances on (R_n, R_t) of a case (see the module documentation).
fn law_tolerance(case: &LawCase, (rn, rt): (f64, f64)) -> (f64, f64) {
    let c = &case.c;
    let d = case.vi - case.vj;
    let s_n = (d.x * c.n.x).abs()
        + (d.y * c.n.y).abs()
        + (c.wnn * c.rn).abs()
        + (c.wnt * c.rt).abs()
        + c.bias_n.abs();
    let s_t = (d.x * c.n.y).abs()
        + (d.y * c.n.x).abs()
        + (case.vi.z * c.ri).abs()
        + (case.vj.z * c.rj).abs()
        + (c.wnt * c.rn).abs()
        + (c.wtt * c.rt).abs()
        + c.bias_t.abs();
    let det = c.wnn * c.wtt - c.wnt * c.wnt;
    let w_inv = (c.wtt.abs() + c.wnt.abs()).max(c.wnn.abs() + c.wnt.abs()) / det;
    let w = (c.wnn.abs() + c.wnt.abs()).max(c.wtt.abs() + c.wnt.abs());
    let kappa = w * w_inv;
    let tol_rn = 32.0 * U * ((s_n + s_t) * w_inv + kappa * rn.abs());
    let mut tol_rt = 32.0 * U * ((s_n + s_t) * w_inv + kappa * rt.abs());
    // At or near sliding R_t follows mu R_n and its error.
    if c.mu * rn - rt.abs() <= tol_rt + c.mu * tol_rn {
        tol_rt += c.mu * tol_rn;
    }
    (tol_rn, tol_rt)
}

#[test]
fn gpu_local_law_matches_solver_law() {
    let Some(gpu) = device_or_skip("local law kernel") else {
        return;
    };
    let n = 8192;
    let cases = law_cases(n, &mut Rng(25));
    let contacts: Vec<GpuContact> = cases.iter().map(|c| gpu_contact(&c.c)).collect();
    let vel: Vec<[f32; 4]> = cases
        .iter()
        .flat_map(|c| [c.vi, c.vj].map(|v| [v.x as f32, v.y as f32, v.z as f32, 0.0]))
        .collect();
    let out = vec![0f32; 2 * n];
    let bytes = run(
        &gpu,
        "probe_law",
        n as u32,
        &[
            (3, bytemuck::cast_slice(&vel).to_vec()),
            (5, bytemuck::cast_slice(&contacts).to_vec()),
            (6, bytemuck::cast_slice(&out).to_vec()),
        ],
        6,
    );
    let got: &[f32] = bytemuck::cast_slice(&bytes);
    let (mut separated, mut stuck, mut sliding, mut blocks) = (0, 0, 0, 0);
    let mut worst: f64 = 0.0;
    let mut bad = Vec::new();
    for (k, case) in cases.iter().enumerate() {
        let (rn, rt) = cpu_law(case);
        let (gn, gt) = (got[2 * k] as f64, got[2 * k + 1] as f64);
        let (tn, tt) = law_tolerance(case, (rn, rt));
        let ratio = ((gn - rn).abs() / tn).max((gt - rt).abs() / tt);
        worst = worst.max(ratio);
        // Written so that a NaN fails too.
        let within = ratio <= 1.0;
        if !within && bad.len() < 10 {
            bad.push(format!(
                "case {k}: CPU ({rn:e}, {rt:e}) N·s, GPU ({gn:e}, {gt:e}) N·s, tolerance ({tn:e}, {tt:e}) N·s"
            ));
        }
        // The GPU's impulses obey the law's constraints by construction.
        assert!(
            gn >= 0.0 && gt.abs() <= case.c.mu as f32 as f64 * gn * (1.0 + 4.0 * U),
            "case {k}: ({gn}, {gt})"
        );
        if rn == 0.0 {
            separated += 1;
        } else if rt.abs() < case.c.mu * rn * (1.0 - 1e-9) {
            stuck += 1;
        } else {
            sliding += 1;
        }
        blocks += usize::from(case.c.wnt != 0.0 && rn > 0.0);
    }
    println!(
        "local law: {n} cases ({separated} separated, {stuck} sticking, {sliding} sliding, \
         {blocks} loaded full blocks); largest error / tolerance = {worst:.3}"
    );
    assert!(
        bad.is_empty(),
        "GPU local law differs from solver::law:\n  {}",
        bad.join("\n  ")
    );
    // Every case of the law is exercised, or the comparison proves little.
    for (what, count) in [
        ("separated", separated),
        ("sticking", stuck),
        ("sliding", sliding),
        ("full-block", blocks),
    ] {
        assert!(count >= n / 20, "only {count} {what} cases of {n}");
    }
}

#[test]
fn gpu_normal_offset_matches_the_engine() {
    let Some(gpu) = device_or_skip("normal offset kernel") else {
        return;
    };
    let n = 8192;
    let mut rng = Rng(2005);
    let mut data = Vec::with_capacity(6 * n);
    for k in 0..n {
        // Open gaps from 1 nm to 1 mm: the small ones close within the step when the disks
        // approach (the offset is then clamped at 0), the large ones do not.
        let gap = match k % 6 {
            0 => 0.0,
            1 => -rng.range(1e-7, 1e-3),
            2 | 3 => rng.range(1e-7, 1e-3),
            _ => rng.range(1e-9, 1e-6),
        };
        let un = if k % 7 == 0 { 0.0 } else { rng.range(-1.0, 1.0) };
        let theta = match k % 3 {
            0 => 0.5,
            1 => 1.0,
            _ => rng.range(0.5, 1.0),
        };
        let dt = rng.range(1e-5, 1e-3);
        let e_n = if k % 5 == 0 { 0.0 } else { rng.range(0.0, 1.0) };
        data.extend([gap, un, theta, dt, e_n, f64::NAN].map(|x| x as f32));
    }
    let bytes = run(
        &gpu,
        "probe_bias",
        n as u32,
        &[(6, bytemuck::cast_slice(&data).to_vec())],
        6,
    );
    let got: &[f32] = bytemuck::cast_slice(&bytes);
    let (mut clamped, mut shifted, mut closed) = (0, 0, 0);
    let mut worst: f64 = 0.0;
    let mut bad = Vec::new();
    for k in 0..n {
        let [gap, un, theta, dt, e_n] = std::array::from_fn(|q| data[6 * k + q] as f64);
        let want = normal_bias(gap, un, theta, dt, e_n);
        let g = got[6 * k + 5] as f64;
        // One division of a two-term sum, or one product (closed gaps): 8 u of the terms.
        let tol = 8.0 * U * ((gap.abs() + ((1.0 - theta) * dt * un).abs()) / (theta * dt) + want.abs());
        let ratio = (g - want).abs() / tol.max(f64::MIN_POSITIVE);
        worst = worst.max(ratio);
        // Written so that a NaN fails too.
        let within = ratio <= 1.0;
        if !within && bad.len() < 10 {
            bad.push(format!(
                "record {k}: gap {gap:e} m, U_n {un:e} m/s, theta {theta}, dt {dt:e} s, e_n {e_n}: \
                 CPU {want:e} m/s, GPU {g:e} m/s, tolerance {tol:e} m/s"
            ));
        }
        if gap > 0.0 {
            assert!(g >= 0.0, "record {k}: an open gap got a negative offset {g} m/s");
            if want == 0.0 {
                clamped += 1;
            } else {
                shifted += 1;
            }
        } else {
            closed += 1;
            if un >= 0.0 {
                assert_eq!(
                    g, 0.0,
                    "record {k}: a closed gap opening at {un} m/s got an offset"
                );
            }
        }
    }
    println!(
        "normal offset: {n} records ({shifted} open and shifted, {clamped} open and closing \
         within the step, {closed} closed); largest error / tolerance = {worst:.3}"
    );
    assert!(
        bad.is_empty(),
        "GPU normal offset differs from the engine's:\n  {}",
        bad.join("\n  ")
    );
    for (what, count) in [("clamped", clamped), ("shifted", shifted), ("closed", closed)] {
        assert!(count >= n / 20, "only {count} {what} records of {n}");
    }
}

/// The kinds of contact whose Delassus block detection builds (src/contact/detect.rs,
/// `make_contact` and the wall loop; detect.wgsl, `build_contacts`).
#[derive(Clone, Copy, Debug, PartialEq)]
enum BlockKind {
    /// Two free disks: diagonal block.
    Disks,
    /// A free disk and a disk glued to a force-driven wall: the wall's axis on side j.
    GluedToForced,
    /// A free disk and a disk glued to a kinematic wall: side j does not move.
    GluedToKinematic,
    /// A disk against a kinematic wall.
    KinematicWall,
    /// A disk against a force-driven wall: the axis is the contact normal.
    ForcedWall,
    /// A disk glued to a force-driven wall (side i, as the CPU builds it: no mass, lever or
    /// spin) against a free disk.
    GluedFirst,
}

/// Random contacts of every [`BlockKind`], built with the sides the CPU's detection gives
/// them, values drawn in f32: unit normals at every angle, wall normals and axes at every
/// angle, inverse masses and levers over an order of magnitude.
fn block_cases(n: usize, rng: &mut Rng) -> Vec<(BlockKind, Contact)> {
    use BlockKind::*;
    let kinds = [
        Disks,
        GluedToForced,
        GluedToKinematic,
        KinematicWall,
        ForcedWall,
        GluedFirst,
    ];
    (0..n)
        .map(|k| {
            let kind = kinds[k % kinds.len()];
            let mut unit = || {
                let a = rng.range(0.0, std::f64::consts::TAU);
                DVec2::new(f(a.cos()), f(a.sin()))
            };
            let (normal, wall_axis) = (unit(), unit());
            let mut c = Contact {
                n: normal,
                ..Default::default()
            };
            let mut free = |c_r: &mut f64, c_m: &mut f64, c_k: &mut f64| {
                *c_r = f(rng.range(0.05, 1.5));
                *c_m = f(rng.range(0.1, 10.0));
                *c_k = f(*c_r * rng.range(1.0, 20.0));
            };
            if kind != GluedFirst {
                free(&mut c.ri, &mut c.mi, &mut c.ki);
            }
            match kind {
                Disks | GluedFirst => free(&mut c.rj, &mut c.mj, &mut c.kj),
                GluedToForced => {
                    c.ma = f(rng.range(0.01, 1.0));
                    c.a = wall_axis;
                }
                GluedToKinematic => c.a = wall_axis,
                KinematicWall => c.a = normal,
                ForcedWall => {
                    c.ma = f(rng.range(0.01, 1.0));
                    c.a = normal;
                }
            }
            (kind, c)
        })
        .collect()
}

#[test]
fn gpu_delassus_block_matches_compute_delassus() {
    let Some(gpu) = device_or_skip("Delassus block kernel") else {
        return;
    };
    let n = 6 * 1024;
    let cases = block_cases(n, &mut Rng(1979));
    let contacts: Vec<GpuContact> = cases.iter().map(|(_, c)| gpu_contact(c)).collect();
    let out = vec![f32::NAN; 3 * n];
    let bytes = run(
        &gpu,
        "probe_delassus",
        n as u32,
        &[
            (5, bytemuck::cast_slice(&contacts).to_vec()),
            (6, bytemuck::cast_slice(&out).to_vec()),
        ],
        6,
    );
    let got: &[f32] = bytemuck::cast_slice(&bytes);
    let mut worst: f64 = 0.0;
    let mut bad = Vec::new();
    let mut full = 0;
    for (k, (kind, c)) in cases.iter().enumerate() {
        let mut cpu = *c;
        cpu.compute_delassus();
        // Tolerance: each entry is a sum of at most five rounded products (two for each
        // projection of the axis, one square or product of them, one with the mass, the
        // lever terms) and its additions, about seven f32 roundings, each at most u times
        // the sum S of the magnitudes of the terms: 32 u S leaves a factor 4 for fused
        // multiply-adds and reassociation, while a wrong field or sign errs by a whole term.
        let pn = (c.a.x * c.n.x).abs() + (c.a.y * c.n.y).abs();
        let pt = (c.a.x * c.n.y).abs() + (c.a.y * c.n.x).abs();
        let s = [
            c.mi + c.mj + c.ma * pn * pn,
            c.mi + c.mj + c.ma * pt * pt + c.ri * c.ki + c.rj * c.kj,
            c.ma * pn * pt,
        ];
        let want = [cpu.wnn, cpu.wtt, cpu.wnt];
        for q in 0..3 {
            let g = got[3 * k + q] as f64;
            let tol = 32.0 * U * s[q];
            let ratio = (g - want[q]).abs() / tol.max(f64::MIN_POSITIVE);
            worst = worst.max(ratio);
            // Written so that a NaN fails too.
            let within = ratio <= 1.0;
            if !within && bad.len() < 10 {
                bad.push(format!(
                    "case {k} ({kind:?}), {}: CPU {:e} m/kg, GPU {g:e} m/kg, tolerance {tol:e} m/kg",
                    ["W_nn", "W_tt", "W_nt"][q],
                    want[q]
                ));
            }
        }
        // Beyond round-off: the off-diagonal term of a force-driven wall seen through a glued
        // disk at an oblique axis.
        if cpu.wnt.abs() > 1e-3 * cpu.wnn {
            full += 1;
        }
    }
    println!(
        "Delassus block: {n} contacts ({} of each of 6 kinds, {full} full blocks); largest error / tolerance = {worst:.3}",
        n / 6
    );
    assert!(
        bad.is_empty(),
        "GPU Delassus block differs from Contact::compute_delassus:\n  {}",
        bad.join("\n  ")
    );
    // The glued-to-force-driven cases give full blocks, or the comparison of W_nt proves
    // little.
    assert!(full >= n / 12, "only {full} full blocks of {n}");
}
