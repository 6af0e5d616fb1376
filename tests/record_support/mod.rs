//! A small biaxial test from a compacted sample, and what two runs of it must share bit for
//! bit, for the fault-injection tests of the records (`tests/faults.rs`,
//! `tests/stress_resume.rs`).
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use cdlab::cli::biaxial::{run_fresh, run_resume};
use cdlab::cli::run::Progress;
use cdlab::config::Config;
use cdlab::model::Scene;
use cdlab::protocol::biaxial::Lab;
use cdlab::protocol::{Collect, Phase, prepare};

/// 200 disks, 0.3% of axial strain, a checkpoint every 200 steps: about 7500 steps, most of
/// them in the confinement, under a second on one core.
pub fn config(series_every: u32) -> Config {
    Config::from_toml_str(&format!(
        "[sample]\ndisks = 200\n[solver]\ntol = 1e-3\nbackend = \"cpu\"\n\
         [test]\nstrip_thickness = \"3 m\"\nstrain_end = 0.003\n\
         [output]\nseries_every = {series_every}\nsnapshot_every = 0.001\ncheckpoint_every = 200\n"
    ))
    .expect("valid configuration")
}

/// The sample of `config` deposited and compacted (what `cdlab prepare` writes).
pub fn compacted(config: &Config) -> Scene {
    let params = config.protocol();
    let (scene, _) = prepare::deposit_scene(&params).expect("deposit");
    let backend = cdlab::backend::CpuBackend::new(scene.clone(), params.step).expect("backend");
    let mut lab = Lab::new(backend, params, &scene, false).expect("lab");
    let mut obs = Collect::default();
    while lab.state.phase == Phase::Compaction {
        lab.advance(&mut obs).expect("compaction");
    }
    cdlab::backend::Backend::scene(&mut lab.backend).expect("scene")
}

/// Writes a compacted scene to `path` in the checkpoint layout (read back by [`load`]).
pub fn save(path: &Path, config: &Config, scene: &Scene) {
    let lab = Lab::new(
        cdlab::backend::CpuBackend::new(scene.clone(), config.protocol().step).unwrap(),
        config.protocol(),
        scene,
        true,
    )
    .unwrap();
    let bytes = cdlab::protocol::checkpoint::encode(&lab.state, scene, &[], &[], None);
    std::fs::write(path, bytes).unwrap();
}

/// The scene written by [`save`].
pub fn load(path: &Path) -> Scene {
    cdlab::protocol::checkpoint::decode(&std::fs::read(path).unwrap())
        .unwrap()
        .scene
}

/// A fresh scratch directory.
pub fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("cdlab-rel-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs the test into `dir` from `scene`.
pub fn fresh(config: &Config, dir: &Path, scene: &Scene) -> cdlab::Result<()> {
    run_fresh(config, dir, Some(scene.clone()), &Progress::Quiet).map(drop)
}

/// Resumes the run in `dir`.
pub fn resume(dir: &Path) -> cdlab::Result<()> {
    run_resume(dir, None, &Progress::Quiet).map(drop)
}

/// What a run must share with any other run of its configuration and sample on the CPU
/// path, however often it was interrupted: its summary (all but the wall clock and the
/// identities), every recorded row (all but the wall clock) and its final checkpoint, the
/// complete mechanical state, byte for byte.
#[derive(Debug, PartialEq)]
pub struct Outcome {
    pub summary: serde_json::Value,
    pub rows: Vec<cdlab::record::SeriesRow>,
    pub last_checkpoint: (u64, Vec<u8>),
}

/// The [`Outcome`] of the finished run in `dir`.
pub fn outcome(dir: &Path) -> Outcome {
    let text = std::fs::read_to_string(dir.join("summary.json")).expect("summary.json");
    let mut summary: serde_json::Value = serde_json::from_str(&text).expect("summary JSON");
    let rec = cdlab::record::read_run(dir).expect("record");
    assert!(rec.truncated.is_none(), "{}: {:?}", dir.display(), rec.truncated);
    // The summary names the record beside it.
    assert_eq!(
        summary["record_id"].as_str(),
        rec.run_id.as_deref(),
        "{}",
        dir.display()
    );
    let obj = summary.as_object_mut().unwrap();
    // The checksum covers the wall clock too.
    for volatile in [
        "wall_time_s",
        "steps_per_second",
        "record_id",
        "backend",
        "checksum",
    ] {
        obj.remove(volatile);
    }
    let rows = rec
        .series
        .iter()
        .map(|r| cdlab::record::SeriesRow {
            wall_s: 0.0,
            ..r.clone()
        })
        .collect();
    Outcome {
        summary,
        rows,
        last_checkpoint: rec.last_checkpoint.expect("a final checkpoint"),
    }
}
