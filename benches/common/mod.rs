//! What the benches that continue a recorded run share: reading the environment, and the
//! run's last checkpoint set to continue its compression with the overrides common to them.

use cdlab::protocol::Phase;
use cdlab::protocol::checkpoint::{Checkpoint, decode};
use cdlab::record::read_run;

/// The variable `name` parsed, or `None` when unset; exits with a message when it does not
/// parse.
pub fn env<T: std::str::FromStr>(name: &str) -> Option<T> {
    let v = std::env::var(name).ok()?;
    match v.parse() {
        Ok(x) => Some(x),
        Err(_) => {
            eprintln!("{name}={v} is not valid");
            std::process::exit(2);
        }
    }
}

/// The last checkpoint of the run in `dir`, set to continue compressing (to strain 0.99,
/// no snapshots) on `threads` threads, with the time step (`CDLAB_DT`, ms) and the disk
/// friction (`CDLAB_MU`) of the environment when set.
pub fn continued(dir: &std::ffi::OsStr, threads: usize) -> Result<Checkpoint, Box<dyn std::error::Error>> {
    let rec = read_run(dir)?;
    let (_, bytes) = rec
        .last_checkpoint
        .clone()
        .ok_or("the record holds no checkpoint")?;
    let mut ck = decode(&bytes)?;
    ck.state.phase = Phase::Compression;
    ck.state.params.strain_end = 0.99;
    ck.state.params.snapshot_every = 0.0;
    ck.state.params.step.solver.threads = threads;
    if let Some(ms) = env::<f64>("CDLAB_DT") {
        ck.state.params.step.set_dt(ms * 1e-3);
    }
    if let Some(mu) = env::<f64>("CDLAB_MU") {
        ck.scene.material.mu_disk = mu;
        ck.state.params.mu = mu;
    }
    Ok(ck)
}

/// The smallest disk radius of the checkpoint's scene (m): the unit of overlaps and of the
/// settings given as fractions of it.
pub fn r_min(ck: &Checkpoint) -> f64 {
    ck.scene
        .disks
        .radius
        .iter()
        .cloned()
        .fold(f64::INFINITY, f64::min)
}
