//! Bit-reproducibility of the CPU path (docs/validation.md, "Determinism").

mod common;

use cdlab::model::Scene;
use cdlab::solver::Method;
use common::*;
use glam::DVec2;

/// A dense 50 x 50 lattice of slightly polydisperse disks with random velocities in a box,
/// under gravity: about 5000 candidate contacts, so each color is large enough to be swept
/// on several threads.
fn dense(seed: u64) -> Scene {
    let mut rng = Rng(seed);
    let mut s = scene(0.4);
    s.gravity = DVec2::new(0.0, -9.81);
    for a in 0..50 {
        for b in 0..50 {
            let r = rng.range(0.95, 1.0);
            let k = s
                .disks
                .push(DVec2::new(2.0 * a as f64, 2.0 * b as f64), r, RHO)
                .unwrap();
            s.disks.vel[k] = DVec2::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0));
        }
    }
    add_box(&mut s, -1.0, 99.0, -1.0, 99.0);
    s
}

/// [`dense`] with its right wall pushing on the sample with a column of glued disks:
/// their contacts share the wall and form the serial group of the colored sweeps.
fn pushed(seed: u64) -> Scene {
    let mut s = dense(seed);
    s.walls[3].drive = cdlab::model::WallDrive::Force {
        mass: 5e4,
        force: 2e5,
    };
    for b in 0..50 {
        s.disks.glue(49 * 50 + b, 3);
    }
    s
}

fn run(seed: u64, method: Method, parallel: bool) -> (Scene, usize) {
    let (s, largest, _) = run_on(seed, method, parallel, 0, None);
    (s, largest)
}

/// `relax`: Gauss-Seidel relaxation, the plain iterations before it and the velocity test
/// (m/s) (default: those of `tight`). Returns the state, the largest color's size and the
/// bits of every step's contact records (their bodies, gaps, offsets and impulses).
fn run_on(
    seed: u64,
    method: Method,
    parallel: bool,
    threads: usize,
    relax: Option<(f64, u32, f64)>,
) -> (Scene, usize, Vec<u64>) {
    let mut s = pushed(seed);
    let mut p = tight(method);
    p.alert = 0.2;
    p.solver.tol = 1e-6;
    p.solver.parallel = parallel;
    p.solver.threads = threads;
    // Colors here hold about 1500 contacts: lower the threshold so the threads do run.
    p.solver.parallel_min = 1024;
    if let Some((w, after, velocity_tol)) = relax {
        p.solver.gauss_seidel.relax = w;
        p.solver.gauss_seidel.relax_after = after;
        p.solver.velocity_tol = velocity_tol;
    }
    let mut e = cdlab::engine::CpuEngine::new(p).unwrap();
    let mut largest_color = 0;
    let mut records = Vec::new();
    for _ in 0..15 {
        e.step(&mut s).unwrap();
        records.extend(e.contacts().iter().flat_map(|c| {
            [c.i as u64, c.j as u64]
                .into_iter()
                .chain([c.gap, c.bias_n, c.rn, c.rt].map(f64::to_bits))
        }));
        if method == Method::ColoredGs {
            assert!(
                e.last_range_is_serial(),
                "the glued column's contacts form a serial group"
            );
        }
        largest_color = largest_color.max(
            e.color_ranges()
                .windows(2)
                .map(|w| w[1] - w[0])
                .max()
                .unwrap_or(0),
        );
    }
    (s, largest_color as usize, records)
}

fn bits(s: &Scene) -> Vec<u64> {
    let d = &s.disks;
    (0..d.len())
        .flat_map(|k| {
            [
                d.pos[k].x, d.pos[k].y, d.vel[k].x, d.vel[k].y, d.spin[k], d.theta[k],
            ]
        })
        .map(f64::to_bits)
        .collect()
}

#[test]
fn same_configuration_and_seed_give_bit_identical_states() {
    for method in [Method::Gs, Method::ColoredGs, Method::Jacobi] {
        let (a, _) = run(1, method, true);
        let (b, _) = run(1, method, true);
        assert_eq!(bits(&a), bits(&b), "{method:?}");
        let (c, _) = run(2, method, true);
        assert_ne!(bits(&a), bits(&c), "{method:?}: another seed must differ");
    }
}

#[test]
fn parallel_colored_sweeps_equal_sequential_ones_bit_for_bit() {
    // The thread team engages from 1024 contacts (parallel_min above); teams of 2 and 3
    // split colors of ~1500 contacts into uneven shares of 64-contact chunks, and must
    // still give exactly the sequential sweep (updates within a color commute).
    let (seq, largest, seq_records) = run_on(1, Method::ColoredGs, false, 0, None);
    assert!(largest >= 1024, "largest color has {largest} contacts");
    for threads in [2, 3] {
        let (par, _, par_records) = run_on(1, Method::ColoredGs, true, threads, None);
        assert_eq!(bits(&par), bits(&seq), "team of {threads}");
        assert!(
            par_records == seq_records,
            "team of {threads}: the contact records"
        );
    }
    // The same with relaxed sweeps from the 6th iteration: every member of the team must
    // switch at the same iteration. The relaxed run must differ from the plain one, or the
    // relaxation was never reached.
    let relax = Some((0.7, 5, 0.0));
    let (seq_relaxed, _, _) = run_on(1, Method::ColoredGs, false, 0, relax);
    assert_ne!(bits(&seq_relaxed), bits(&seq), "relaxation engaged");
    let (par_relaxed, _, _) = run_on(1, Method::ColoredGs, true, 2, relax);
    assert_eq!(bits(&par_relaxed), bits(&seq_relaxed), "relaxed team of 2");
    // And with the velocity test, which each member of the team runs on its share of the
    // bodies (uneven shares with 3).
    let tested = Some((0.7, 5, 5e-2));
    let (seq_tested, _, _) = run_on(1, Method::ColoredGs, false, 0, tested);
    assert_ne!(bits(&seq_tested), bits(&seq_relaxed), "velocity test engaged");
    for threads in [2, 3] {
        let (par_tested, _, _) = run_on(1, Method::ColoredGs, true, threads, tested);
        assert_eq!(
            bits(&par_tested),
            bits(&seq_tested),
            "team of {threads} with the velocity test"
        );
    }
    let (jp, _) = run(1, Method::Jacobi, true);
    let (js, _) = run(1, Method::Jacobi, false);
    assert_eq!(bits(&jp), bits(&js));
}

#[test]
fn bad_parameters_are_rejected_with_the_field_named() {
    let mut p = tight(Method::Gs);
    p.dt = 0.0;
    let e = cdlab::engine::CpuEngine::new(p).unwrap_err().to_string();
    assert!(e.contains("solver.dt"), "{e}");
    let mut p = tight(Method::Gs);
    p.theta = 0.3;
    let e = cdlab::engine::CpuEngine::new(p).unwrap_err().to_string();
    assert!(e.contains("solver.theta") && e.contains("[0.5, 1]"), "{e}");
    let mut p = tight(Method::Gs);
    p.solver.tol = f64::NAN;
    assert!(
        cdlab::engine::CpuEngine::new(p)
            .unwrap_err()
            .to_string()
            .contains("solver.tol")
    );
    let mut d = cdlab::model::Disks::default();
    assert!(
        d.push(DVec2::ZERO, -1.0, RHO)
            .unwrap_err()
            .to_string()
            .contains("radius")
    );
    assert!(d.push(DVec2::new(f64::NAN, 0.0), 1.0, RHO).is_err());
    let mut s = scene(-0.1);
    s.disks.push(DVec2::ZERO, 1.0, RHO).unwrap();
    assert!(s.validate().unwrap_err().to_string().contains("mu_disk"));
}

#[test]
fn an_overlap_above_the_limit_stops_the_run_naming_the_bodies() {
    let mut s = scene(0.0);
    s.disks.push(DVec2::new(0.0, 0.0), 1.0, RHO).unwrap();
    s.disks.push(DVec2::new(1.9, 0.0), 1.0, RHO).unwrap();
    let mut e = engine(Method::Gs);
    let msg = e.step(&mut s).unwrap_err().to_string();
    assert!(
        msg.contains("overlap") && msg.contains("disk 0") && msg.contains("disk 1"),
        "{msg}"
    );
    // The advice names the iteration cap, the usual cause at high friction.
    assert!(msg.contains("solver.max_iter = "), "{msg}");
}

#[test]
fn a_non_finite_state_stops_the_run() {
    let mut s = scene(0.0);
    s.disks.push(DVec2::new(0.0, 0.0), 1.0, RHO).unwrap();
    s.disks.vel[0] = DVec2::new(f64::NAN, 0.0);
    s.disks.push(DVec2::new(2.0, 0.0), 1.0, RHO).unwrap();
    let mut e = engine(Method::Gs);
    let msg = e.step(&mut s).unwrap_err().to_string();
    assert!(msg.contains("non-finite") && msg.contains("disk 0"), "{msg}");
}

/// In color order (colored Gauss-Seidel), the kept list gives the grid search's records
/// bit for bit, only grouped by color: within a color no two contacts share a body an
/// impulse can move, and the contacts with a force-driven wall's single degree of freedom
/// (those of the disks glued to it) are the last, serial, range. Checked while disks move,
/// after a column is glued to a wall that becomes force-driven, and after a radius changes.
#[test]
fn kept_pair_list_in_color_order_is_the_grid_search_records_properly_colored() {
    use cdlab::contact::detect::{CellGrid, Neighbours, detect};
    use cdlab::model::WallDrive;
    let mut s = dense(4);
    let mut e = cdlab::engine::CpuEngine::new(tight(Method::ColoredGs)).unwrap();
    let alert = 0.05;
    let mut list = Neighbours::default();
    let (mut grid, mut full, mut kept) = (CellGrid::default(), Vec::new(), Vec::new());
    let mut serial_steps = 0;
    for step in 0..120 {
        if step == 40 {
            // The left column (disks 0-49, at x = 0) glued to the left wall (wall 2 of
            // add_box), which is then driven by a force.
            for k in 0..50 {
                s.disks.glue(k, 2);
            }
            s.walls[2].drive = WallDrive::Force {
                mass: 50.0,
                force: 0.0,
            };
        }
        if step == 80 {
            s.disks.radius[1234] *= 0.9;
        }
        detect(&s, alert, &mut grid, &mut full).unwrap();
        list.detect_kept(&s, alert, 0.02, true, None, &mut kept, &[], |_, _, _, _| {})
            .unwrap();
        let mut by_key = kept.clone();
        by_key.sort_by_key(|c| c.key());
        assert_eq!(full, by_key, "step {step}");
        let ranges = list.contact_ranges();
        assert_eq!(ranges.first(), Some(&0));
        assert_eq!(ranges.last(), Some(&(kept.len() as u32)), "step {step}");
        let proper = ranges.len() - 1 - usize::from(list.serial_last());
        for (c, w) in ranges.windows(2).enumerate() {
            let part = &kept[w[0] as usize..w[1] as usize];
            if c >= proper {
                assert!(
                    part.iter().all(|k| k.ma != 0.0),
                    "step {step}: a plain contact in the serial range"
                );
                serial_steps += usize::from(!part.is_empty());
                continue;
            }
            let mut moved: Vec<u32> = part
                .iter()
                .flat_map(|k| {
                    assert!(k.ma == 0.0, "step {step}: a serial contact in color {c}");
                    [k.moves_i().then_some(k.i), k.moves_j().then_some(k.j)]
                })
                .flatten()
                .collect();
            let n = moved.len();
            moved.sort_unstable();
            moved.dedup();
            assert_eq!(
                moved.len(),
                n,
                "step {step}: two contacts of color {c} move one body"
            );
        }
        e.step(&mut s).unwrap();
    }
    assert!(
        serial_steps >= 60,
        "the glued column's contacts formed a serial range in {serial_steps} steps"
    );
    assert!(
        list.rebuilds > 3 && list.rebuilds < 100,
        "rebuilds {}",
        list.rebuilds
    );
}

/// The pair list kept across steps must give exactly the records of the full grid search
/// (same pairs, same order, same bits) while disks move, after disks are glued to a wall
/// (a pair of two non-free disks drops out, and a glued disk's pairs are keyed by their
/// free disk, which may come after a later glued disk's partner), and after a radius
/// changes.
#[test]
fn kept_pair_list_gives_the_grid_search_records_bit_for_bit() {
    use cdlab::contact::detect::{CellGrid, Neighbours, detect};
    let mut s = dense(3);
    let mut e = cdlab::engine::CpuEngine::new(tight(Method::ColoredGs)).unwrap();
    let alert = 0.05;
    let mut list = Neighbours::default();
    let (mut grid, mut full, mut kept) = (CellGrid::default(), Vec::new(), Vec::new());
    for step in 0..120 {
        if step == 40 {
            // Glue the bottom row to the floor wall (wall 0 of add_box), and the left
            // column too: disk 50's free partner 51 then comes before disk 2's partner 52,
            // so the glued disks' pairs, keyed by their free disk, are emitted out of the
            // order in which they are found.
            for k in (0..2500).step_by(50).chain(1..50) {
                s.disks.glue(k, 0);
            }
        }
        if step == 80 {
            s.disks.radius[1234] *= 0.9;
        }
        detect(&s, alert, &mut grid, &mut full).unwrap();
        // A skin of 0.02 m: disks moving at up to ~1.4 m/s cover half of it in about 15
        // steps of 0.5 ms, so the list is rebuilt now and then and reused in between.
        list.detect(&s, alert, 0.02, &mut kept).unwrap();
        assert_eq!(full, kept, "step {step}");
        // Sorted by key, as the warm start's merge with the previous step's impulses needs.
        assert!(
            kept.windows(2).all(|w| w[0].key() < w[1].key()),
            "step {step}: records out of key order"
        );
        e.step(&mut s).unwrap();
    }
    // Rebuilt at the start, after the radius change, and whenever a disk has moved 0.01 m
    // (every 10-20 steps here): both paths were exercised.
    assert!(
        list.rebuilds > 3 && list.rebuilds < 100,
        "rebuilds {}",
        list.rebuilds
    );
}

/// The engine gives the Gauss-Seidel solve its table of body properties in one pass over
/// the bodies; a solve given only the contacts builds it from them. Both must give the
/// same impulses and velocities bit for bit, with the velocity test on (it weighs each
/// body's spin by its lever) and with the glued column and its force-driven wall (whose
/// body the table leaves at zero). Plain Gauss-Seidel, as a replay of a colored step would
/// color again and sweep in another order.
#[test]
fn the_body_table_given_by_the_engine_is_the_one_the_contacts_give() {
    let mut s = pushed(6);
    let mut p = tight(Method::Gs);
    p.alert = 0.2;
    p.solver.tol = 1e-6;
    p.solver.velocity_tol = 1e-5;
    p.solver.gauss_seidel.relax_after = 5;
    let mut e = cdlab::engine::CpuEngine::new(p).unwrap();
    e.capture(true);
    let mut velocity_stops = 0;
    for step in 0..12 {
        let stats = e.step(&mut s).unwrap();
        let problem = e.captured().expect("a captured problem");
        let (solved, again) = problem.solve(&p.solver);
        assert_eq!(again.iterations, stats.solve.iterations, "step {step}");
        assert_eq!(solved.contacts, e.contacts(), "step {step}: impulses differ");
        velocity_stops += usize::from(stats.solve.converged && stats.solve.residual > p.solver.tol);
    }
    assert!(velocity_stops > 0, "the velocity test never stopped a step");
}
