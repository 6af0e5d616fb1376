//! A short biaxial run on both backends from the same compacted sample (docs/validation.md,
//! "Cross-checks between the two backends"): chaotic dynamics diverge in detail, the
//! macroscopic curve must not.

mod common;
mod gpu_support;

use cdlab::backend::{Backend, CpuBackend};
use cdlab::measure::SeriesRow;
use cdlab::protocol::biaxial::Lab;
use cdlab::protocol::{Collect, Phase, ProtocolParams, prepare};

fn params() -> ProtocolParams {
    let mut p = cdlab::Config::with_disks(300).protocol();
    p.strip_thickness = 3.0;
    p.strain_end = 0.006;
    p.series_every = 20;
    p.step.solver.tol = 1e-3;
    p
}

/// The sample of `p` deposited and compacted on the CPU, once for both backends.
fn compacted(p: &ProtocolParams) -> cdlab::model::Scene {
    let (scene, _) = prepare::deposit_scene(p).unwrap();
    let cpu = CpuBackend::new(scene.clone(), p.step).unwrap();
    let mut lab = Lab::new(cpu, p.clone(), &scene, false).unwrap();
    let mut obs = Collect::default();
    while lab.state.phase == Phase::Compaction {
        lab.advance(&mut obs).unwrap();
    }
    lab.backend.scene().unwrap()
}

fn compression(rows: &[SeriesRow]) -> Vec<SeriesRow> {
    rows.iter()
        .filter(|r| r.phase == "compression")
        .cloned()
        .collect()
}

#[test]
fn short_biaxial_run_gives_the_same_macroscopic_curve_on_both_backends() {
    cross_check(params());
}

/// The same whole run with the Jacobi method on both backends (relaxation 0.5, the
/// built-in), held to the same bands: Jacobi's GPU kernels (WGSL `jacobi_solve`,
/// `jacobi_commit`) through confinement and compression, not only one step. Measured on
/// lavapipe: CPU-GPU gaps 0.044, 0.044, 0.018 and 5.3e-4 (the order of the bands); the
/// CPU's own 1-ulp spread with Jacobi 0.031, 0.009, 0.002 and 4.2e-4, inside the colored
/// Gauss-Seidel study's range below.
#[test]
fn a_jacobi_run_gives_the_same_macroscopic_curve_on_both_backends() {
    let mut p = params();
    p.step.solver.method = cdlab::Method::Jacobi;
    cross_check(p);
}

/// Runs `p` from one compacted sample on the CPU and on the GPU, and on the CPU again with
/// one disk moved by one ulp, and holds the CPU-GPU gap of the compression's curves to the
/// bands of the CPU's own spread (the study below).
fn cross_check(p: ProtocolParams) {
    // Compaction on the CPU, once: both backends start from the same compacted sample.
    let compacted = compacted(&p);
    let mut curves = Vec::new();
    let what = format!("short biaxial run ({})", p.step.solver.method.name());
    let Some(gpu) = gpu_support::gpu_or_skip(&what, &compacted, p.step) else {
        return;
    };
    let cpu = CpuBackend::new(compacted.clone(), p.step).unwrap();
    for backend in [Box::new(cpu) as Box<dyn Backend>, Box::new(gpu)] {
        let mut lab = Lab::new(backend, p.clone(), &compacted, true).unwrap();
        let mut obs = Collect::default();
        lab.run(&mut obs).unwrap();
        curves.push(compression(&obs.rows));
    }
    let (c, g) = (&curves[0], &curves[1]);
    assert!(c.len() > 40, "{} rows", c.len());
    // The natural spread of this test: the same CPU run from the compacted sample with one
    // disk moved by one ulp (1e-15 m). The dynamics are chaotic: contacts open and close at
    // other instants and the row-by-row curves part within a few rows, so no comparison of
    // two backends can be tighter than this.
    let mut nudged = compacted.clone();
    nudged.disks.pos[0].x = nudged.disks.pos[0].x.next_up();
    let mut lab = Lab::new(
        Box::new(CpuBackend::new(nudged.clone(), p.step).unwrap()) as Box<dyn Backend>,
        p.clone(),
        &nudged,
        true,
    )
    .unwrap();
    let mut obs = Collect::default();
    lab.run(&mut obs).unwrap();
    let spread = curve_gap(c, &compression(&obs.rows));
    let gap = curve_gap(c, g);
    println!(
        "{what}: CPU vs CPU with one disk moved by 1 ulp: {spread:?}; CPU vs GPU: {gap:?} \
         ([RMS row sigma1, 16-row window sigma1, mean sigma1] relative, max row dV/V0)"
    );
    // Bands, from a trajectory-divergence study of this test (300 disks, strain 0.006, 63
    // rows of compression): twelve CPU runs, each with one disk (0, 25, ..., 275) moved by
    // one ulp, against the unperturbed run. Largest (and smallest) gaps over the twelve:
    //   RMS over rows of the relative sigma1 difference   0.051 (0.032)
    //   16-row windows of sigma1, largest relative gap     0.054 (0.004)
    //   mean sigma1 over the run, relative                 0.014 (0.001)
    //   largest row difference of dV/V0                    3.9e-4 (1.2e-4)
    // The GPU run (f32, colored Gauss-Seidel, convergence checked every 8 iterations) gave
    // 0.046, 0.043, 0.015 and 3.0e-4: inside the CPU's own spread, so f32 and the coloring
    // add nothing visible over chaos on this test. Bands: 1.5 times the largest CPU gap
    // (room for the spread of other samples of the ensemble). The former bands (10% on the
    // mean sigma1, 2e-3 on the final dV/V0) were 7 and 5 times wider.
    let band = [0.075, 0.08, 0.021, 6e-4];
    let names = [
        "RMS row sigma1",
        "16-row window sigma1",
        "mean sigma1",
        "row dV/V0",
    ];
    for k in 0..4 {
        assert!(
            spread[k] < band[k],
            "{}: the CPU's 1-ulp spread {:.3e} exceeds the band {:.1e} set from it: the study \
             above is out of date",
            names[k],
            spread[k],
            band[k]
        );
        assert!(
            gap[k] < band[k],
            "{}: CPU vs GPU gap {:.3e} exceeds the band {:.1e} (the CPU's own 1-ulp spread: \
             {:.3e})",
            names[k],
            gap[k],
            band[k],
            spread[k]
        );
    }
}

/// The state downloaded from the GPU is the state uploaded, to f32 round-off.
#[test]
fn scene_round_trips_through_the_gpu() {
    let p = params();
    let (scene, _) = prepare::deposit_scene(&p).unwrap();
    let Some(mut gpu) = gpu_support::gpu_or_skip("scene round trip", &scene, p.step) else {
        return;
    };
    gpu.set_scene(&scene).unwrap();
    let back = gpu.scene().unwrap();
    // Upload stores each coordinate as an f32 relative to the sample centre c (the middle
    // of the disks' bounding box, src/gpu/backend.rs): rounding to the nearest f32 moves x - c
    // by at most 2^-24 |x - c| (half an ulp), and adding c back in f64 adds at most one f64
    // ulp of x. At 30 m from the centre that is 1.8e-6 m; the former bound was 1e-4 m.
    let d = &scene.disks;
    let lo = d
        .pos
        .iter()
        .fold(glam::DVec2::splat(f64::INFINITY), |a, p| a.min(*p));
    let hi = d
        .pos
        .iter()
        .fold(glam::DVec2::splat(f64::NEG_INFINITY), |a, p| a.max(*p));
    let c = 0.5 * (lo + hi);
    let bound = |x: f64, c: f64| (x - c).abs() * 2f64.powi(-24) + x.abs() * f64::EPSILON;
    let mut worst = 0.0f64;
    let mut check = |what: String, a: glam::DVec2, b: glam::DVec2| {
        for (x, y, c) in [(a.x, b.x, c.x), (a.y, b.y, c.y)] {
            assert!(
                (x - y).abs() <= bound(x, c),
                "{what}: {x} m came back as {y} m, beyond half an f32 ulp of {} m",
                x - c
            );
            worst = worst.max((x - y).abs());
        }
    };
    for k in 0..d.len() {
        check(format!("disk {k}"), d.pos[k], back.disks.pos[k]);
    }
    for w in 0..scene.walls.len() {
        check(format!("wall {w}"), scene.walls[w].point, back.walls[w].point);
    }
    // The walls are compared too, and something was rounded (the check saw f32 values).
    assert!(
        worst > 0.0,
        "no coordinate changed: the round trip was not through f32"
    );
    println!("worst round-trip error {worst:.2e} m");
}

/// Differences between two curves of the same test (row by row): RMS over rows of the
/// relative sigma_1 difference, the largest relative difference of sigma_1 summed over
/// windows of 16 rows, the relative difference of the mean sigma_1 over the run, and the
/// largest volumetric-strain difference of a row.
fn curve_gap(a: &[SeriesRow], b: &[SeriesRow]) -> [f64; 4] {
    // Rows are paired by their index in the compression: the confinement before it lasts a
    // different number of steps in each run, the compression's rows come at the same
    // strains (the top wall moves at a set velocity).
    assert_eq!(a.len(), b.len(), "rows of the compression");
    let n = a.len();
    for k in 0..n {
        let ds = (a[k].strain_axial - b[k].strain_axial).abs();
        assert!(
            ds < 1e-5,
            "row {k}: strains {} and {}",
            a[k].strain_axial,
            b[k].strain_axial
        );
    }
    let rel: Vec<f64> = (0..n)
        .map(|k| (b[k].sigma1_pa - a[k].sigma1_pa) / a[k].sigma1_pa)
        .collect();
    let rms = (rel.iter().map(|r| r * r).sum::<f64>() / n as f64).sqrt();
    let window = |rows: &[SeriesRow], k: usize| rows[k..k + 16].iter().map(|r| r.sigma1_pa).sum::<f64>();
    let win = (0..=n - 16)
        .step_by(16)
        .map(|k| ((window(b, k) - window(a, k)) / window(a, k)).abs())
        .fold(0.0, f64::max);
    let total = |r: &[SeriesRow]| r.iter().map(|r| r.sigma1_pa).sum::<f64>();
    let mean_rel = ((total(b) - total(a)) / total(a)).abs();
    let ev = (0..n)
        .map(|k| (b[k].volumetric_strain - a[k].volumetric_strain).abs())
        .fold(0.0, f64::max);
    [rms, win, mean_rel, ev]
}

/// Collects what a run reports and asks it to stop once a compression row reaches
/// `stop_at` axial strain.
struct StopAt {
    inner: Collect,
    stop_at: f64,
    cancel: cdlab::interrupt::Cancel,
}

impl cdlab::protocol::Observer for StopAt {
    fn series(&mut self, row: &SeriesRow) -> cdlab::Result<()> {
        if row.phase == "compression" && row.strain_axial >= self.stop_at {
            self.cancel.cancel();
        }
        self.inner.series(row)
    }
    fn phase_end(&mut self, end: &cdlab::protocol::PhaseEnd) -> cdlab::Result<()> {
        self.inner.phase_end(end)
    }
    fn snapshot(
        &mut self,
        strain: f64,
        scene: &cdlab::model::Scene,
        contacts: &[cdlab::backend::ContactRecord],
        reference: &[glam::DVec2],
    ) -> cdlab::Result<()> {
        self.inner.snapshot(strain, scene, contacts, reference)
    }
    fn checkpoint(&mut self, step: u64, bytes: &[u8]) -> cdlab::Result<()> {
        self.inner.checkpoint(step, bytes)
    }
}

/// A GPU run stopped in its compression, its checkpoint resumed on a new GPU backend, and
/// on the CPU, and run to the end, gives the curve of the uninterrupted GPU run within the
/// bands of the test above (the CPU's own spread under a 1-ulp change: the resumed backend
/// colors the contacts afresh, or is the CPU, so the trajectory parts as for any
/// perturbation), with its rows at the same strains and no row lost or doubled at the stop.
#[test]
fn gpu_run_resumed_from_its_checkpoint_follows_the_uninterrupted_one() {
    let p = params();
    let compacted = compacted(&p);
    let Some(gpu) = gpu_support::gpu_or_skip("GPU resume", &compacted, p.step) else {
        return;
    };
    let mut whole = Lab::new(gpu, p.clone(), &compacted, true).unwrap();
    let mut obs = Collect::default();
    whole.run(&mut obs).unwrap();
    let uninterrupted = compression(&obs.rows);

    let gpu = gpu_support::gpu_or_skip("GPU resume", &compacted, p.step).unwrap();
    let mut first = Lab::new(gpu, p.clone(), &compacted, true).unwrap();
    let cancel = cdlab::interrupt::Cancel::new();
    let mut stop = StopAt {
        inner: Collect::default(),
        stop_at: 0.5 * p.strain_end,
        cancel: cancel.clone(),
    };
    let stopped = first.run_until(&mut stop, &cancel);
    assert!(
        matches!(stopped, Err(cdlab::Error::Interrupted { .. })),
        "the run was not stopped: {stopped:?}"
    );
    let (step, bytes) = stop
        .inner
        .last_checkpoint
        .clone()
        .expect("no checkpoint at the stop");
    let ck = cdlab::protocol::checkpoint::decode(&bytes).unwrap();
    assert_eq!(ck.scene.step, step);
    let gpu = gpu_support::gpu_or_skip("GPU resume", &ck.scene, ck.state.params.step).unwrap();
    let cpu = CpuBackend::new(ck.scene.clone(), ck.state.params.step).unwrap();
    let before = compression(&stop.inner.rows);
    // The same checkpoint resumed on the GPU and on the CPU (a GPU run continued on a
    // machine without one).
    for backend in [Box::new(gpu) as Box<dyn Backend>, Box::new(cpu)] {
        let name = backend.name();
        let mut resumed = Lab::resume(backend, ck.clone()).unwrap();
        let mut rest = Collect::default();
        resumed.run(&mut rest).unwrap();
        let after = compression(&rest.rows);
        assert!(
            !before.is_empty() && !after.is_empty(),
            "{} rows before the stop, {} after on {name}",
            before.len(),
            after.len()
        );
        let mut joined = before.clone();
        joined.extend(after);
        // curve_gap pairs the rows by index and checks their strains: a row lost or
        // written twice at the stop fails there.
        let gap = curve_gap(&uninterrupted, &joined);
        println!("uninterrupted GPU run vs stopped and resumed on {name}: {gap:?}");
        let band = [0.075, 0.08, 0.021, 6e-4];
        for (k, (g, b)) in gap.iter().zip(band).enumerate() {
            assert!(
                *g < b,
                "measure {k}: resumed on {name} vs uninterrupted gap {g:.3e} exceeds the band {b:.1e}"
            );
        }
    }
}

/// What a run past its peak shows of its strength, from the compression's rows: the peak
/// of `sigma_1` averaged over windows of 16 rows (about 0.002 of strain) (Pa), the strain
/// at that window's centre, the mean `sigma_1` over the last 40 rows (about 0.005 of
/// strain) (Pa), and the last row's `dV/V0`.
fn strength(rows: &[SeriesRow]) -> [f64; 4] {
    let n = rows.len();
    let mean = |part: &[SeriesRow]| part.iter().map(|r| r.sigma1_pa).sum::<f64>() / part.len() as f64;
    let (peak, at) = (0..=n - 16)
        .map(|k| (mean(&rows[k..k + 16]), rows[k + 8].strain_axial))
        .fold((f64::MIN, 0.0), |a, b| if b.0 > a.0 { b } else { a });
    [peak, at, mean(&rows[n - 40..]), rows[n - 1].volumetric_strain]
}

/// The GPU past the peak. Run to 0.025 on both backends from one compacted sample (seed 3),
/// the CPU run must pass its peak (the peak before 70% of the compression, the last 40 rows
/// 5% or more below it) and dilate, the GPU run must dilate, and the GPU's peak, its strain,
/// the post-peak stress and the final dV/V0 must lie within 1.5 times the spread of twelve
/// CPU runs, each with one disk moved by 1e-5 m (floors: 0.5% of the stresses, 5e-4 of
/// strain, 1e-4 of dV/V0).
///
/// Why the GPU is not held to pass its own peak: the 300-disk curves have several maxima of
/// nearly the same height, and which one is highest depends on the trajectory. Measured on
/// lavapipe, seeds 1-9 to strains 0.025 and 0.03 (the CPU with the kept list's coloring):
/// no seed passed its peak by that rule on both backends; seed 3's CPU run peaks at 17.7
/// MPa at strain 0.009 and ends at 16.2 MPa, its GPU run's highest window is 18.0 MPa at
/// strain 0.021. What the test holds is that the GPU lies within the CPU's own spread.
///
/// Why 1e-5 m and not one ulp, as the short run's study: the GPU holds positions in f32
/// pairs and rounds what it is given to f32 (2.4e-6 m at 40 m), so past the peak its
/// trajectories part from the CPU's as those of runs moved by that much, not by 1e-15 m.
/// Measured on lavapipe: with one-ulp moves the CPU's final dV/V0 ranged over 7.7e-3 to
/// 9.4e-3 and the GPU's, 10.5e-3, lay above all twelve; with 1e-5 m moves three CPU runs
/// gave 8.2e-3 to 11.3e-3 and three GPU runs 8.8e-3 to 10.5e-3 (and seed 6: GPU 7.9e-3
/// inside the CPU's 5.7e-3 to 9.0e-3). The GPU's width is the outline of its own disks
/// (its reduction and the CPU's outline of its final scene agree to 1e-8 m).
#[test]
fn a_gpu_run_past_the_peak_stays_within_the_cpus_spread() {
    let mut p = params();
    p.seed = 3;
    p.strain_end = 0.025;
    let compacted = compacted(&p);
    let Some(gpu) = gpu_support::gpu_or_skip("a run past the peak", &compacted, p.step) else {
        return;
    };
    let run = |backend: Box<dyn Backend>, scene: &cdlab::model::Scene| {
        let mut lab = Lab::new(backend, p.clone(), scene, true).unwrap();
        let mut obs = Collect::default();
        lab.run(&mut obs).unwrap();
        compression(&obs.rows)
    };
    let cpu = strength(&run(
        Box::new(CpuBackend::new(compacted.clone(), p.step).unwrap()),
        &compacted,
    ));
    let gpu = strength(&run(Box::new(gpu), &compacted));
    assert!(
        cpu[1] < 0.7 * p.strain_end && cpu[2] < 0.95 * cpu[0] && cpu[3] > 0.005,
        "CPU: peak {:.3} MPa at strain {:.4}, {:.3} MPa at the end, final dV/V0 {:.2e}: not past \
         the peak, or not dilating",
        cpu[0] / 1e6,
        cpu[1],
        cpu[2] / 1e6,
        cpu[3]
    );
    assert!(gpu[3] > 0.005, "GPU: final dV/V0 {:.2e}: not dilating", gpu[3]);
    let mut spread = [0.0f64; 4];
    for disk in (0..300).step_by(25) {
        let mut nudged = compacted.clone();
        nudged.disks.pos[disk].x += 1e-5;
        let s = strength(&run(
            Box::new(CpuBackend::new(nudged.clone(), p.step).unwrap()),
            &nudged,
        ));
        for k in 0..4 {
            spread[k] = spread[k].max((s[k] - cpu[k]).abs());
        }
    }
    let floor = [0.005 * cpu[0], 5e-4, 0.005 * cpu[2], 1e-4];
    let names = [
        "peak sigma1 (Pa)",
        "strain at the peak",
        "post-peak sigma1 (Pa)",
        "final dV/V0",
    ];
    println!("past the peak: CPU {cpu:?}, GPU {gpu:?}, spread of the moved CPU runs {spread:?}");
    for k in 0..4 {
        let band = (1.5 * spread[k]).max(floor[k]);
        assert!(
            (gpu[k] - cpu[k]).abs() <= band,
            "{}: GPU {:.4e}, CPU {:.4e}, band {band:.3e} (the moved CPU runs' spread {:.3e})",
            names[k],
            gpu[k],
            cpu[k],
            spread[k]
        );
    }
}
