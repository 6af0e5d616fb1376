//! The per-kernel traffic table (`src/gpu/traffic.rs`) that the GPU counters add up, and
//! which the GPU performance model of docs/benchmarks.md is fitted on: every kernel has one
//! entry; the record sizes it multiplies are the WGSL sizes (naga's layout, no adapter
//! needed); every entry names exactly the buffers its entry point loads and stores (naga's
//! reading of the shaders, through the functions it calls); and on a device, each solver
//! iteration adds exactly the closed-form bytes of its kernels over the step's contacts.

mod common;
#[path = "gpu_support/mod.rs"]
mod gpu_support;

use std::collections::BTreeSet;

use cdlab::backend::{Backend, Loading};
use cdlab::gpu::buffers::{GpuContact, GpuDisk, GpuWall};
use cdlab::gpu::pipeline::Kernel;
use cdlab::gpu::traffic::{self, Buf, CONTACT, DISK, TABLE, VEL, WALL, WORD};
use cdlab::gpu::{SHADERS, compose, compose_file};
use cdlab::solver::Method;
use naga::{Expression, Handle, Statement, TypeInner};

#[test]
fn every_kernel_has_exactly_one_traffic_entry_in_kernel_order() {
    let listed: Vec<Kernel> = TABLE.iter().map(|(k, _)| *k).collect();
    assert_eq!(listed, Kernel::ALL, "the table must list Kernel::ALL, in order");
    for (k, accesses) in TABLE {
        assert!(!accesses.is_empty(), "{k:?} has no access");
        // An entry that moves nothing would leave the kernel out of the byte count.
        assert!(
            accesses.iter().any(|a| a.bytes > 0),
            "{k:?}: every access is 0 bytes"
        );
    }
}

fn parse(name: &str, source: &str) -> naga::Module {
    naga::front::wgsl::parse_str(source).unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)))
}

#[test]
fn the_record_sizes_of_the_table_are_the_wgsl_sizes() {
    let (name, src) = SHADERS[0];
    let module = parse(name, &compose_file(name, src));
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("WGSL layout");
    let size_of_struct = |wgsl: &str| -> u32 {
        let (h, _) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(wgsl))
            .unwrap_or_else(|| panic!("WGSL struct `{wgsl}` not found"));
        layouter[h].size
    };
    assert_eq!(DISK, size_of_struct("Disk"));
    assert_eq!(CONTACT, size_of_struct("Contact"));
    assert_eq!(WALL, size_of_struct("Wall"));
    assert_eq!(
        (DISK, CONTACT, WALL),
        (
            size_of::<GpuDisk>() as u32,
            size_of::<GpuContact>() as u32,
            size_of::<GpuWall>() as u32
        )
    );
    // Element sizes of the runtime-sized arrays: vel is vec4<f32>, the scratch buffers and
    // the warm-start records are 4-byte words.
    let element = |var: &str| -> u32 {
        let (_, g) = module
            .global_variables
            .iter()
            .find(|(_, g)| g.name.as_deref() == Some(var))
            .unwrap_or_else(|| panic!("WGSL `{var}` not found"));
        match module.types[g.ty].inner {
            TypeInner::Array { stride, .. } => stride,
            ref other => panic!("`{var}` is {other:?}, not an array"),
        }
    };
    assert_eq!(VEL, element("vel"));
    for var in ["ints", "floats", "prev"] {
        assert_eq!(WORD, element(var), "{var}");
    }
    assert_eq!(DISK, element("disks"));
    assert_eq!(CONTACT, element("contacts"));
    assert_eq!(WALL, element("walls"));
}

/// The storage global a pointer expression is rooted at.
fn root(f: &naga::Function, mut e: Handle<Expression>) -> Option<Handle<naga::GlobalVariable>> {
    loop {
        match f.expressions[e] {
            Expression::GlobalVariable(g) => return Some(g),
            Expression::Access { base, .. } | Expression::AccessIndex { base, .. } => e = base,
            _ => return None,
        }
    }
}

/// (buffer, written) pairs a function loads and stores, through the functions it calls.
fn accesses(module: &naga::Module, f: &naga::Function, out: &mut BTreeSet<(String, bool)>) {
    let mut add = |g: Handle<naga::GlobalVariable>, write: bool| {
        let var = &module.global_variables[g];
        if let (naga::AddressSpace::Storage { .. }, Some(name)) = (var.space, var.name.as_deref()) {
            // The parameters: read by every thread at one address, not counted.
            if name != "sim" && name != "args" {
                out.insert((name.to_string(), write));
            }
        }
    };
    for (_, e) in f.expressions.iter() {
        if let Expression::Load { pointer } = *e
            && let Some(g) = root(f, pointer)
        {
            add(g, false);
        }
    }
    let mut calls = Vec::new();
    walk(&f.body, &mut |s| match *s {
        Statement::Store { pointer, .. } => {
            if let Some(g) = root(f, pointer) {
                add(g, true);
            }
        }
        Statement::Atomic { pointer, .. } => {
            if let Some(g) = root(f, pointer) {
                add(g, false);
                add(g, true);
            }
        }
        Statement::Call { function, .. } => calls.push(function),
        _ => {}
    });
    for c in calls {
        accesses(module, &module.functions[c], out);
    }
}

fn walk(block: &naga::Block, visit: &mut impl FnMut(&Statement)) {
    for s in block.iter() {
        visit(s);
        match s {
            Statement::Block(b) => walk(b, visit),
            Statement::If { accept, reject, .. } => {
                walk(accept, visit);
                walk(reject, visit);
            }
            Statement::Switch { cases, .. } => {
                for c in cases {
                    walk(&c.body, visit);
                }
            }
            Statement::Loop { body, continuing, .. } => {
                walk(body, visit);
                walk(continuing, visit);
            }
            _ => {}
        }
    }
}

#[test]
fn every_entry_names_the_buffers_its_kernel_loads_and_stores() {
    let mut bad = Vec::new();
    for (file, src) in SHADERS {
        let module = parse(file, &compose_file(file, src));
        for &kernel in Kernel::ALL.iter().filter(|k| k.file() == *file) {
            let ep = module
                .entry_points
                .iter()
                .find(|e| e.name == kernel.entry_point())
                .unwrap_or_else(|| panic!("{file}: no entry point {}", kernel.entry_point()));
            let mut wgsl = BTreeSet::new();
            accesses(&module, &ep.function, &mut wgsl);
            let table: BTreeSet<(String, bool)> = traffic::accesses(kernel)
                .iter()
                .map(|a| (a.buf.name().to_string(), a.write))
                .collect();
            if wgsl != table {
                let show = |s: &BTreeSet<(String, bool)>| -> Vec<String> {
                    s.iter()
                        .map(|(b, w)| format!("{} {b}", if *w { "writes" } else { "reads" }))
                        .collect()
                };
                bad.push(format!(
                    "{kernel:?}: the WGSL {:?}, the table {:?}",
                    show(&wgsl),
                    show(&table)
                ));
            }
        }
    }
    assert!(
        bad.is_empty(),
        "traffic table vs shaders:\n  {}",
        bad.join("\n  ")
    );
}

#[test]
fn the_comparison_sees_a_store_the_table_leaves_out() {
    // A velocity store added to save_prev: the walk must report `vel` as written there.
    let (file, src) = SHADERS
        .iter()
        .find(|(f, _)| *f == "detect.wgsl")
        .expect("detect.wgsl");
    let altered = src.replace(
        "    if k <= nd { prev[k] = min(ld(sim.o_dcount + k), sim.cap_contacts); }",
        "    if k <= nd { prev[k] = min(ld(sim.o_dcount + k), sim.cap_contacts); vel[k] = vec4<f32>(0.0); }",
    );
    assert_ne!(&altered, src, "the line of save_prev was not found");
    let module = parse(file, &compose(&altered));
    let ep = module
        .entry_points
        .iter()
        .find(|e| e.name == "save_prev")
        .expect("save_prev");
    let mut wgsl = BTreeSet::new();
    accesses(&module, &ep.function, &mut wgsl);
    assert!(wgsl.contains(&("vel".to_string(), true)), "{wgsl:?}");
    assert!(
        !traffic::accesses(Kernel::SavePrev)
            .iter()
            .any(|a| a.buf == Buf::Vel),
        "save_prev does not touch vel"
    );
}

/// Bytes counted by a backend after one step of a 16-disk column with exactly `iterations`
/// iterations, checked one by one, with the step's contact and body counts.
fn one_step(method: Method, iterations: u32) -> Option<(u64, u64, u64, u64)> {
    let scene = common::column(16, 0.5, gpu_support::G, None);
    let mut p = common::tight(method);
    // Never converged: the step runs exactly `iterations` (checked below).
    p.solver.tol = 1e-30;
    p.solver.max_iter = iterations;
    let mut g = gpu_support::gpu_or_skip("traffic per iteration", &scene, p)?;
    g.conv_every = 1;
    g.run(1, &Loading::default()).expect("step");
    let k = g.counters();
    assert_eq!(
        k.iterations, iterations as u64,
        "{method:?}: the step converged early, the test needs every iteration"
    );
    assert_eq!(k.redone, 0, "{method:?}: a redone step is counted twice");
    let n = g.raw_contacts().expect("contacts").len() as u64;
    let bodies = (scene.disks.len() + scene.walls.len()) as u64;
    Some((k.bytes_read, k.bytes_written, n, bodies))
}

#[test]
fn each_solver_iteration_adds_the_closed_form_bytes_of_its_kernels() {
    let (c, v, w) = (size_of::<GpuContact>() as u64, 16u64, 4u64);
    for method in [Method::ColoredGs, Method::Jacobi] {
        let Some((r2, w2, n, nb)) = one_step(method, 2) else {
            return;
        };
        let (r5, w5, n5, _) = one_step(method, 5).expect("a second backend");
        assert_eq!(n, n5, "{method:?}: both steps must find the same contacts");
        assert_eq!(n, 16, "a column of 16 disks on a floor has 16 contacts");
        // Every iteration ends with its convergence test (check every iteration): the
        // flag, the contact count and the iterations, two terms per contact; two sums, the
        // iterations and the residual written.
        let (conv_r, conv_w) = (3 * w + 2 * w * n, 4 * w);
        let (read, written) = match method {
            // One sweep over every contact (the colors tile them): per contact the color's
            // place in the sweep order, its two offsets and the contact's index, the
            // record, two velocities; two velocities, R_n, R_t and two convergence terms.
            Method::ColoredGs => (n * (4 * w + c + 2 * v), n * (2 * v + 4 * w)),
            // Solve (count, record, two velocities; four words), commit (count, two words;
            // two words), gather (per body its velocity and list bounds, per contact two
            // list entries and two records; per body its velocity).
            _ => (
                n * (w + c + 2 * v) + n * (3 * w) + nb * (v + 2 * w) + n * (2 * w + 2 * c),
                n * 4 * w + n * 2 * w + nb * v,
            ),
        };
        assert_eq!(
            r5 - r2,
            3 * (read + conv_r),
            "{method:?}: bytes read per iteration"
        );
        assert_eq!(
            w5 - w2,
            3 * (written + conv_w),
            "{method:?}: bytes written per iteration"
        );
    }
}
