//! Adapter selection and listing.
//!
//! `--backend gpu` takes the best hardware adapter (discrete, then integrated, then
//! virtual) and falls back to a software one (Mesa lavapipe, WARP) with a one-line
//! warning, so the GPU path runs on any machine with a Vulkan driver.

use std::sync::{Arc, Mutex};

use crate::error::{Error, Result};

/// The message of a missing adapter: what to install for the software fallback.
pub const NO_ADAPTER: &str = "no GPU adapter found; install a GPU driver, or for the software \
     Vulkan fallback: apt-get install mesa-vulkan-drivers libvulkan1 (then WGPU_BACKEND=vulkan)";

/// The wgpu errors of a device not caught by an error scope (validation, out of memory,
/// internal) and its loss, kept for the next [`GpuDevice::check`]. Installed in place of
/// wgpu's default handler, which panics: a failing device must end the run with an error
/// the user can act on, and leave the records written so far intact.
#[derive(Clone, Debug, Default)]
pub struct ErrorLog(Arc<Mutex<Vec<String>>>);

impl ErrorLog {
    fn push(&self, message: String) {
        // A poisoned lock only means another thread panicked while pushing: keep logging.
        self.0.lock().unwrap_or_else(|e| e.into_inner()).push(message);
    }

    fn take(&self) -> Vec<String> {
        std::mem::take(&mut *self.0.lock().unwrap_or_else(|e| e.into_inner()))
    }
}

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
    /// Errors reported outside error scopes, and the device's loss.
    pub errors: ErrorLog,
    /// Whether the device writes timestamps at the start and end of compute passes
    /// (`TIMESTAMP_QUERY`): the GPU path then times its steps on the device.
    pub timestamps: bool,
}

impl GpuDevice {
    /// The error that ends a run on this device: names the adapter, what was being done,
    /// wgpu's message, and the way out.
    pub fn failure(&self, during: &str, detail: impl std::fmt::Display) -> Error {
        crate::error::gpu_failure(format!(
            "{} ({:?}): {during}: {detail}; run on the CPU backend instead (a run stopped here \
             continues there from its last checkpoint)",
            self.info.name, self.info.backend
        ))
    }

    /// Err with the errors reported since the last check (outside any error scope, or the
    /// device's loss), else Ok.
    pub fn check(&self, during: &str) -> Result<()> {
        let errors = self.errors.take();
        if errors.is_empty() {
            Ok(())
        } else {
            Err(self.failure(during, errors.join("; ")))
        }
    }

    /// Runs `f` (resource or pipeline creation) inside error scopes for validation,
    /// out-of-memory and internal errors, and returns the first error they caught.
    pub fn scoped<T>(&self, during: &str, f: impl FnOnce(&wgpu::Device) -> T) -> Result<T> {
        let filters = [
            wgpu::ErrorFilter::OutOfMemory,
            wgpu::ErrorFilter::Validation,
            wgpu::ErrorFilter::Internal,
        ];
        let scopes: Vec<_> = filters.iter().map(|f| self.device.push_error_scope(*f)).collect();
        let out = f(&self.device);
        // Scopes pop innermost first.
        let caught: Vec<String> = scopes
            .into_iter()
            .rev()
            .filter_map(|s| pollster::block_on(s.pop()))
            .map(|e| match e {
                wgpu::Error::OutOfMemory { .. } => "out of device memory".to_string(),
                e => e.to_string(),
            })
            .collect();
        if let Some(first) = caught.first() {
            return Err(self.failure(during, first));
        }
        self.check(during)?;
        Ok(out)
    }
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
///
/// wgpu's check of indirect dispatch arguments (`VALIDATION_INDIRECT_CALL`, on in release
/// builds too) is turned off unless `WGPU_VALIDATION_INDIRECT_CALL` asks for it: it adds a
/// validating dispatch and its barriers before every indirect dispatch, and the solver
/// issues one indirect dispatch per color per iteration, whose arguments cdlab's own kernels
/// write (`solve_args`, `conv_check`, `contact_args`), each bounded by the contact
/// capacity over the workgroup size.
fn instance() -> wgpu::Instance {
    let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
    desc.backends = wgpu::Backends::all();
    desc.flags.remove(wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL);
    wgpu::Instance::new(desc.with_env())
}

/// The names `WGPU_BACKEND` accepts (a comma-separated list), as wgpu reads them.
pub const BACKEND_NAMES: &[&str] = &[
    "vulkan", "vk", "dx12", "d3d12", "metal", "mtl", "opengl", "gles", "gl", "webgpu",
];

/// Refuses a `WGPU_BACKEND` with a name wgpu does not know: wgpu ignores it, finds no
/// adapter, and the user is told to install a driver without a word about the variable.
fn check_backend_env() -> Result<()> {
    let Some(value) = std::env::var_os("WGPU_BACKEND") else {
        return Ok(());
    };
    let value = value.to_string_lossy();
    let unknown: Vec<&str> = value
        .split(',')
        .map(str::trim)
        .filter(|b| !BACKEND_NAMES.contains(&b.to_lowercase().as_str()))
        .collect();
    if unknown.is_empty() {
        return Ok(());
    }
    Err(crate::error::GpuError::BackendEnv {
        value: value.to_string(),
        unknown: unknown.iter().map(|b| b.to_string()).collect(),
        accepted: BACKEND_NAMES,
    }
    .into())
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
/// [`GpuError::NoAdapter`](crate::error::GpuError::NoAdapter) naming the packages to install when there is none.
pub fn open() -> Result<GpuDevice> {
    check_backend_env()?;
    let instance = instance();
    let mut adapters = pollster::block_on(instance.enumerate_adapters(wgpu::Backends::all()));
    adapters.retain(|a| a.get_info().backend != wgpu::Backend::Noop);
    adapters.sort_by_key(rank);
    let adapter = adapters
        .into_iter()
        .next()
        .ok_or_else(|| Error::Gpu(crate::error::GpuError::NoAdapter(NO_ADAPTER.to_string())))?;
    let info = adapter.get_info();
    if info.device_type == wgpu::DeviceType::Cpu {
        // A warning that cannot be shown (stderr closed or full) must not stop the work.
        use std::io::Write as _;
        let _ = writeln!(
            std::io::stderr(),
            "warning: no hardware GPU adapter; using the software adapter {} ({:?}): expect it to be slow",
            info.name,
            info.backend
        );
    }
    // The adapter's own limits: the buffer sizes are checked against them with a message
    // naming the limit, rather than against WebGPU's conservative defaults.
    let limits = adapter.limits();
    let features = adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("cdlab"),
        required_limits: limits.clone(),
        required_features: features,
        ..Default::default()
    }))
    .map_err(|e| crate::error::gpu_failure(format!("cannot open {}: {e}", info.name)))?;
    let errors = ErrorLog::default();
    let log = errors.clone();
    device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
        log.push(match e {
            wgpu::Error::OutOfMemory { .. } => "out of device memory".to_string(),
            e => e.to_string(),
        })
    }));
    let log = errors.clone();
    device.set_device_lost_callback(move |reason, message| {
        // Dropping the device reports a loss too: that one is no failure.
        if reason != wgpu::DeviceLostReason::Destroyed {
            log.push(format!("device lost ({reason:?}): {message}"));
        }
    });
    Ok(GpuDevice {
        device,
        queue,
        info,
        limits,
        errors,
        timestamps: !features.is_empty(),
    })
}
