//! Choosing the backend a test runs on.

use crate::backend::{Backend, CpuBackend};
use crate::config::{Backend as Choice, Config};
use crate::engine::StepParams;
use crate::error::Result;
use crate::model::Scene;

/// Opens the backend the configuration asks for. `auto` takes the GPU path only on a
/// hardware adapter (on the software one the CPU path is faster) and for a method the GPU
/// path implements ([`crate::solver::Method::on_gpu`]); the backend's
/// [`Backend::name`] says which it took.
pub fn open_backend(config: &Config, scene: Scene, params: StepParams) -> Result<Box<dyn Backend>> {
    let gpu = match config.solver.backend {
        Choice::Cpu => false,
        Choice::Gpu => true,
        Choice::Auto => {
            params.solver.method.on_gpu()
                && crate::gpu::device::list_adapters()
                    .iter()
                    .any(|a| a.device_type != "Cpu")
        }
    };
    if gpu {
        Ok(Box::new(crate::gpu::backend::GpuBackend::new(scene, params)?))
    } else {
        Ok(Box::new(CpuBackend::new(scene, params)?))
    }
}
