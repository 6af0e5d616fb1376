//! Choosing the backend a test runs on.

use crate::backend::{Backend, CpuBackend};
use crate::config::{Backend as Choice, Config};
use crate::engine::StepParams;
use crate::error::Result;
use crate::model::Scene;

use super::{Event, Progress};

/// The sample size from which `auto` takes a hardware GPU. Below it the CPU path is the
/// faster one: on an NVIDIA H200 the GPU's step is held at a few milliseconds by its
/// ordered dispatches, hundreds per step at about 4 microseconds each, and the whole
/// 5000-disk test took about 490 s there against 255 s on two of the host's CPU threads;
/// at 50,000 disks the GPU's step was 3.7 times faster than those two threads
/// (docs/gpu.md, "This version on the same kind of machine"). The same test's early
/// compression from prepared samples put the switch between 5000 and 10,000 disks there
/// (docs/gpu.md, "The iterations' margin, and `auto`'s threshold").
pub const AUTO_GPU_FROM_DISKS: usize = 10_000;

/// Opens the backend the configuration asks for. `auto` takes the GPU path only on a
/// hardware adapter (on the software one the CPU path is faster), for a sample of at
/// least [`AUTO_GPU_FROM_DISKS`] disks, and for a method the GPU path implements
/// ([`crate::solver::Method::on_gpu`]); the backend's [`Backend::name`] says which it took.
pub fn open_backend(config: &Config, scene: Scene, params: StepParams) -> Result<Box<dyn Backend>> {
    open_backend_noted(config, scene, params).map(|(backend, _)| backend)
}

/// As [`open_backend`], with a note for the user when `auto` left a hardware GPU unused
/// because the sample is small, so that a run on the CPU on a GPU machine says why.
pub fn open_backend_noted(
    config: &Config,
    scene: Scene,
    params: StepParams,
) -> Result<(Box<dyn Backend>, Option<String>)> {
    let (gpu, note) = match config.solver.backend {
        Choice::Cpu => (false, None),
        Choice::Gpu => (true, None),
        Choice::Auto if !params.solver.method.on_gpu() => (false, None),
        Choice::Auto => {
            let hardware = crate::gpu::device::list_adapters()
                .into_iter()
                .find(|a| a.device_type != "Cpu");
            auto_choice(hardware.map(|a| a.name).as_deref(), scene.disks.len())
        }
    };
    let backend: Box<dyn Backend> = if gpu {
        Box::new(crate::gpu::backend::GpuBackend::new(scene, params)?)
    } else {
        Box::new(CpuBackend::new(scene, params)?)
    };
    Ok((backend, note))
}

/// As [`open_backend`], telling `progress` when `auto` left a hardware GPU unused.
pub(super) fn open_backend_told(
    config: &Config,
    scene: Scene,
    params: StepParams,
    progress: &mut dyn Progress,
) -> Result<Box<dyn Backend>> {
    let (backend, note) = open_backend_noted(config, scene, params)?;
    if let Some(note) = &note {
        progress.event(&Event::BackendNote(note));
    }
    Ok(backend)
}

/// What `auto` takes for a method the GPU runs, given the best hardware adapter's name (if
/// any) and the sample's size: whether the GPU, and the note when it leaves one unused.
fn auto_choice(hardware: Option<&str>, disks: usize) -> (bool, Option<String>) {
    match hardware {
        Some(name) if disks < AUTO_GPU_FROM_DISKS => (
            false,
            Some(format!(
                "backend auto: {disks} disks run on the CPU, faster than a GPU below \
                 {AUTO_GPU_FROM_DISKS} disks; --backend gpu (solver.backend = \"gpu\") runs them \
                 on {name}"
            )),
        ),
        Some(_) => (true, None),
        None => (false, None),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn auto_takes_a_hardware_gpu_from_the_threshold_and_says_why_not_below_it() {
        let n = AUTO_GPU_FROM_DISKS;
        assert_eq!(auto_choice(None, n), (false, None));
        assert_eq!(auto_choice(None, n - 1), (false, None));
        assert_eq!(auto_choice(Some("NVIDIA H200"), n), (true, None));
        let (gpu, note) = auto_choice(Some("NVIDIA H200"), 5000);
        assert!(!gpu);
        let note = note.unwrap();
        assert!(
            note.contains("5000 disks") && note.contains("NVIDIA H200"),
            "{note}"
        );
        assert!(note.contains("--backend gpu"), "{note}");
    }
}
