//! Compute pipelines: one shader module per phase file (composed with `common.wgsl`), one
//! pipeline per entry point, all sharing one pipeline layout so a single bind group serves
//! a whole step. Group 1 carries per-dispatch arguments at a dynamic offset (the region a
//! scan works on, the color a sweep updates).

use std::collections::HashMap;

use super::buffers::{Buffers, SimParams};
use super::device::GpuDevice;
use super::{SHADERS, compose};
use crate::error::{Error, Result};

/// Entry points, by shader file.
const ENTRY_POINTS: &[(&str, &[&str])] = &[
    ("scan.wgsl", &["clear_ints", "scan"]),
    ("integrate_free.wgsl", &["free_velocity"]),
    ("grid.wgsl", &["grid_bounds", "grid_count", "grid_scatter"]),
    (
        "detect.wgsl",
        &["detect", "contact_args", "build_contacts", "save_prev"],
    ),
    (
        "color.wgsl",
        &[
            "incidence_count",
            "incidence_fill",
            "incidence_rank",
            "color_seed",
            "color_round",
            "color_count",
            "color_offsets",
            "color_scatter",
        ],
    ),
    (
        "solve.wgsl",
        &[
            "gather",
            "sweep_color",
            "jacobi_solve",
            "jacobi_commit",
            "conv_reduce",
            "save_iterate",
            "velocity_change",
            "deep_mark",
            "deep_color",
            "deep_tally",
        ],
    ),
    ("integrate.wgsl", &["integrate"]),
    ("reduce.wgsl", &["wall_impulse", "reduce_final"]),
];

/// The pipelines and the layouts they share.
pub struct Pipelines {
    pipelines: HashMap<&'static str, wgpu::ComputePipeline>,
    /// Layout of group 0 (parameters and buffers).
    pub group0: wgpu::BindGroupLayout,
    /// Layout of group 1 (per-dispatch arguments).
    pub group1: wgpu::BindGroupLayout,
}

fn entry(binding: u32, ty: wgpu::BufferBindingType, dynamic: bool) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer {
            ty,
            has_dynamic_offset: dynamic,
            min_binding_size: None,
        },
        count: None,
    }
}

impl Pipelines {
    /// Compiles every shader and creates every pipeline inside error scopes: a shader the
    /// driver rejects (a bug in the crate, or a driver that cannot take it) comes back as
    /// [`Error::Gpu`] naming the adapter, not as wgpu's panic.
    pub fn new(gpu: &GpuDevice) -> Result<Self> {
        gpu.scoped("compiling the compute shaders", Self::create)?
    }

    fn create(device: &wgpu::Device) -> Result<Self> {
        let storage = wgpu::BufferBindingType::Storage { read_only: false };
        // The parameters and the per-dispatch arguments are read-only storage, not uniform
        // buffers: see the note at `sim` in shaders/common.wgsl (a driver leak).
        let params = wgpu::BufferBindingType::Storage { read_only: true };
        let mut entries = vec![entry(0, params, false)];
        entries.extend((1..=7).map(|b| entry(b, storage, false)));
        let group0 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("cdlab group 0"),
            entries: &entries,
        });
        let group1 = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("cdlab group 1"),
            entries: &[entry(0, params, true)],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("cdlab"),
            bind_group_layouts: &[Some(&group0), Some(&group1)],
            immediate_size: 0,
        });
        let mut pipelines = HashMap::new();
        for (file, points) in ENTRY_POINTS {
            let source = SHADERS
                .iter()
                .find(|(name, _)| name == file)
                .map(|(_, s)| compose(s))
                .ok_or_else(|| Error::Gpu(format!("missing shader {file}")))?;
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(file),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            });
            for point in points.iter() {
                let p = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(point),
                    layout: Some(&layout),
                    module: &module,
                    entry_point: Some(point),
                    compilation_options: Default::default(),
                    cache: None,
                });
                pipelines.insert(*point, p);
            }
        }
        Ok(Pipelines {
            pipelines,
            group0,
            group1,
        })
    }

    /// The pipeline of an entry point (panics on a name not in the table: a crate bug).
    pub fn get(&self, name: &str) -> &wgpu::ComputePipeline {
        &self.pipelines[name]
    }

    /// The bind groups of a set of buffers.
    pub fn bind(&self, device: &wgpu::Device, b: &Buffers) -> (wgpu::BindGroup, wgpu::BindGroup) {
        let g0 = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("cdlab group 0"),
            layout: &self.group0,
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
        });
        let g1 = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("cdlab group 1"),
            layout: &self.group1,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer: &b.args,
                    offset: 0,
                    size: wgpu::BufferSize::new(16),
                }),
            }],
        });
        (g0, g1)
    }
}

fn whole(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// Size check of the uniform parameters against the WGSL struct (a layout mismatch would
/// silently scramble every kernel).
const _: () = assert!(size_of::<SimParams>() == 224);
