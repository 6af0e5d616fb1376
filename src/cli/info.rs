//! `cdlab info`: the GPU adapters wgpu can see, with the limits that bound the sample size.

use clap::Args as ClapArgs;

/// Arguments of `cdlab info`.
#[derive(ClapArgs, Debug)]
pub struct Args {
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// Lists the adapters, best first (the one `--backend gpu` picks is the first).
pub fn run(args: &Args) -> crate::Result<()> {
    let adapters = crate::gpu::device::list_adapters();
    if args.json {
        let text = serde_json::to_string_pretty(&adapters).map_err(|e| crate::Error::Other(e.to_string()))?;
        println!("{text}");
        return Ok(());
    }
    println!("cdlab {}", env!("CARGO_PKG_VERSION"));
    if adapters.is_empty() {
        println!("no GPU adapter: {}", crate::gpu::device::NO_ADAPTER);
        return Ok(());
    }
    println!("GPU adapters (best first; `--backend gpu` takes the first):");
    for (k, a) in adapters.iter().enumerate() {
        println!(
            "  [{k}] {} ({}, {}), driver {}\n      max storage binding {} MiB, max buffer {} MiB, \
             {} storage buffers/stage, {} workgroups/dim",
            a.name,
            a.device_type,
            a.backend,
            a.driver.trim(),
            a.max_storage_binding >> 20,
            a.max_buffer >> 20,
            a.max_storage_buffers_per_stage,
            a.max_workgroups_per_dim
        );
    }
    Ok(())
}
