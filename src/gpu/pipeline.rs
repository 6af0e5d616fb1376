//! Compute pipelines: one shader module per phase file (composed with `common.wgsl`), one
//! pipeline per entry point, all sharing one pipeline layout so a single bind group serves
//! a whole step. Group 1 carries per-dispatch arguments at a dynamic offset (the region a
//! scan works on, the color a sweep updates).

use super::buffers::{Buffers, GpuArgs, GpuContact, GpuDisk, GpuWall, SimParams};
use super::device::GpuDevice;
use super::{SHADERS, compose_file};
use crate::error::Result;

/// Declares [`Kernel`] from the entry points of each shader file.
macro_rules! kernels {
    ($($file:literal => [$($kernel:ident = $entry:literal),* $(,)?]),* $(,)?) => {
        /// A compute kernel: one entry point of one phase shader. [`Pipelines::get`] takes
        /// one, so a kernel that does not exist cannot be asked for.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
        pub enum Kernel {
            $($(
                #[doc = concat!("Entry point `", $entry, "` of `shaders/", $file, "`.")]
                $kernel,
            )*)*
        }

        impl Kernel {
            /// Every kernel, in declaration order (the order of the pipeline table).
            pub const ALL: &[Kernel] = &[$($(Kernel::$kernel,)*)*];

            /// The WGSL entry point's name.
            pub fn entry_point(self) -> &'static str {
                match self {
                    $($(Kernel::$kernel => $entry,)*)*
                }
            }

            /// The phase shader file (in `shaders/`) that holds the entry point.
            pub fn file(self) -> &'static str {
                match self {
                    $($(Kernel::$kernel => $file,)*)*
                }
            }
        }
    };
}

kernels! {
    "scan.wgsl" => [
        ClearInts = "clear_ints",
        ScanBlocks = "scan_blocks",
        ScanSums = "scan_sums",
        ScanAdd = "scan_add",
    ],
    "integrate_free.wgsl" => [FreeVelocity = "free_velocity"],
    "grid.wgsl" => [
        GridPartial = "grid_partial",
        GridBounds = "grid_bounds",
        GridCount = "grid_count",
        GridScatter = "grid_scatter",
    ],
    "detect.wgsl" => [
        Detect = "detect",
        ContactArgs = "contact_args",
        BuildContacts = "build_contacts",
        SavePrev = "save_prev",
    ],
    "color.wgsl" => [
        IncidenceCount = "incidence_count",
        IncidenceFill = "incidence_fill",
        IncidenceRank = "incidence_rank",
        ColorSeed = "color_seed",
        ColorRound = "color_round",
        ColorCount = "color_count",
        ColorOffsets = "color_offsets",
        ColorScatter = "color_scatter",
    ],
    "solve.wgsl" => [
        SolveArgs = "solve_args",
        ConvCheck = "conv_check",
        DeepMark = "deep_mark",
        DeepUpdates = "deep_updates",
    ],
    "sweep.wgsl" => [
        Gather = "gather",
        SweepColor = "sweep_color",
        SweepTail = "sweep_tail",
        SweepAll = "sweep_all",
        JacobiSolve = "jacobi_solve",
        JacobiCommit = "jacobi_commit",
        SaveIterate = "save_iterate",
        VelocityChange = "velocity_change",
    ],
    "integrate.wgsl" => [Integrate = "integrate"],
    "reduce.wgsl" => [
        WallImpulse = "wall_impulse",
        ReduceFinal = "reduce_final",
        OutlineClear = "outline_clear",
        StripOutline = "strip_outline",
        OutlineSum = "outline_sum",
        FreeOutline = "free_outline",
        StripClassify = "strip_classify",
        SetStrips = "set_strips",
    ],
}

/// One buffer binding of the layout, as the generated WGSL declares it
/// ([`wgsl_bindings`]).
#[derive(Clone, Copy, Debug)]
pub struct Binding {
    /// Bind group.
    pub group: u32,
    /// Binding index within the group.
    pub binding: u32,
    /// The WGSL variable's name.
    pub name: &'static str,
    /// Whether every kernel only reads it (`var<storage, read>`); [`Binds::read_only`]
    /// says which others a phase file binds read-only.
    pub read_only: bool,
    /// The WGSL type where it is bound read-write.
    pub wgsl_type: &'static str,
    /// The smallest size a bound buffer may have, in bytes: the record for a single
    /// struct, one element for a runtime-sized array. It is the layout's
    /// `min_binding_size`, so wgpu checks every bind group against it at creation instead
    /// of each dispatch, and tests/gpu_layout.rs checks it against the WGSL types.
    pub min_size: u64,
}

const fn binding(
    group: u32,
    binding: u32,
    name: &'static str,
    read_only: bool,
    wgsl_type: &'static str,
    min_size: usize,
) -> Binding {
    Binding {
        group,
        binding,
        name,
        read_only,
        wgsl_type,
        min_size: min_size as u64,
    }
}

/// The buffer bindings of both groups, in binding order. Group 1 carries the per-dispatch
/// arguments at a dynamic offset.
///
/// The parameters (`sim`) and the arguments are read-only storage, not uniform buffers:
/// Mesa lavapipe 22.x specializes a shader to the values of the uniform buffers its
/// branches depend on, compiles it again at every dispatch and never frees the copies, so
/// the host memory of a GPU run grew without bound (tests/gpu_memory.rs keeps it flat).
/// Storage buffers are never specialized.
pub const BINDINGS: [Binding; 9] = [
    binding(0, 0, "sim", true, "Sim", size_of::<SimParams>()),
    binding(0, 1, "disks", false, "array<Disk>", size_of::<GpuDisk>()),
    binding(0, 2, "walls", false, "array<Wall>", size_of::<GpuWall>()),
    binding(0, 3, "vel", false, "array<vec4<f32>>", size_of::<[f32; 4]>()),
    binding(0, 4, "ints", false, "array<atomic<u32>>", size_of::<u32>()),
    binding(0, 5, "contacts", false, "array<Contact>", size_of::<GpuContact>()),
    binding(0, 6, "floats", false, "array<f32>", size_of::<f32>()),
    binding(0, 7, "prev", false, "array<u32>", size_of::<u32>()),
    binding(1, 0, "args", true, "Args", size_of::<GpuArgs>()),
];

/// How the kernels of a phase file see the buffers of group 0. Each access is its own
/// layout and bind group over the same buffers; a kernel that writes a buffer its access
/// binds read-only does not compile (naga refuses the store).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Binds {
    /// Every buffer but the parameters read-write, the integers atomic: the kernels that
    /// detect, color, integrate, reduce and decide the solve's course.
    Shared,
    /// The iterations (`shaders/sweep.wgsl`): velocities, contacts and floats read-write;
    /// the disks, walls, warm-start records and integers read-only, the integers read with
    /// plain loads. Nothing writes those during an iteration, and a GPU may cache a plain
    /// read-only load where it sends an atomic one to its shared cache every time.
    Sweep,
}

impl Binds {
    /// Both accesses, in the order of their layouts.
    pub const ALL: [Binds; 2] = [Binds::Shared, Binds::Sweep];

    /// The access of a phase file's kernels.
    pub fn of_file(file: &str) -> Binds {
        if file == "sweep.wgsl" {
            Binds::Sweep
        } else {
            Binds::Shared
        }
    }

    /// Whether binding `b` is read-only under this access.
    pub fn read_only(self, b: &Binding) -> bool {
        b.read_only || (self == Binds::Sweep && matches!(b.name, "disks" | "walls" | "ints" | "prev"))
    }

    /// The WGSL type of binding `b` under this access: the integers are plain `u32`
    /// where they are read-only (atomics cannot be).
    pub fn wgsl_type(self, b: &Binding) -> &'static str {
        if b.name == "ints" && self.read_only(b) {
            "array<u32>"
        } else {
            b.wgsl_type
        }
    }
}

/// The WGSL declarations of the bindings under `access`, with the integer accessors: `ld`
/// (an atomic load, or a plain one where the integers are read-only) and, where they are
/// writable, `st`.
pub fn wgsl_bindings(access: Binds) -> String {
    let mut out = format!("// Generated by cdlab::gpu::pipeline::wgsl_bindings ({access:?} access).\n");
    for b in &BINDINGS {
        let mode = if access.read_only(b) { "read" } else { "read_write" };
        out.push_str(&format!(
            "@group({}) @binding({}) var<storage, {mode}> {}: {};\n",
            b.group,
            b.binding,
            b.name,
            access.wgsl_type(b)
        ));
    }
    let ints = BINDINGS
        .iter()
        .find(|b| b.name == "ints")
        .expect("the integer arena is bound");
    if access.read_only(ints) {
        out.push_str("fn ld(k: u32) -> u32 { return ints[k]; }\n");
    } else {
        out.push_str("fn ld(k: u32) -> u32 { return atomicLoad(&ints[k]); }\n");
        out.push_str("fn st(k: u32, v: u32) { atomicStore(&ints[k], v); }\n");
    }
    out
}

/// The pipelines and the layouts they share.
pub struct Pipelines {
    /// One pipeline per kernel, indexed by `Kernel as usize`.
    pipelines: Vec<wgpu::ComputePipeline>,
    /// Layouts of group 0 (parameters and buffers), one per [`Binds`], in the order of
    /// [`Binds::ALL`].
    pub group0: [wgpu::BindGroupLayout; 2],
    /// Layout of group 1 (per-dispatch arguments).
    pub group1: wgpu::BindGroupLayout,
}

fn entry(b: &Binding, access: Binds) -> wgpu::BindGroupLayoutEntry {
    // Read-only storage, not uniform buffers, for the parameters: see BINDINGS.
    wgpu::BindGroupLayoutEntry {
        binding: b.binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty: wgpu::BufferBindingType::Storage {
                read_only: access.read_only(b),
            },
            has_dynamic_offset: b.group == 1,
            min_binding_size: wgpu::BufferSize::new(b.min_size),
        },
        count: None,
    }
}

/// Parses and validates a composed shader with naga, as wgpu would, so that a shader error
/// comes back as [`GpuError::Shader`](crate::error::GpuError::Shader) naming the file and line rather than as a driver's
/// failure to create a pipeline.
pub fn validate(file: &str, source: &str) -> Result<()> {
    let shader_error = |message: String| crate::error::GpuError::Shader {
        file: file.to_string(),
        message,
    };
    let module = naga::front::wgsl::parse_str(source).map_err(|e| shader_error(e.emit_to_string(source)))?;
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .map_err(|e| shader_error(e.emit_to_string(source)))?;
    Ok(())
}

impl Pipelines {
    /// Compiles every shader and creates every pipeline inside error scopes: a shader the
    /// driver rejects (a bug in the crate, or a driver that cannot take it) comes back as
    /// [`Error::Gpu`] naming the adapter, not as wgpu's panic; a shader naga rejects
    /// ([`validate`]) is [`GpuError::Shader`](crate::error::GpuError::Shader).
    pub fn new(gpu: &GpuDevice) -> Result<Self> {
        gpu.scoped("compiling the compute shaders", Self::create)?
    }

    fn create(device: &wgpu::Device) -> Result<Self> {
        let entries = |group: u32, access: Binds| -> Vec<wgpu::BindGroupLayoutEntry> {
            BINDINGS
                .iter()
                .filter(|b| b.group == group)
                .map(|b| entry(b, access))
                .collect()
        };
        let group0 = Binds::ALL.map(|access| {
            device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
                label: Some("cdlab group 0"),
                entries: &entries(0, access),
            })
        });
        let group1 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("cdlab group 1"),
            entries: &entries(1, Binds::Shared),
        });
        let layouts = group0.each_ref().map(|g0| {
            device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some("cdlab"),
                bind_group_layouts: &[Some(g0), Some(&group1)],
                immediate_size: 0,
            })
        });
        let mut slots: Vec<Option<wgpu::ComputePipeline>> = Kernel::ALL.iter().map(|_| None).collect();
        for (file, source) in SHADERS {
            let access = Binds::of_file(file);
            let source = compose_file(file, source);
            validate(file, &source)?;
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(file),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
            for &kernel in Kernel::ALL.iter().filter(|k| k.file() == *file) {
                let point = kernel.entry_point();
                slots[kernel as usize] =
                    Some(device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some(point),
                        layout: Some(&layouts[access as usize]),
                        module: &module,
                        entry_point: Some(point),
                        compilation_options: Default::default(),
                        cache: None,
                    }));
            }
        }
        let pipelines = Kernel::ALL
            .iter()
            .zip(slots)
            .map(|(k, p)| p.ok_or_else(|| crate::error::gpu_failure(format!("missing shader {}", k.file()))))
            .collect::<Result<_>>()?;
        Ok(Pipelines {
            pipelines,
            group0,
            group1,
        })
    }

    /// The pipeline of a kernel.
    pub fn get(&self, kernel: Kernel) -> &wgpu::ComputePipeline {
        &self.pipelines[kernel as usize]
    }

    /// The bind groups of a set of buffers.
    pub fn bind(&self, device: &wgpu::Device, b: &Buffers) -> BindGroups {
        let group0 = self.group0.each_ref().map(|layout| {
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("cdlab group 0"),
                layout,
                entries: &[
                    whole(0, &b.sim),
                    whole(1, &b.disks),
                    whole(2, &b.walls),
                    whole(3, &b.vel),
                    whole(4, &b.ints),
                    whole(5, &b.contacts),
                    whole(6, &b.floats),
                    whole(7, &b.prev),
                ],
            })
        });
        let args = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("cdlab group 1"),
            layout: &self.group1,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &b.args,
                    offset: 0,
                    size: wgpu::BufferSize::new(size_of::<GpuArgs>() as u64),
                }),
            }],
        });
        BindGroups { group0, args }
    }
}

/// The bind groups of a set of buffers: group 0 once per [`Binds`], and group 1.
pub struct BindGroups {
    /// Group 0 under each access, in the order of [`Binds::ALL`].
    pub group0: [wgpu::BindGroup; 2],
    /// Group 1, the per-dispatch arguments.
    pub args: wgpu::BindGroup,
}

fn whole(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

// The layouts of these records and of the WGSL structs are compared field by field by
// tests/gpu_layout.rs (through naga, no adapter needed).

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;

    #[test]
    fn a_shader_naga_rejects_is_a_shader_error_naming_the_file_and_line() {
        for (file, source) in SHADERS {
            validate(file, &compose_file(file, source)).expect("the crate's shaders validate");
        }
        let broken = super::super::compose("fn f() -> u32 { return ST_CONTACTS + 1.0; }");
        match validate("broken.wgsl", &broken) {
            Err(Error::Gpu(crate::error::GpuError::Shader { file, message })) => {
                assert_eq!(file, "broken.wgsl");
                let line = broken.lines().count();
                assert!(message.contains(&format!("wgsl:{line}:")), "{message}");
            }
            other => panic!("expected GpuError::Shader, got {other:?}"),
        }
    }
}
