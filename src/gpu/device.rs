//! Adapter selection and listing.
//!
//! `--backend gpu` takes the best hardware adapter (discrete, then integrated, then
//! virtual) and falls back to a software one (Mesa lavapipe, WARP) with a one-line
//! warning, so the GPU path runs on any machine with a Vulkan driver.

use crate::error::{Error, Result};

/// The message of a missing adapter: what to install for the software fallback.
pub const NO_ADAPTER: &str = "no GPU adapter found; install a GPU driver, or for the software \
     Vulkan fallback: apt-get install mesa-vulkan-drivers libvulkan1 (then WGPU_BACKEND=vulkan)";

/// An opened device with what the backend needs to know about it.
pub struct GpuDevice {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// Name, type and backend of the adapter.
    pub info: wgpu::AdapterInfo,
    /// The limits the device was opened with (the adapter's own).
    pub limits: wgpu::Limits,
}

/// One adapter as listed by `cdlab info`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct AdapterSummary {
    /// Adapter name.
    pub name: String,
    /// Discrete, integrated, virtual, CPU (software) or other.
    pub device_type: String,
    /// Vulkan, Metal, DX12, GL.
    pub backend: String,
    /// Driver name and version.
    pub driver: String,
    /// Largest storage buffer binding (bytes).
    pub max_storage_binding: u64,
    /// Largest buffer (bytes).
    pub max_buffer: u64,
    /// Storage buffers per shader stage.
    pub max_storage_buffers_per_stage: u32,
    /// Workgroups per dispatch dimension.
    pub max_workgroups_per_dim: u32,
}

/// Backends to look at: all of them (`WGPU_BACKEND` in the environment narrows the set,
/// e.g. `WGPU_BACKEND=vulkan` for lavapipe).
fn instance() -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = wgpu::Backends::all();
    wgpu::Instance::new(desc.with_env())
}

/// Sort key of an adapter: hardware before software, and GL last within a type (its
/// compute support is the weakest).
fn rank(a: &wgpu::Adapter) -> (u32, bool) {
    let i = a.get_info();
    let t = match i.device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    };
    (t, i.backend == wgpu::Backend::Gl)
}

/// Every adapter wgpu can see, best first.
pub fn list_adapters() -> Vec<AdapterSummary> {
    let mut adapters = pollster::block_on(instance().enumerate_adapters(wgpu::Backends::all()));
    adapters.sort_by_key(rank);
    adapters
        .iter()
        .map(|a| {
            let i = a.get_info();
            let l = a.limits();
            AdapterSummary {
                name: i.name.clone(),
                device_type: format!("{:?}", i.device_type),
                backend: format!("{:?}", i.backend),
                driver: format!("{} {}", i.driver, i.driver_info),
                max_storage_binding: l.max_storage_buffer_binding_size,
                max_buffer: l.max_buffer_size,
                max_storage_buffers_per_stage: l.max_storage_buffers_per_shader_stage,
                max_workgroups_per_dim: l.max_compute_workgroups_per_dimension,
            }
        })
        .collect()
}

/// Opens the best adapter: hardware first, software with a warning on stderr, and
/// [`Error::Gpu`] naming the packages to install when there is none.
pub fn open() -> Result<GpuDevice> {
    let instance = instance();
    let mut adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
    adapters.retain(|a| a.get_info().backend != wgpu::Backend::Noop);
    adapters.sort_by_key(rank);
    let adapter = adapters
        .into_iter()
        .next()
        .ok_or_else(|| Error::Gpu(NO_ADAPTER.to_string()))?;
    let info = adapter.get_info();
    if info.device_type == wgpu::DeviceType::Cpu {
        eprintln!(
            "warning: no hardware GPU adapter; using the software adapter {} ({:?}): expect it to be slow",
            info.name, info.backend
        );
    }
    // The adapter's own limits: the buffer sizes are checked against them with a message
    // naming the limit, rather than against WebGPU's conservative defaults.
    let limits = adapter.limits();
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("cdlab"),
        required_limits: limits.clone(),
        ..Default::default()
    }))
    .map_err(|e| Error::Gpu(format!("cannot open {}: {e}", info.name)))?;
    Ok(GpuDevice {
        device,
        queue,
        info,
        limits,
    })
}
