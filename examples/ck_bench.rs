//! Dev tool: times compression steps from a recorded checkpoint.
use cdlab::backend::CpuBackend;
use cdlab::protocol::biaxial::Lab;
use cdlab::protocol::checkpoint::decode;
use cdlab::protocol::{Collect, Phase};
use cdlab::record::read_run;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = &args[1];
    let windows: usize = args.get(2).map_or(10, |s| s.parse().unwrap());
    let threads: usize = args.get(3).map_or(1, |s| s.parse().unwrap());
    let rec = read_run(dir).unwrap();
    let (_, bytes) = rec.last_checkpoint.clone().unwrap();
    let mut ck = decode(&bytes).unwrap();
    ck.state.phase = Phase::Compression;
    ck.state.params.strain_end = 0.9;
    ck.state.params.snapshot_every = 0.0;
    ck.state.params.step.solver.threads = threads;
    if let Ok(m) = std::env::var("METHOD") {
        ck.state.params.step.solver.method = m.parse().unwrap();
    }
    if let Ok(t) = std::env::var("TOL") {
        ck.state.params.step.solver.tol = t.parse().unwrap();
    }
    let backend = CpuBackend::new(ck.scene.clone(), ck.state.params.step).unwrap();
    let mut lab = Lab::resume(backend, ck).unwrap();
    let mut obs = Collect::default();
    let t0 = std::time::Instant::now();
    for _ in 0..windows {
        lab.advance(&mut obs).unwrap();
    }
    let secs = t0.elapsed().as_secs_f64();
    let steps: u64 = obs.rows.len() as u64 * lab.state.params.series_every as u64;
    let it: f64 = obs.rows.iter().map(|r| r.iterations).sum::<f64>() / obs.rows.len() as f64;
    let c: f64 = obs.rows.iter().map(|r| r.n_contacts as f64).sum::<f64>() / obs.rows.len() as f64;
    let s1 = obs.rows.last().unwrap().sigma1_pa;
    println!(
        "{steps} steps, {:.3} ms/step, {it:.1} it/step, {c:.0} contacts, {:.2} ns/update, sigma1 {:.4e} Pa",
        secs / steps as f64 * 1e3,
        secs / (steps as f64 * it * c) * 1e9,
        s1
    );
}
