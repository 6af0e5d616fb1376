use cdlab::backend::CpuBackend;
use cdlab::protocol::biaxial::Lab;
use cdlab::protocol::{Collect, ProtocolParams, prepare};
fn main() {
    let n: usize = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(300);
    let mut p = ProtocolParams::paper_defaults(n);
    p.strain_end = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(0.03);
    p.strip_thickness = std::env::args().nth(3).map(|s| s.parse().unwrap()).unwrap_or(3.0);
    p.series_every = 20;
    let t = std::time::Instant::now();
    let (scene, rep) = prepare::deposit_scene(&p).unwrap();
    println!("{rep:?}");
    let backend = CpuBackend::new(scene.clone(), p.step).unwrap();
    let mut lab = Lab::new(backend, p, &scene, false).unwrap();
    let mut obs = Collect::default();
    lab.run(&mut obs).unwrap();
    for e in &obs.ends {
        println!("{e:?}");
    }
    for (k, r) in obs.rows.iter().enumerate() {
        if k % 10 == 0 || r.phase != "compression" && k % 5 == 0 {
            println!(
                "{} t={:.3} eps={:.4} s1={:.3}MPa vol={:.4} it={:.1} itmax={} nc={} slide={} Z={:.2} ov={:.2e} ke={:.3e} H={:.2} W={:.2}",
                r.phase,
                r.time_s,
                r.strain_axial,
                r.sigma1_pa / 1e6,
                r.volumetric_strain,
                r.iterations,
                r.iterations_max,
                r.n_force,
                r.n_sliding,
                r.coordination,
                r.overlap_max_rel,
                r.kinetic_energy_j,
                r.height_m,
                r.width_m
            );
        }
    }
    println!("wall {:.1}s", t.elapsed().as_secs_f64());
}
