//! The Rust records and the WGSL structs describe the same bytes: every shared struct's size
//! and every field's offset, size and scalar type are compared through naga's reading of
//! the shaders (no adapter needed), and so are the binding table, the shared constants and
//! the kernel table. A mismatch here would otherwise scramble every kernel silently.
//! How to add a field: docs/gpu.md.

use std::mem::offset_of;

use cdlab::gpu::buffers::{GpuArgs, GpuContact, GpuDisk, GpuWall, SimParams};
use cdlab::gpu::pipeline::{BINDINGS, Binds, Kernel, wgsl_bindings};
use cdlab::gpu::{COMMON_WGSL, SHADERS, compose_file, wgsl_constants, wgsl_prelude};
use naga::{Scalar, ScalarKind, TypeInner};

/// One field of a Rust record: name, byte offset, byte size, scalar type of its elements.
#[derive(Debug)]
struct Field {
    name: &'static str,
    offset: usize,
    size: usize,
    scalar: &'static str,
}

/// The WGSL scalar type a Rust field's elements are stored as.
trait Wgsl {
    const SCALAR: &'static str;
}
impl Wgsl for f32 {
    const SCALAR: &'static str = "f32";
}
impl Wgsl for u32 {
    const SCALAR: &'static str = "u32";
}
impl Wgsl for i32 {
    const SCALAR: &'static str = "i32";
}
impl<T: Wgsl, const N: usize> Wgsl for [T; N] {
    const SCALAR: &'static str = T::SCALAR;
}

fn scalar_of<S, T: Wgsl>(_: fn(&S) -> &T) -> &'static str {
    T::SCALAR
}

fn size_of_field<S, T>(_: fn(&S) -> &T) -> usize {
    size_of::<T>()
}

/// The fields of a `#[repr(C)]` record, with offsets from `offset_of!`.
macro_rules! fields {
    ($ty:ty { $($f:ident),* $(,)? }) => {
        vec![$(Field {
            name: stringify!($f),
            offset: offset_of!($ty, $f),
            size: size_of_field::<$ty, _>(|s| &s.$f),
            scalar: scalar_of::<$ty, _>(|s| &s.$f),
        }),*]
    };
}

/// Every record shared with the shaders: WGSL struct name, Rust name, size, fields.
fn records() -> Vec<(&'static str, &'static str, usize, Vec<Field>)> {
    vec![
        (
            "Sim",
            "SimParams",
            size_of::<SimParams>(),
            fields!(SimParams {
                n_disks,
                n_walls,
                n_bodies,
                k_slots,
                cap_contacts,
                cap_cells,
                max_colors,
                strips,
                top,
                bottom,
                o_cell_start,
                o_cell_fill,
                o_items,
                o_cell_of,
                o_dcount,
                o_slots,
                o_inc_count,
                o_inc_fill,
                o_inc_list,
                o_status,
                o_color_count,
                o_color_fill,
                o_order,
                o_per_disk,
                f_d2,
                f_r2,
                f_fresh,
                f_wall,
                f_red,
                f_grid,
                f_conv,
                jacobi,
                dt,
                theta,
                alert,
                r_max,
                gx,
                gy,
                mu_disk,
                mu_wall,
                e_n,
                e_t,
                sigma3,
                relax,
                strip_sum_r0,
                strip_sum_r1,
                gap_tol,
                gs_relax,
                o_color,
                o_left,
                max_rounds,
                o_inc_tmp,
                f_deep,
                deep_gap,
                deep_sweeps,
                deep_budget,
                o_disp,
                max_iter,
                tol,
                velocity_tol,
                r_min,
                o_outline,
                one,
                o_color_map
            }),
        ),
        (
            "Disk",
            "GpuDisk",
            size_of::<GpuDisk>(),
            fields!(GpuDisk {
                x,
                y,
                theta,
                radius,
                inv_mass,
                inv_inertia,
                mass,
                kind,
                glued,
                strip,
                fx,
                fy,
                torque,
                x_lo,
                y_lo,
                pad
            }),
        ),
        (
            "Wall",
            "GpuWall",
            size_of::<GpuWall>(),
            fields!(GpuWall {
                nx,
                ny,
                px,
                py,
                inv_mass,
                force,
                is_active,
                forced,
                px_lo,
                py_lo,
                pad
            }),
        ),
        (
            "Contact",
            "GpuContact",
            size_of::<GpuContact>(),
            fields!(GpuContact {
                i,
                j,
                disk_j,
                color,
                nx,
                ny,
                gap,
                ri,
                rj,
                mi,
                mj,
                ma,
                ax,
                ay,
                ki,
                kj,
                wnn,
                wtt,
                wnt,
                mu,
                un0,
                ut0,
                bias_n,
                bias_t,
                rn,
                rt,
                deep,
                pad
            }),
        ),
        (
            "Args",
            "GpuArgs",
            size_of::<GpuArgs>(),
            fields!(GpuArgs { a, b, c, d }),
        ),
    ]
}

/// Padding: a Rust field named `pad` or a WGSL member whose name starts with `_`.
fn is_pad(name: &str) -> bool {
    name == "pad" || name.starts_with('_')
}

fn scalar_name(s: Scalar) -> String {
    match (s.kind, s.width) {
        (ScalarKind::Float, 4) => "f32".into(),
        (ScalarKind::Uint, 4) => "u32".into(),
        (ScalarKind::Sint, 4) => "i32".into(),
        (k, w) => format!("{k:?}{}", 8 * w as u32),
    }
}

/// The scalar type of a WGSL type's elements (through vectors, arrays and atomics).
fn element_scalar(module: &naga::Module, ty: naga::Handle<naga::Type>) -> Option<String> {
    match &module.types[ty].inner {
        TypeInner::Scalar(s) | TypeInner::Vector { scalar: s, .. } | TypeInner::Atomic(s) => {
            Some(scalar_name(*s))
        }
        TypeInner::Array { base, .. } => element_scalar(module, *base),
        _ => None,
    }
}

fn parse(name: &str, source: &str) -> naga::Module {
    naga::front::wgsl::parse_str(source).unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(source)))
}

/// The differences between a Rust record and its WGSL struct, one line each (empty when
/// they agree).
fn compare(module: &naga::Module, wgsl: &str, rust: &str, size: usize, fields: &[Field]) -> Vec<String> {
    let Some((_, ty)) = module.types.iter().find(|(_, t)| t.name.as_deref() == Some(wgsl)) else {
        return vec![format!("WGSL struct `{wgsl}` (twin of {rust}) not found")];
    };
    let TypeInner::Struct { members, span } = &ty.inner else {
        return vec![format!("WGSL `{wgsl}` is not a struct")];
    };
    let mut layouter = naga::proc::Layouter::default();
    layouter.update(module.to_ctx()).expect("WGSL layout");
    let mut bad = Vec::new();
    if *span as usize != size {
        bad.push(format!(
            "{rust} is {size} bytes but WGSL `{wgsl}` is {span} bytes"
        ));
    }
    let mut pad_rust: Vec<(usize, usize)> = Vec::new();
    let mut pad_wgsl: Vec<(usize, usize)> = Vec::new();
    for f in fields {
        if is_pad(f.name) {
            pad_rust.push((f.offset, f.offset + f.size));
            continue;
        }
        let Some(m) = members.iter().find(|m| m.name.as_deref() == Some(f.name)) else {
            bad.push(format!("{rust}.{} has no WGSL twin in `{wgsl}`", f.name));
            continue;
        };
        let (offset, msize) = (m.offset as usize, layouter[m.ty].size as usize);
        if offset != f.offset {
            bad.push(format!(
                "{rust}.{} is at byte {} in Rust but at byte {offset} in WGSL `{wgsl}`",
                f.name, f.offset
            ));
        }
        if msize != f.size {
            bad.push(format!(
                "{rust}.{} is {} bytes in Rust but {msize} bytes in WGSL `{wgsl}`",
                f.name, f.size
            ));
        }
        let scalar = element_scalar(module, m.ty).unwrap_or_else(|| "?".into());
        if scalar != f.scalar {
            bad.push(format!(
                "{rust}.{} is {} in Rust but {scalar} in WGSL `{wgsl}`",
                f.name, f.scalar
            ));
        }
    }
    for m in members {
        let name = m.name.as_deref().unwrap_or("");
        let (start, end) = (m.offset as usize, (m.offset + layouter[m.ty].size) as usize);
        if is_pad(name) {
            pad_wgsl.push((start, end));
        } else if !fields.iter().any(|f| f.name == name) {
            bad.push(format!("WGSL `{wgsl}.{name}` has no field in {rust}"));
        }
    }
    // Padding may be spelled differently (one array in Rust, scalars in WGSL) but must
    // cover the same bytes.
    let bytes = |ranges: &[(usize, usize)]| -> Vec<usize> {
        let mut b: Vec<usize> = ranges.iter().flat_map(|&(s, e)| s..e).collect();
        b.sort_unstable();
        b
    };
    if bytes(&pad_rust) != bytes(&pad_wgsl) {
        bad.push(format!(
            "padding differs: {rust} pads bytes {pad_rust:?}, WGSL `{wgsl}` pads {pad_wgsl:?}"
        ));
    }
    bad
}

fn modules() -> Vec<(&'static str, String, naga::Module)> {
    SHADERS
        .iter()
        .map(|(name, src)| {
            let source = compose_file(name, src);
            let module = parse(name, &source);
            (*name, source, module)
        })
        .collect()
}

#[test]
fn every_shared_record_has_the_wgsl_layout() {
    // The records are declared once, in common.wgsl, which every phase shader includes.
    let (_, _, module) = &modules()[0];
    let mut bad = Vec::new();
    for (wgsl, rust, size, fields) in records() {
        bad.extend(compare(module, wgsl, rust, size, &fields));
    }
    assert!(
        bad.is_empty(),
        "Rust/WGSL layout mismatch:\n  {}",
        bad.join("\n  ")
    );
}

#[test]
fn the_comparison_catches_a_moved_field_and_a_wrong_size() {
    // A WGSL `Wall` with two fields swapped, one of them retyped, and one dropped: the
    // comparison must name the struct, the field and both values.
    let source = COMMON_WGSL.replace(
        "inv_mass: f32, force: f32, is_active: u32, forced: u32,",
        "inv_mass: f32, is_active: u32, force: u32,",
    );
    assert_ne!(source, COMMON_WGSL, "the WGSL `Wall` declaration was not found");
    let module = parse(
        "altered common.wgsl",
        &format!("{}{}{source}", wgsl_prelude(), wgsl_bindings(Binds::Shared)),
    );
    let walls = records().into_iter().find(|r| r.0 == "Wall").unwrap();
    let bad = compare(&module, walls.0, walls.1, walls.2, &walls.3);
    let text = bad.join("\n");
    assert!(
        text.contains("GpuWall is 48 bytes but WGSL `Wall` is 44 bytes"),
        "{text}"
    );
    assert!(
        text.contains("GpuWall.force is at byte 20 in Rust but at byte 24"),
        "{text}"
    );
    assert!(
        text.contains("GpuWall.is_active is at byte 24 in Rust but at byte 20"),
        "{text}"
    );
    assert!(
        text.contains("GpuWall.force is f32 in Rust but u32 in WGSL"),
        "{text}"
    );
    assert!(text.contains("GpuWall.forced has no WGSL twin"), "{text}");
}

#[test]
fn every_binding_matches_the_shaders_declaration() {
    for (name, _, module) in modules() {
        let mut layouter = naga::proc::Layouter::default();
        layouter.update(module.to_ctx()).expect("WGSL layout");
        let globals: Vec<_> = module
            .global_variables
            .iter()
            .filter_map(|(_, g)| g.binding.as_ref().map(|b| (b, g)))
            .collect();
        assert_eq!(globals.len(), BINDINGS.len(), "{name}: bindings declared");
        for b in BINDINGS {
            let (_, g) = globals
                .iter()
                .find(|(rb, _)| rb.group == b.group && rb.binding == b.binding)
                .unwrap_or_else(|| panic!("{name}: no @group({}) @binding({})", b.group, b.binding));
            assert_eq!(
                g.name.as_deref(),
                Some(b.name),
                "{name}: name at ({}, {})",
                b.group,
                b.binding
            );
            let naga::AddressSpace::Storage { access } = g.space else {
                panic!("{name}: `{}` is not a storage buffer", b.name);
            };
            assert_eq!(
                !access.contains(naga::StorageAccess::STORE),
                Binds::of_file(name).read_only(&b),
                "{name}: `{}` read-only",
                b.name
            );
            // The integers are atomic where they are written and plain loads where they
            // are read-only (the sweeps' access): atomics cannot be bound read-only.
            if b.name == "ints" {
                let TypeInner::Array { base, .. } = module.types[g.ty].inner else {
                    panic!("{name}: `ints` is not an array");
                };
                let atomic = matches!(module.types[base].inner, TypeInner::Atomic(_));
                assert_eq!(
                    atomic,
                    !Binds::of_file(name).read_only(&b),
                    "{name}: `ints` atomic"
                );
            }
            // The smallest valid binding: one element of a runtime-sized array, else the
            // whole type.
            let min = match &module.types[g.ty].inner {
                TypeInner::Array {
                    stride,
                    size: naga::ArraySize::Dynamic,
                    ..
                } => *stride,
                _ => layouter[g.ty].size,
            };
            assert_eq!(
                b.min_size, min as u64,
                "{name}: min_binding_size of `{}` (Rust) against its WGSL type",
                b.name
            );
        }
    }
}

/// The generated prelude declares every shared constant with its Rust value, as a `u32`
/// literal naga reads back, in every composed shader.
#[test]
fn the_shared_constants_have_the_rust_values() {
    for (name, _, module) in modules() {
        for (cname, value, _) in wgsl_constants() {
            let c = module
                .constants
                .iter()
                .find(|(_, c)| c.name.as_deref() == Some(cname))
                .unwrap_or_else(|| panic!("{name}: constant {cname} missing"))
                .1;
            match module.global_expressions[c.init] {
                naga::Expression::Literal(naga::Literal::U32(v)) => assert_eq!(
                    v, value,
                    "{name}: WGSL {cname} = {v} but its Rust source (gpu::wgsl_constants) is {value}"
                ),
                ref e => panic!("{name}: {cname} is {e:?}, not a u32 literal"),
            }
        }
    }
}

#[test]
fn no_shader_spells_a_status_word_or_kernel_width_as_a_literal() {
    // Status words are named (ST_*), so that the host's indices (`status::*`) are the only
    // spelling; the per-item kernels use the host's WG; the shared constants come from the
    // generated prelude alone (gpu::wgsl_prelude), declared in no shader file.
    for (name, src) in SHADERS.iter().chain([&("common.wgsl", COMMON_WGSL)]) {
        for (n, line) in src.lines().enumerate() {
            let code = line.split("//").next().unwrap_or("");
            if let Some(at) = code.find("o_status + ") {
                let next = code[at + "o_status + ".len()..].chars().next();
                assert!(
                    !next.is_some_and(|c| c.is_ascii_digit()),
                    "{name}:{}: status word by number: {line}",
                    n + 1
                );
            }
            assert!(
                !code.contains("@workgroup_size(64)"),
                "{name}:{}: use WG: {line}",
                n + 1
            );
            for (cname, _, _) in wgsl_constants() {
                assert!(
                    !code.contains(&format!("const {cname}:")),
                    "{name}:{}: {cname} comes from gpu::wgsl_prelude, generated from Rust",
                    n + 1
                );
            }
        }
    }
}

/// The lines of `src` that use a float region the host reads back (`f_red`, `f_grid`,
/// `f_conv`) without one of its slot constants (`FR_*`, `FG_*`, `FC_*`), and how many uses
/// there are.
fn float_slot_faults(name: &str, src: &str) -> (Vec<String>, usize) {
    let regions = [("f_red", "FR_"), ("f_grid", "FG_"), ("f_conv", "FC_")];
    let (mut faults, mut uses) = (Vec::new(), 0);
    for (n, line) in src.lines().enumerate() {
        let code = line.split("//").next().unwrap_or("");
        for (region, prefix) in regions {
            let field = format!("sim.{region}");
            for (at, _) in code.match_indices(&field) {
                uses += 1;
                if !code[at + field.len()..].starts_with(&format!(" + {prefix}")) {
                    faults.push(format!(
                        "{name}:{}: {region} without a {prefix}* slot: {line}",
                        n + 1
                    ));
                }
            }
        }
    }
    (faults, uses)
}

/// The float regions the host reads back are indexed by name: every use of `f_red`,
/// `f_grid` or `f_conv` in a shader adds one of the slot constants of its region (checked
/// against `gpu::buffers::float_slot` above), never a number and never through an alias
/// that would hide the slot.
#[test]
fn no_shader_spells_a_float_region_slot_as_a_literal() {
    let mut uses = 0;
    for (name, src) in SHADERS.iter() {
        let (faults, n) = float_slot_faults(name, src);
        assert!(faults.is_empty(), "{faults:#?}");
        uses += n;
    }
    // grid.wgsl, detect.wgsl, solve.wgsl, sweep.wgsl and reduce.wgsl read or write the
    // regions.
    assert!(
        uses >= 20,
        "{uses} uses of the float regions found: the check reads nothing"
    );
    // The check itself: a numbered slot and an alias are refused, a named slot passes.
    let bad = "floats[sim.f_grid + 3u] = 1.0;\nlet r = sim.f_red;\nfloats[sim.f_conv] = 0.0;";
    assert_eq!(float_slot_faults("bad", bad).0.len(), 3);
    assert!(
        float_slot_faults("good", "floats[sim.f_grid + FG_NX] = 1.0;")
            .0
            .is_empty()
    );
}

#[test]
fn every_kernel_is_a_compute_entry_point_of_its_shader() {
    let modules = modules();
    for &k in Kernel::ALL {
        let (_, _, module) = modules
            .iter()
            .find(|(n, _, _)| *n == k.file())
            .unwrap_or_else(|| panic!("{k:?}: shader {} not in SHADERS", k.file()));
        let ep = module
            .entry_points
            .iter()
            .find(|e| e.name == k.entry_point())
            .unwrap_or_else(|| panic!("{k:?}: no entry point {} in {}", k.entry_point(), k.file()));
        assert_eq!(ep.stage, naga::ShaderStage::Compute, "{k:?}");
    }
    // And no entry point is left without a kernel (it would never be dispatched).
    for (name, _, module) in &modules {
        for ep in &module.entry_points {
            assert!(
                Kernel::ALL
                    .iter()
                    .any(|k| k.file() == *name && k.entry_point() == ep.name),
                "{name}: entry point {} has no Kernel",
                ep.name
            );
        }
    }
}

#[test]
fn every_composed_shader_validates() {
    for (name, source, module) in modules() {
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::default(),
        )
        .validate(&module)
        .unwrap_or_else(|e| panic!("{name}: {}", e.emit_to_string(&source)));
    }
}
