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
    let mut p = ProtocolParams::paper_defaults(300);
    p.strip_thickness = 3.0;
    p.strain_end = 0.006;
    p.series_every = 20;
    p.step.solver.tol = 1e-3;
    p
}

fn compression(rows: &[SeriesRow]) -> Vec<SeriesRow> {
    rows.iter()
        .filter(|r| r.phase == "compression")
        .cloned()
        .collect()
}

#[test]
fn short_biaxial_run_gives_the_same_macroscopic_curve_on_both_backends() {
    let p = params();
    // Compaction on the CPU, once: both backends start from the same compacted sample.
    let (scene, _) = prepare::deposit_scene(&p).unwrap();
    let mut lab = Lab::new(
        CpuBackend::new(scene.clone(), p.step).unwrap(),
        p.clone(),
        &scene,
        false,
    )
    .unwrap();
    let mut obs = Collect::default();
    while lab.state.phase == Phase::Compaction {
        lab.advance(&mut obs).unwrap();
    }
    let compacted = lab.backend.scene().unwrap();
    let mut curves = Vec::new();
    let Some(gpu) = gpu_support::gpu_or_skip("short biaxial run", &compacted, p.step) else {
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
    assert!(c.len() > 10 && g.len() > 10, "{} and {} rows", c.len(), g.len());
    let mean = |rows: &[SeriesRow]| rows.iter().map(|r| r.sigma1_pa).sum::<f64>() / rows.len() as f64;
    let (mc, mg) = (mean(c), mean(g));
    // Band: 10% of the mean axial stress. The two paths solve in f64 and f32 with different
    // colorings, so contacts slip at different instants; on a 300-disk sample sigma1
    // fluctuates by about 10% from row to row, its mean over the run much less.
    assert!(
        (mc - mg).abs() < 0.1 * mc,
        "mean sigma1 CPU {mc:.4e} Pa, GPU {mg:.4e} Pa"
    );
    // Volume change at the end: within 0.002 (about a third of its value at this strain).
    let (vc, vg) = (
        c.last().unwrap().volumetric_strain,
        g.last().unwrap().volumetric_strain,
    );
    assert!((vc - vg).abs() < 2e-3, "final dV/V0 CPU {vc:.4}, GPU {vg:.4}");
    println!(
        "mean sigma1 CPU {:.3} MPa, GPU {:.3} MPa; final dV/V0 CPU {vc:.4}, GPU {vg:.4}",
        mc / 1e6,
        mg / 1e6
    );
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
    // Upload stores f32 coordinates relative to the sample centre: at 30 m from it one f32
    // ulp is 2e-6 m, so a round trip may move a disk by a few ulps, never by 1e-4 m.
    let worst = (0..scene.disks.len())
        .map(|k| (scene.disks.pos[k] - back.disks.pos[k]).length())
        .fold(0.0, f64::max);
    assert!(worst < 1e-4, "worst position error {worst:e} m");
    let worst_wall = (0..scene.walls.len())
        .map(|w| (scene.walls[w].point - back.walls[w].point).length())
        .fold(0.0, f64::max);
    assert!(worst_wall < 1e-4, "worst wall error {worst_wall:e} m");
}
