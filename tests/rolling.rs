//! Disks on frictional planes under gravity (docs/validation.md, "Rolling and sliding").

mod common;

use cdlab::solver::Method;
use common::*;
use glam::DVec2;

const G: f64 = 9.81;

/// A disk of radius `r` resting on the floor y = 0 with gravity tilted by `angle` (the
/// frame of a plane inclined at `angle`, downhill along +x). Returns the velocity and spin
/// after `steps` steps.
fn incline(angle: f64, mu: f64, r: f64, steps: usize) -> (f64, f64, f64) {
    incline_with(angle, mu, r, steps, tight(Method::Gs))
}

/// [`incline`] with step parameters `params`.
fn incline_with(
    angle: f64,
    mu: f64,
    r: f64,
    steps: usize,
    params: cdlab::engine::StepParams,
) -> (f64, f64, f64) {
    let mut s = scene(mu);
    s.walls.push(floor());
    s.gravity = G * DVec2::new(angle.sin(), -angle.cos());
    s.disks.push(DVec2::new(0.0, r), r, RHO).unwrap();
    let mut e = cdlab::engine::CpuEngine::new(params).unwrap();
    for _ in 0..steps {
        e.step(&mut s).unwrap();
    }
    let t = steps as f64 * e.params.dt;
    (s.disks.vel[0].x / t, s.disks.spin[0] / t, s.disks.pos[0].y - r)
}

#[test]
fn disk_on_an_incline_rolls_without_slipping_below_the_friction_limit() {
    let (mu, r) = (0.3, 0.8);
    // tan(a) = 0.6 <= 3 mu = 0.9: rolling.
    let a = 0.6f64.atan();
    let (acc, alpha, lift) = incline(a, mu, r, 200);
    // Expected: linear acceleration (2/3) g sin a (rolling disk, I = m r^2 / 2), angular
    // acceleration -acc / r (rolling downhill is clockwise).
    let expected = 2.0 / 3.0 * G * a.sin();
    assert!(
        (acc - expected).abs() < 1e-9 * expected,
        "a = {acc}, expected {expected} m/s^2"
    );
    assert!(
        (alpha + expected / r).abs() < 1e-9 * expected / r,
        "alpha = {alpha} rad/s^2"
    );
    assert!(lift.abs() < 1e-12, "the disk must stay on the plane ({lift} m)");
}

#[test]
fn disk_on_a_steep_incline_slips_with_coulomb_friction() {
    let (mu, r) = (0.2, 0.8);
    // tan(a) = 1 > 3 mu = 0.6: slipping.
    let a = std::f64::consts::FRAC_PI_4;
    let (acc, alpha, _) = incline(a, mu, r, 200);
    // Expected: a = g (sin a - mu cos a), angular acceleration 2 mu g cos a / r (clockwise).
    let expected = G * (a.sin() - mu * a.cos());
    let expected_alpha = -2.0 * mu * G * a.cos() / r;
    assert!(
        (acc - expected).abs() < 1e-9 * expected,
        "a = {acc}, expected {expected} m/s^2"
    );
    assert!(
        (alpha - expected_alpha).abs() < 1e-9 * expected_alpha.abs(),
        "alpha = {alpha}"
    );
}

/// Both inclines at the built-in settings: a single contact, which one Gauss-Seidel update
/// solves exactly whatever the tolerance, relaxation or velocity test, so the closed forms
/// hold to the same 1e-9 as with the tight settings.
#[test]
fn inclines_at_the_built_in_settings() {
    for method in [Method::ColoredGs, Method::Gs] {
        let r = 0.8;
        let a = 0.6f64.atan();
        let (acc, alpha, lift) = incline_with(a, 0.3, r, 200, builtin(method));
        let rolling = 2.0 / 3.0 * G * a.sin();
        assert!(
            (acc - rolling).abs() < 1e-9 * rolling,
            "{method:?}: rolling a = {acc}, expected {rolling}"
        );
        assert!(
            (alpha + rolling / r).abs() < 1e-9 * rolling / r,
            "{method:?}: alpha = {alpha}"
        );
        assert!(lift.abs() < 1e-12, "{method:?}: lift {lift} m");
        let (mu, a) = (0.2, std::f64::consts::FRAC_PI_4);
        let (acc, alpha, _) = incline_with(a, mu, r, 200, builtin(method));
        let slipping = G * (a.sin() - mu * a.cos());
        let spin = -2.0 * mu * G * a.cos() / r;
        assert!(
            (acc - slipping).abs() < 1e-9 * slipping,
            "{method:?}: slipping a = {acc}, expected {slipping}"
        );
        assert!(
            (alpha - spin).abs() < 1e-9 * spin.abs(),
            "{method:?}: alpha = {alpha}, expected {spin}"
        );
    }
}

#[test]
fn sliding_spinning_disk_on_a_floor_ends_rolling_at_the_predicted_velocity() {
    let (mu, r, v0, w0) = (0.4, 0.5, 3.0, 4.0);
    let mut s = scene(mu);
    s.walls.push(floor());
    s.gravity = DVec2::new(0.0, -G);
    s.disks.push(DVec2::new(0.0, r), r, RHO).unwrap();
    s.disks.vel[0] = DVec2::new(v0, 0.0);
    s.disks.spin[0] = w0;
    let mut e = engine(Method::Gs);
    let dt = e.params.dt;
    // Expected (docs/validation.md): the slip v + r w decays at 3 mu g, so rolling starts at
    // t* = |v0 + r w0| / (3 mu g); afterwards v = (2 v0 - r w0) / 3 and w = -v / r.
    let t_roll = (v0 + r * w0).abs() / (3.0 * mu * G);
    let v_final = (2.0 * v0 - r * w0) / 3.0;
    let mut rolled_at = None;
    for k in 1..=((2.0 * t_roll / dt) as usize) {
        e.step(&mut s).unwrap();
        let slip = s.disks.vel[0].x + r * s.disks.spin[0];
        if rolled_at.is_none() && slip.abs() < 1e-9 {
            rolled_at = Some(k as f64 * dt);
        }
    }
    let t = rolled_at.expect("the disk must end up rolling");
    // The discrete slip reaches zero within the step that contains t*.
    assert!(
        (t - t_roll).abs() <= dt,
        "rolling from {t} s, expected {t_roll} s"
    );
    assert!(
        (s.disks.vel[0].x - v_final).abs() < 1e-9,
        "v = {}, expected {v_final}",
        s.disks.vel[0].x
    );
    assert!(
        (s.disks.spin[0] + v_final / r).abs() < 1e-9,
        "w = {}",
        s.disks.spin[0]
    );
}

/// Wall friction and disk friction are separate coefficients: on a 45-degree incline (the
/// floor is a wall) a disk slips with a = g (sin a - mu_wall cos a) whatever mu_disk is, and
/// rolls at (2/3) g sin a when mu_wall alone allows it (tan a = 1 <= 3 mu_wall). Swapping the
/// two coefficients swaps the outcomes, so the floor reads mu_wall, not mu_disk.
#[test]
fn a_wall_uses_the_wall_friction_not_the_disk_friction() {
    let (r, a) = (0.8, std::f64::consts::FRAC_PI_4);
    let run = |mu_disk: f64, mu_wall: f64| {
        let mut s = scene(mu_disk);
        s.material.mu_wall = mu_wall;
        s.walls.push(floor());
        s.gravity = G * DVec2::new(a.sin(), -a.cos());
        s.disks.push(DVec2::new(0.0, r), r, RHO).unwrap();
        let mut e = engine(Method::Gs);
        for _ in 0..200 {
            e.step(&mut s).unwrap();
        }
        s.disks.vel[0].x / (200.0 * e.params.dt)
    };
    let slip = run(0.8, 0.2);
    let expected = G * (a.sin() - 0.2 * a.cos());
    assert!(
        (slip - expected).abs() < 1e-9 * expected,
        "mu_wall 0.2: a = {slip}, expected {expected} m/s^2 (slipping)"
    );
    let roll = run(0.2, 0.8);
    let expected = 2.0 / 3.0 * G * a.sin();
    assert!(
        (roll - expected).abs() < 1e-9 * expected,
        "mu_wall 0.8: a = {roll}, expected {expected} m/s^2 (rolling)"
    );
}
