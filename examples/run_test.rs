//! Runs a tiny biaxial test through the library API, with a progress callback, then reopens
//! its record and prints what it measured, each number with its unit.
//!
//! ```sh
//! cargo run --release --example run_test [OUTPUT_DIR]
//! ```
//!
//! 300 disks (the fewest the default boundary strips allow, about 270) on the CPU, compressed to 0.3% of axial strain: a few seconds. `docs/library.md`
//! describes the API; `tests/example.rs` runs this same code so that it cannot rot.

use std::path::{Path, PathBuf};

use cdlab::run::{self, Event, Existing};
use cdlab::{Backend, Cancel, Overrides};

/// What the example measured, read back from the finished run's record.
pub struct Measured {
    /// The run directory.
    pub dir: PathBuf,
    /// Series rows the progress callback received.
    pub rows_seen: usize,
    /// Phases the progress callback saw end (compaction, confinement, compression).
    pub phases_ended: Vec<String>,
    /// Peak axial stress of the reopened summary (MPa).
    pub sigma1_peak_mpa: f64,
    /// Axial strain of the record's last row.
    pub final_strain: f64,
    /// Rows in the reopened record.
    pub rows_recorded: usize,
}

/// Runs the tiny test into `dir` (replacing a run there) and reads it back.
pub fn run_example(dir: &Path) -> cdlab::Result<Measured> {
    // The built-in configuration with a few values replaced, as `cdlab biaxial --disks 300
    // --strain 0.003 --sigma3 "1 MPa" --backend cpu --out DIR` would do.
    let config = run::configure(
        None,
        &Overrides {
            disks: Some(300),
            strain: Some(0.003),
            sigma3: Some(run::sigma3("1 MPa", "sigma3")?),
            backend: Some(Backend::Cpu),
            out: Some(dir.to_path_buf()),
            ..Default::default()
        },
    )?;
    // Any closure taking an `&Event` is a progress callback. It runs on the thread that
    // runs the test, between windows of steps.
    let mut rows_seen = 0;
    let mut phases_ended = Vec::new();
    let mut progress = |event: &Event| match event {
        Event::Row { row, strain_end } if row.phase == "compression" => {
            rows_seen += 1;
            if rows_seen % 20 == 0 {
                eprintln!(
                    "  {:5.1}% of the compression, sigma1 {:.3} MPa",
                    100.0 * row.strain_axial / strain_end,
                    row.sigma1_pa / 1e6
                );
            }
        }
        Event::Row { .. } => rows_seen += 1,
        Event::PhaseEnd(end) => phases_ended.push(end.phase.name().to_string()),
        _ => {}
    };

    // A token another thread could set to stop the test at its next checkpoint; no signal
    // handler is installed, so Ctrl-C keeps its usual meaning.
    let cancel = Cancel::new();
    let outcome = run::start(&config, None, Existing::Replace, &mut progress, &cancel)?;

    // Everything below comes from the files the run left, not from memory.
    let finished = run::open(&outcome.dir)?;
    let summary = finished.summary.ok_or_else(|| cdlab::Error::Run {
        path: finished.dir.clone(),
        fault: cdlab::error::RunFault::Unfinished,
        message: format!("{}: the run has no summary", finished.dir.display()),
        remedy: None,
    })?;
    let last = finished.record.series.last().map_or(f64::NAN, |r| r.strain_axial);
    Ok(Measured {
        dir: outcome.dir,
        rows_seen,
        phases_ended,
        sigma1_peak_mpa: summary.sigma1_peak_mpa,
        final_strain: last,
        rows_recorded: finished.record.series.len(),
    })
}

fn main() -> cdlab::Result<()> {
    let dir = std::env::args_os()
        .nth(1)
        .map_or_else(|| std::env::temp_dir().join("cdlab_example_run"), PathBuf::from);
    let m = run_example(&dir)?;
    println!("run directory:   {}", m.dir.display());
    println!("phases ended:    {}", m.phases_ended.join(", "));
    println!(
        "rows recorded:   {} (the callback saw {})",
        m.rows_recorded, m.rows_seen
    );
    println!("final strain:    {:.4} (axial, dimensionless)", m.final_strain);
    println!("peak sigma1:     {:.3} MPa", m.sigma1_peak_mpa);
    Ok(())
}
