//! Strength against the project's own seed statistics (docs/validation.md, "Strength bands
//! from seed statistics"). `benches/strength_bands.sh` ran the built-in 1000-disk test at
//! 8 MPa on ten samples (seeds 1-10) at contact friction 0.1, 0.3 and 3 (the last at a
//! time step of 0.25 ms) and wrote each test's peak and residual `sigma_1` to
//! `assets/results/strength_bands.csv`. A test here runs one of those tests again, exactly
//! as the study's sweep ran it (the sample prepared with the base configuration, the test
//! from it at the study's friction, pressure and time step), and checks it against the
//! study:
//!
//! - within 3 standard deviations of the ten samples' mean, at friction 0.3, 0.1 and 3;
//! - within 2 standard deviations of the same seed's stored result (a non-regression
//!   bound: a change that keeps the physics moves a single test by the spread between
//!   trajectories of one sample, smaller than the spread between samples);
//! - at friction 0.1, weaker than the same sample at friction 0.3 by more than twice the
//!   spread between samples.
//!
//! A friction read wrong fails here, where the whole-run tests of `tests/biaxial.rs` ask
//! only for a peak above 1.3 sigma3: the default test run at friction 0.15 instead of 0.3
//! (halved) gave a peak outside its stored result's band (docs/validation.md).

mod record_support;

use cdlab::config::{Config, Duration, Pressure};
use cdlab::interrupt::Cancel;
use cdlab::measure::summary::Summary;
use cdlab::run::{self, Silent};

/// The study's results, one line per test.
const STUDY: &str = include_str!("../assets/results/strength_bands.csv");
/// The study's base configuration.
const BASE: &str = include_str!("../assets/bands/base.toml");

/// One test of the study.
struct Stored {
    seed: u64,
    mu: f64,
    dt_ms: f64,
    peak: f64,
    residual: f64,
}

fn study() -> Vec<Stored> {
    let mut lines = STUDY.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .unwrap_or_else(|| panic!("no column {name} in the study"))
    };
    let (seed, mu, dt_ms, peak, residual) = (
        col("seed"),
        col("mu"),
        col("dt_ms"),
        col("sigma1_peak_mpa"),
        col("sigma1_residual_mpa"),
    );
    lines
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let num = |k: usize| f[k].parse::<f64>().unwrap_or_else(|e| panic!("{l}: {e}"));
            Stored {
                seed: num(seed) as u64,
                mu: num(mu),
                dt_ms: num(dt_ms),
                peak: num(peak),
                residual: num(residual),
            }
        })
        .collect()
}

/// Mean and sample standard deviation of `pick` over the study's tests at friction `mu`.
fn band(mu: f64, pick: fn(&Stored) -> f64) -> (f64, f64) {
    let v: Vec<f64> = study().iter().filter(|s| s.mu == mu).map(pick).collect();
    assert!(v.len() >= 6, "{} tests at friction {mu} in the study", v.len());
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    let sd = (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    (mean, sd)
}

/// The stored result of `seed` at friction `mu`.
fn stored(mu: f64, seed: u64) -> Stored {
    study()
        .into_iter()
        .find(|s| s.mu == mu && s.seed == seed)
        .unwrap_or_else(|| panic!("no test of seed {seed} at friction {mu} in the study"))
}

/// Runs the study's test of `seed` at friction `mu`, 8 MPa, as its sweep does.
fn run_test(mu: f64, seed: u64) -> Summary {
    let dir = record_support::scratch(&format!("strength-{mu}-{seed}"));
    let mut base = Config::from_toml_str(BASE).expect("the study's base configuration");
    base.sample.seed = seed;
    // Every core: the CPU path's result does not depend on the threads.
    base.solver.threads = 0;
    let scene = run::prepare(&base, &dir.join("sample.bin"), &mut Silent, &Cancel::new())
        .expect("sample")
        .scene;
    let mut config = base;
    config.test.mu = mu;
    config.test.sigma3 = Pressure(8e6);
    // The study's time step at this friction (its sweep's dt_by_friction).
    config.solver.dt = Duration(stored(mu, seed).dt_ms * 1e-3);
    config.output.dir = dir.join("test");
    let summary = run::start(
        &config,
        Some(scene),
        run::Existing::Refuse,
        &mut Silent,
        &Cancel::new(),
    )
    .expect("test")
    .summary;
    let _ = std::fs::remove_dir_all(&dir);
    summary
}

/// Checks a run's peak and residual against the study at its friction.
fn within_study(mu: f64, seed: u64, s: &Summary) {
    let residual = s
        .sigma1_residual_mpa
        .expect("a residual (the test runs to strain 0.1)");
    let reference = stored(mu, seed);
    for (name, value, (mean, sd), own) in [
        ("peak", s.sigma1_peak_mpa, band(mu, |s| s.peak), reference.peak),
        ("residual", residual, band(mu, |s| s.residual), reference.residual),
    ] {
        println!(
            "friction {mu}, seed {seed}: {name} sigma1 {value:.3} MPa; study {mean:.3} +- {sd:.3} \
             MPa, this seed {own:.3} MPa"
        );
        assert!(
            (value - mean).abs() <= 3.0 * sd,
            "friction {mu}, seed {seed}: {name} sigma1 {value:.3} MPa outside the ten samples' \
             {mean:.3} +- 3 x {sd:.3} MPa"
        );
        assert!(
            (value - own).abs() <= 2.0 * sd,
            "friction {mu}, seed {seed}: {name} sigma1 {value:.3} MPa moved from the stored \
             {own:.3} MPa by more than 2 x {sd:.3} MPa (the spread between samples)"
        );
    }
}

#[test]
fn the_default_test_is_within_the_seed_scatter_and_its_stored_result() {
    let s = run_test(0.3, 1);
    within_study(0.3, 1, &s);
}

#[test]
fn friction_3_is_within_the_seed_scatter_and_its_stored_result() {
    // The paper's DWH friction, at the study's 0.25 ms. Friction read as 0.3 (a scratch
    // edit, run once) gave seed 1 a peak of 17.18 MPa, 3.6 MPa from this seed's stored
    // 20.77 MPa where the bound is 2 x 0.88 MPa.
    let s = run_test(3.0, 1);
    within_study(3.0, 1, &s);
}

#[test]
fn friction_0_1_is_weaker_than_friction_0_3_beyond_the_scatter() {
    let s = run_test(0.1, 1);
    within_study(0.1, 1, &s);
    // Against the same sample at friction 0.3: a single sample sits anywhere in its band,
    // so the margin is twice the spread between samples at 0.3, not three times from the
    // mean (seed 1 at 0.1 is the strongest of its ten, 14.25 MPa, against 16.43 - 3 x
    // 0.68 MPa at 0.3).
    let other = stored(0.3, 1);
    let residual = s.sigma1_residual_mpa.expect("a residual");
    for (name, value, at_0_3, (_, sd)) in [
        ("peak", s.sigma1_peak_mpa, other.peak, band(0.3, |s| s.peak)),
        ("residual", residual, other.residual, band(0.3, |s| s.residual)),
    ] {
        assert!(
            value < at_0_3 - 2.0 * sd,
            "friction 0.1: {name} sigma1 {value:.3} MPa not below the same sample's {at_0_3:.3} \
             MPa at friction 0.3 less 2 x {sd:.3} MPa: the contact friction does not act as it \
             should"
        );
    }
}
