//! Protocol-level checks (docs/validation.md) on a small sample (a few hundred disks, short
//! strain), and resume-equals-uninterrupted on the CPU path.

use cdlab::backend::Backend;
use cdlab::backend::CpuBackend;
use cdlab::protocol::biaxial::Lab;
use cdlab::protocol::checkpoint::decode;
use cdlab::protocol::{Collect, Observer, Phase, ProtocolParams, prepare, walls};

fn small() -> ProtocolParams {
    let mut p = cdlab::Config::with_disks(600).protocol();
    // Shorter than the paper's 10%: a dense sample peaks and starts dilating within 2-3%.
    p.strain_end = 0.03;
    // The paper's 7.5 m strips are for an 86 m wide sample; this one is about 27 m wide.
    p.strip_thickness = 4.0;
    // A looser tolerance keeps the test to seconds; the strength moves by a few percent
    // (docs/results.md, "Solver tolerance").
    p.step.solver.tol = 1e-3;
    p.series_every = 10;
    p.checkpoint_every = 400;
    p.snapshot_every = 0.01;
    p
}

fn run_small() -> Collect {
    run_with(&small())
}

/// A whole test with `p`, from its deposit, on the CPU.
fn run_with(p: &ProtocolParams) -> Collect {
    let (scene, _) = prepare::deposit_scene(p).expect("deposit");
    let backend = CpuBackend::new(scene.clone(), p.step).expect("backend");
    let mut lab = Lab::new(backend, p.clone(), &scene, false).expect("lab");
    let mut obs = Collect::default();
    lab.run(&mut obs).expect("run");
    obs
}

#[test]
fn small_biaxial_test_confines_then_peaks_and_dilates() {
    let p = small();
    let obs = run_small();
    let phases: Vec<Phase> = obs.ends.iter().map(|e| e.phase).collect();
    assert_eq!(
        phases,
        [Phase::Compaction, Phase::Confinement, Phase::Compression]
    );
    for e in &obs.ends[..2] {
        assert!(e.settled, "{:?} did not reach equilibrium: {e:?}", e.phase);
    }
    // Confinement: the top wall carries sigma3 within 1% (docs/validation.md) and the sample is
    // isotropic before compression (the strips carry sigma3 by construction).
    let last_conf = obs
        .rows
        .iter()
        .rev()
        .find(|r| r.phase == "confinement")
        .expect("rows");
    let rel = (last_conf.sigma1_pa - p.sigma3).abs() / p.sigma3;
    assert!(
        rel < 0.01,
        "sigma1 at the end of confinement {} Pa vs sigma3 {} Pa",
        last_conf.sigma1_pa,
        p.sigma3
    );
    let comp: Vec<_> = obs.rows.iter().filter(|r| r.phase == "compression").collect();
    assert!(comp.len() > 20);
    // Compression: sigma1 rises well above sigma3 (the paper's peak at mu = 0.3 is about
    // 1.9 sigma3; a small sample is noisier, so ask only for 1.3 sigma3).
    let peak = comp.iter().map(|r| r.sigma1_pa).fold(0.0, f64::max);
    assert!(peak > 1.3 * p.sigma3, "peak sigma1 {peak} Pa");
    // Dense samples dilate once sheared (paper: positive dilation).
    let last = comp.last().expect("rows");
    assert!(
        last.volumetric_strain > 0.0,
        "volumetric strain {}",
        last.volumetric_strain
    );
    // Overlaps stay below 1% of the smallest radius (docs/method.md, "Overlaps").
    let worst = obs.rows.iter().map(|r| r.overlap_max_rel).fold(0.0, f64::max);
    assert!(worst < 0.01, "largest overlap {worst} r_min");
    assert!(last.strain_axial >= p.strain_end);
    // The ends of the compaction and the confinement (strain 0), every 0.01 of the
    // compression, and its end.
    let s = &obs.snapshots;
    assert_eq!(s.len(), 5, "snapshots: {s:?}");
    assert_eq!(&s[..2], &[0.0, 0.0], "{s:?}");
    for (k, want) in [(2, 0.01), (3, 0.02)] {
        assert!(s[k] >= want && s[k] < want + 1e-4, "{s:?}");
    }
    assert_eq!(
        s[4], last.strain_axial,
        "the last snapshot is the final state: {s:?}"
    );
}

/// Keeps the rows and every checkpoint.
#[derive(Default)]
struct AllCheckpoints {
    inner: Collect,
    checkpoints: Vec<(u64, Vec<u8>)>,
}

impl Observer for AllCheckpoints {
    fn series(&mut self, row: &cdlab::measure::SeriesRow) -> cdlab::Result<()> {
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
        self.checkpoints.push((step, bytes.to_vec()));
        Ok(())
    }
}

#[test]
fn resumed_run_equals_the_uninterrupted_run_bit_for_bit() {
    let p = small();
    let (scene, _) = prepare::deposit_scene(&p).expect("deposit");
    let mut lab = Lab::new(
        CpuBackend::new(scene.clone(), p.step).unwrap(),
        p.clone(),
        &scene,
        false,
    )
    .unwrap();
    let mut full = AllCheckpoints::default();
    lab.run(&mut full).unwrap();
    // Resume from a checkpoint taken during compression.
    let (step, bytes) = full
        .checkpoints
        .iter()
        .find(|(_, b)| decode(b).unwrap().state.phase == Phase::Compression)
        .cloned()
        .expect("a checkpoint during compression");
    let ck = decode(&bytes).unwrap();
    let mut resumed = Lab::resume(CpuBackend::new(ck.scene.clone(), p.step).unwrap(), ck).unwrap();
    let mut rest = Collect::default();
    resumed.run(&mut rest).unwrap();
    let tail: Vec<_> = full
        .inner
        .rows
        .iter()
        .filter(|r| r.step > step)
        .cloned()
        .collect();
    assert!(!tail.is_empty());
    assert_eq!(tail.len(), rest.rows.len());
    for (a, b) in tail.iter().zip(&rest.rows) {
        assert_eq!(a.sigma1_pa.to_bits(), b.sigma1_pa.to_bits(), "step {}", a.step);
        assert_eq!(a.volumetric_strain.to_bits(), b.volumetric_strain.to_bits());
        assert_eq!(a, b);
    }
}

#[test]
fn damaged_checkpoints_are_rejected() {
    assert!(decode(b"not a checkpoint").is_err());
    let mut c = AllCheckpoints::default();
    let p = small();
    let (scene, _) = prepare::deposit_scene(&p).unwrap();
    let mut lab = Lab::new(CpuBackend::new(scene.clone(), p.step).unwrap(), p, &scene, false).unwrap();
    lab.advance(&mut c).unwrap();
    lab.advance(&mut c).unwrap();
    let bytes = {
        let scene = cdlab::backend::Backend::scene(&mut lab.backend).unwrap();
        cdlab::protocol::checkpoint::encode(&lab.state, &scene, &[], &[], None)
    };
    assert!(decode(&bytes).is_ok());
    for cut in [9, 20, bytes.len() / 2, bytes.len() - 1] {
        assert!(decode(&bytes[..cut]).is_err(), "truncated at {cut}");
    }
}

/// A compression that leaves the quasi-static regime stops with an error after recording
/// its row. Here the limit is set below the kinetic ratio of a healthy compression of this
/// sample (about 1e-5 with the wall moving at 0.5 m/s; a runaway passes 1e-2), so the
/// first compression window must trip it.
#[test]
fn a_runaway_compression_stops_with_an_error() {
    let mut p = small();
    p.equilibrium.runaway_kinetic_ratio = 1e-9;
    let (scene, _) = prepare::deposit_scene(&p).expect("deposit");
    let backend = CpuBackend::new(scene.clone(), p.step).expect("backend");
    let mut lab = Lab::new(backend, p, &scene, false).expect("lab");
    let mut obs = Collect::default();
    let err = lab.run(&mut obs).expect_err("the guard trips").to_string();
    assert!(err.contains("no longer quasi-static"), "{err}");
    assert!(err.contains("runaway_kinetic_ratio"), "{err}");
    let compression: Vec<_> = obs.rows.iter().filter(|r| r.phase == "compression").collect();
    assert_eq!(compression.len(), 1, "stopped after the first compression row");
    assert_eq!(lab.state.phase, Phase::Compression);
}

#[test]
fn strips_follow_the_sides_and_carry_exactly_sigma3_times_height() {
    let mut p = small();
    p.strip_refresh_every = 20;
    let (scene, _) = prepare::deposit_scene(&p).expect("deposit");
    let backend = CpuBackend::new(scene.clone(), p.step).expect("backend");
    let mut lab = Lab::new(backend, p.clone(), &scene, false).expect("lab");
    let mut obs = Collect::default();
    while lab.state.phase != Phase::Compression {
        lab.advance(&mut obs).expect("preparation");
    }
    let first = lab.state.loading.strip.clone();
    lab.run(&mut obs).expect("compression");
    let s = lab.backend.scene().unwrap();
    let strip = &lab.state.loading.strip;
    let left = (0..first.len())
        .filter(|&k| first[k] != 0 && strip[k] == 0)
        .count();
    // As the sample widens the strips move out with its sides and their inner disks drop
    // out (7 of them in this test).
    assert!(left > 0, "no disk left the strips: the refresh is not exercised");
    // Each strip carries sigma3 x H (docs/protocol.md, "Confinement") and nothing else pushes: the
    // disks that left the strips have lost their share. H is the height at the start of
    // the last step, when the forces were set, one wall move of v dt above the final one.
    let h = s.walls[walls::TOP].point.y - s.walls[walls::BOTTOM].point.y + p.axial_velocity * p.step.dt;
    for side in [-1i8, 1] {
        let pushed: f64 = (0..s.disks.len())
            .filter(|&k| (s.disks.force[k].x < 0.0) == (side > 0) && s.disks.force[k].x != 0.0)
            .map(|k| s.disks.force[k].x.abs())
            .sum();
        let expected = p.sigma3 * h;
        assert!(
            (pushed - expected).abs() < 1e-9 * expected,
            "side {side}: disks push with {pushed} N/m, sigma3 x H = {expected} N/m"
        );
        // The strips stay at the sides: every member lies within the strip thickness of
        // the outermost disk of its side.
        let members: Vec<usize> = (0..strip.len()).filter(|&k| strip[k] == side).collect();
        let xs = members.iter().map(|&k| side as f64 * s.disks.pos[k].x);
        let outer = xs.clone().fold(f64::NEG_INFINITY, f64::max);
        let inner = xs.fold(f64::INFINITY, f64::min);
        assert!(
            outer - inner < p.strip_thickness + 2.0 * p.r_max,
            "side {side}: members span {} m",
            outer - inner
        );
    }
}

/// A dense sample sheared far enough softens to a plateau: sigma_1 peaks, falls to a
/// residual level, and holds it while the dilation stops (the critical state the paper this
/// lab reproduces reports for dense samples: peak, softening, residual plateau at a zero
/// rate of volume change). 600 disks to 12% axial strain, about 25000 steps on the CPU.
/// The curve of so small a sample is noisy (about 10% from one 1% window to the next), so
/// the claims are on 1%-strain windows, with margins taken from that noise.
#[test]
fn a_long_compression_softens_to_a_plateau() {
    let mut p = cdlab::Config::with_disks(600).protocol();
    p.strip_thickness = 4.0;
    p.strain_end = 0.12;
    p.step.solver.tol = 1e-3;
    p.series_every = 50;
    p.checkpoint_every = 100_000;
    p.snapshot_every = 0.0;
    let (scene, _) = prepare::deposit_scene(&p).expect("deposit");
    let backend = CpuBackend::new(scene.clone(), p.step).expect("backend");
    let mut lab = Lab::new(backend, p.clone(), &scene, false).expect("lab");
    let mut obs = Collect::default();
    lab.run(&mut obs).expect("run");
    let comp: Vec<_> = obs.rows.iter().filter(|r| r.phase == "compression").collect();
    // Mean sigma_1 / sigma_3 and the last dV/V0 of each 1% window of axial strain.
    let windows: Vec<(f64, f64)> = (0..12)
        .map(|w| {
            let rows: Vec<_> = comp
                .iter()
                .filter(|r| (r.strain_axial * 100.0).floor() as usize == w)
                .collect();
            assert!(rows.len() > 20, "window {w}: {} rows", rows.len());
            let m = rows.iter().map(|r| r.sigma1_pa).sum::<f64>() / rows.len() as f64 / p.sigma3;
            (m, rows.last().unwrap().volumetric_strain)
        })
        .collect();
    let text = format!("{windows:.4?}");
    let (peak_at, peak) = windows
        .iter()
        .enumerate()
        .map(|(k, w)| (k, w.0))
        .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
    // The peak comes early: within the first 6% of strain.
    assert!(peak_at < 6, "peak in window {peak_at}: {text}");
    // Softening: the last 5% of strain sits at least 8% below the peak window.
    let tail = &windows[7..];
    let residual = tail.iter().map(|w| w.0).sum::<f64>() / tail.len() as f64;
    assert!(
        residual < 0.92 * peak,
        "residual {residual:.3} vs peak {peak:.3} sigma3: no softening: {text}"
    );
    assert!(
        residual > 1.2,
        "residual {residual:.3} sigma3: the sample lost its strength"
    );
    // Plateau: every window of the last 5% within 20% of their mean.
    for (k, w) in tail.iter().enumerate() {
        assert!(
            (w.0 - residual).abs() < 0.2 * residual,
            "window {}: {:.3} vs the residual {residual:.3}: {text}",
            k + 7,
            w.0
        );
    }
    // The dilation stops: the volume change over 8-12% is under half that over 2-6%.
    let early = windows[5].1 - windows[1].1;
    let late = windows[11].1 - windows[7].1;
    assert!(early > 0.0, "the dense sample must dilate: {text}");
    assert!(
        late < 0.5 * early,
        "dV/V0 grew by {late:.4} over 8-12% vs {early:.4} over 2-6%: {text}"
    );
}

/// A packing at rest settles on its creep (docs/protocol.md, "Equilibrium") when its kinetic
/// ratio cannot reach its threshold: with thresholds no packing meets, the compaction and
/// the confinement still end settled, each with a recorded creep below the bound and a
/// kinetic ratio above its threshold, ten windows or more into the phase; without the
/// creep criterion the same compaction runs to its time cap, not settled.
#[test]
fn a_still_packing_settles_on_its_creep() {
    let mut p = small();
    p.strain_end = 0.001;
    p.equilibrium.kinetic_ratio = 1e-30;
    p.equilibrium.compaction_kinetic_ratio = 1e-30;
    p.equilibrium.max_time = 30.0;
    let obs = run_with(&p);
    let window_s = p.equilibrium.window as f64 * p.step.dt;
    let mut start = 0.0;
    for e in &obs.ends[..2] {
        let creep = e.creep_rate.expect("creep measured");
        assert!(e.settled && creep < p.equilibrium.creep_rate, "{e:?}");
        assert!(e.kinetic_ratio > 1e-30, "{e:?}");
        assert!(
            e.time_s - start >= 10.0 * window_s - 1e-9,
            "{e:?} settled before ten windows"
        );
        assert!(e.time_s - start < p.equilibrium.max_time, "{e:?}");
        start = e.time_s;
    }
    p.equilibrium.creep_rate = 0.0;
    p.equilibrium.max_time = 2.0;
    let capped = run_with(&p);
    let e = &capped.ends[0];
    // The cap is checked at the end of each window.
    assert!(
        !e.settled && e.time_s > 2.0 - 1e-9 && e.time_s < 2.0 + window_s + 1e-9,
        "{e:?}"
    );
}

/// Every solver method runs a short test at the built-in settings (docs/method.md's methods
/// otherwise meet only single steps or the fc2d problems in the suite): from one compacted
/// 600-disk sample, confinement and compression to strain 0.005 with each method. Each
/// must end, keep the largest overlap under the lab's bound of 1% of r_min, and follow colored Gauss-Seidel's sigma1 within 5% on average over the
/// compression: the methods stop at the same tolerance on different iterates, while a
/// method that solved another problem moves it by more (halving the contact friction lowers
/// the 1000-disk peak by 20%, assets/results/strength_bands.csv).
#[test]
fn every_solver_method_runs_a_short_test() {
    use cdlab::solver::Method;
    let mut config = cdlab::config::Config::default();
    config.sample.disks = 600;
    let mut p = config.protocol();
    p.strain_end = 0.005;
    p.strip_thickness = 4.0;
    let (scene, _) = prepare::deposit_scene(&p).expect("deposit");
    let backend = CpuBackend::new(scene.clone(), p.step).expect("backend");
    let mut lab = Lab::new(backend, p.clone(), &scene, false).expect("lab");
    let mut obs = Collect::default();
    while lab.state.phase == Phase::Compaction {
        lab.advance(&mut obs).expect("compaction");
    }
    let compacted = lab.backend.scene().expect("scene");
    let mean_sigma1 = |method: Method| {
        let mut q = p.clone();
        q.step.solver.method = method;
        if q.step.solver.validate().is_err() {
            // Methods without local updates of deep contacts refuse them by name.
            q.step.solver.deep_gap = 0.0;
            q.step.solver.deep_sweeps = 0;
        }
        let backend = CpuBackend::new(compacted.clone(), q.step).expect("backend");
        let mut lab = Lab::new(backend, q, &compacted, true).expect("lab");
        let mut obs = Collect::default();
        lab.run(&mut obs).unwrap_or_else(|e| panic!("{method:?}: {e}"));
        let rows: Vec<_> = obs.rows.iter().filter(|r| r.phase == "compression").collect();
        assert!(!rows.is_empty(), "{method:?}: no compression");
        let last = rows.last().unwrap();
        assert!(
            last.strain_axial >= 0.005 - 1e-9,
            "{method:?} ended at {}",
            last.strain_axial
        );
        let overlap = rows.iter().map(|r| r.overlap_max_rel).fold(0.0, f64::max);
        assert!(overlap < 0.01, "{method:?}: largest overlap {overlap} of r_min");
        let mean = rows.iter().map(|r| r.sigma1_pa).sum::<f64>() / rows.len() as f64;
        eprintln!(
            "{method:?}: mean sigma1 {:.3} MPa, largest overlap {overlap:.4}",
            mean / 1e6
        );
        mean
    };
    let reference = mean_sigma1(Method::ColoredGs);
    for method in [Method::Gs, Method::Jacobi, Method::AndersonGs, Method::Apgd] {
        let m = mean_sigma1(method);
        assert!(
            (m - reference).abs() < 0.05 * reference,
            "{method:?}: mean sigma1 {m} Pa against colored Gauss-Seidel's {reference} Pa"
        );
    }
}
