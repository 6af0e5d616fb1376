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
    if let Ok(t) = std::env::var("THETA") {
        p.step.theta = t.parse().unwrap();
    }
    if let Ok(t) = std::env::var("TOL") {
        p.step.solver.tol = t.parse().unwrap();
    }
    if let Ok(t) = std::env::var("METHOD") {
        p.step.solver.method = t.parse().unwrap();
    }
    let t = std::time::Instant::now();
    let (scene, rep) = prepare::deposit_scene(&p).unwrap();
    println!("{rep:?}");
    let backend = CpuBackend::new(scene.clone(), p.step).unwrap();
    let mut lab = Lab::new(backend, p, &scene, false).unwrap();
    struct O {
        c: Collect,
    }
    impl cdlab::protocol::Observer for O {
        fn series(&mut self, r: &cdlab::measure::SeriesRow) -> cdlab::Result<()> {
            self.c.series(r)
        }
        fn phase_end(&mut self, e: &cdlab::protocol::PhaseEnd) -> cdlab::Result<()> {
            self.c.phase_end(e)
        }
        fn checkpoint(&mut self, s: u64, b: &[u8]) -> cdlab::Result<()> {
            self.c.checkpoint(s, b)
        }
        fn snapshot(
            &mut self,
            strain: f64,
            scene: &cdlab::model::Scene,
            _: &[cdlab::backend::ContactRecord],
            _: &[glam::DVec2],
        ) -> cdlab::Result<()> {
            // core packing fraction: disks whose centre is in the middle 50% x 50% box, area / box area approx
            let d = &scene.disks;
            let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
            for k in 0..d.len() {
                x0 = x0.min(d.pos[k].x);
                x1 = x1.max(d.pos[k].x);
                y0 = y0.min(d.pos[k].y);
                y1 = y1.max(d.pos[k].y);
            }
            let (cx0, cx1, cy0, cy1) = (
                x0 + 0.25 * (x1 - x0),
                x1 - 0.25 * (x1 - x0),
                y0 + 0.25 * (y1 - y0),
                y1 - 0.25 * (y1 - y0),
            );
            let mut a = 0.0;
            for k in 0..d.len() {
                let p = d.pos[k];
                if p.x > cx0 && p.x < cx1 && p.y > cy0 && p.y < cy1 {
                    a += std::f64::consts::PI * d.radius[k].powi(2);
                }
            }
            println!(
                "snapshot strain {strain:.4} core phi {:.4}",
                a / ((cx1 - cx0) * (cy1 - cy0))
            );
            Ok(())
        }
    }
    let mut o = O {
        c: Collect::default(),
    };
    lab.run(&mut o).unwrap();
    let obs = o.c;
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
