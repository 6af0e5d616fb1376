//! The GPU coloring on a contact graph large enough that a coloring kernel whose
//! per-thread work grows with the contact count would outrun Mesa's llvmpipe loop limiter
//! (every invocation gets 65,535 loop iterations in all, after which its loops exit
//! silently). The single-workgroup coloring did: from about 30,000 disks (65,000 contacts)
//! it stopped halfway and the step ended on "inconsistent color ranges" (issue 4, the
//! 50,000-disk bench). A hexagonal packing of equal disks gives the largest contact graph
//! for the fewest disks (three contacts owned per disk), so it is the cheapest trigger.
//!
//! Skips visibly without an adapter, fails with `CDLAB_REQUIRE_GPU=1` (or true, yes, on);
//! any other GPU error fails.

mod common;
#[path = "gpu_support/mod.rs"]
mod gpu_support;

use cdlab::backend::{Backend, Loading};
use cdlab::gpu::buffers::GpuContact;
use cdlab::solver::Method;
use gpu_support::*;

/// True when an impulse on contact `c` can move its body i (resp. j): the rule the
/// coloring must respect (shaders/common.wgsl `moves_i`, `moves_j`).
fn moves(c: &GpuContact) -> (bool, bool) {
    (
        c.mi != 0.0 || c.ki != 0.0,
        c.mj != 0.0 || c.ma != 0.0 || c.kj != 0.0,
    )
}

/// Checks a coloring: every contact colored below `colors`, and no two contacts of one
/// color share a body they can move. Returns the number of distinct colors used.
fn check_coloring(contacts: &[GpuContact], colors: u32) -> usize {
    let mut seen = std::collections::HashMap::new();
    let mut used = std::collections::BTreeSet::new();
    for (k, c) in contacts.iter().enumerate() {
        assert!(
            c.color < colors,
            "contact {k} ({}-{}) has color {:#x}, not below the {colors} colors of the step",
            c.i,
            c.j,
            c.color
        );
        used.insert(c.color);
        let (mi, mj) = moves(c);
        for (body, m) in [(c.i, mi), (c.j, mj)] {
            if let (true, Some(other)) = (m, seen.insert((body, c.color), k)) {
                panic!("contacts {other} and {k} share body {body} and color {}", c.color);
            }
        }
    }
    used.len()
}

#[test]
fn gpu_colors_a_graph_beyond_the_per_thread_loop_budget() {
    // 140 x 140 = 19,600 disks of radius 0.5 in contact on a hexagonal lattice: 58,381
    // contacts (below): the smallest size at which the single-workgroup kernel failed on
    // lavapipe (docs/gpu.md, "Coloring"). CDLAB_COLORING_SIDE overrides it.
    let side: usize = std::env::var("CDLAB_COLORING_SIDE")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(140);
    let s = hex(side, side);
    let mut p = gpu_params(Method::ColoredGs);
    // The solver is not under test: one iteration keeps the step cheap on lavapipe.
    p.solver.max_iter = 1;
    let Some(mut g) = gpu_or_skip("coloring beyond the loop budget", &s, p) else {
        return;
    };
    let red = g.run(1, &Loading::default()).unwrap();
    let contacts = g.raw_contacts().unwrap();
    // Expected count: a hexagonal lattice of side s has s - 1 right-hand pairs per row and
    // 2 s - 1 pairs between consecutive rows, (s - 1)(3 s - 1) in all, plus one floor
    // contact per disk of the first row.
    let want = (side - 1) * (3 * side - 1) + side;
    assert_eq!(contacts.len(), want, "contacts found");
    let colors = red.colors_mean.round() as u32;
    let used = check_coloring(&contacts, colors);
    // Every color in 0..colors is used (JPL picks the smallest free color, so no gap can
    // open), and a graph of maximum degree 10 (a contact meets 5 others at each of its two
    // disks) needs at most 11 colors.
    assert_eq!(used as u32, colors, "colors used against colors reported");
    assert!((2..=11).contains(&colors), "{colors} colors");
    eprintln!(
        "{side} x {side} disks: {} contacts, {colors} colors",
        contacts.len()
    );
}

#[test]
fn gpu_coloring_is_seeded_with_the_last_steps_colors() {
    // A settled packing (hexagonal, equal disks in contact, no gravity, nothing moving):
    // every contact persists from step to step.
    let s = hex(20, 20);
    let mut p = gpu_params(Method::ColoredGs);
    p.solver.max_iter = 8;
    let Some(mut g) = gpu_or_skip("seeded coloring", &s, p) else {
        return;
    };
    g.run(1, &Loading::default()).unwrap();
    let first = g.raw_contacts().unwrap();
    let rounds_first = g.counters().color_rounds;
    // Expected: the first step colors from scratch, so at least 2 rounds (a graph with
    // edges cannot be colored in one: the winners of round 1 leave their neighbours).
    assert!(rounds_first >= 2, "first step: {rounds_first} rounds");
    g.run(3, &Loading::default()).unwrap();
    let later = g.raw_contacts().unwrap();
    // Expected: 0 more rounds (every contact persists and keeps its color, no seed
    // conflicts since the last coloring was valid) and the same colors.
    assert_eq!(
        g.counters().color_rounds,
        rounds_first,
        "rounds after the first step"
    );
    let colors = |v: &[GpuContact]| v.iter().map(|c| (c.i, c.j, c.color)).collect::<Vec<_>>();
    assert_eq!(colors(&later), colors(&first));
}

#[test]
fn gpu_seeded_coloring_stays_valid_while_contacts_change() {
    // A jittered lattice with random velocities in a box: contacts open and close, so
    // seeds meet new contacts and each other every step.
    let s = lattice(16, 3);
    let mut p = gpu_params(Method::ColoredGs);
    p.solver.max_iter = 50;
    let Some(mut g) = gpu_or_skip("seeded coloring, changing contacts", &s, p) else {
        return;
    };
    let mut keys = Vec::new();
    for step in 0..10 {
        let red = g.run(1, &Loading::default()).unwrap();
        let contacts = g.raw_contacts().unwrap();
        check_coloring(&contacts, contacts.iter().map(|c| c.color + 1).max().unwrap_or(0));
        // Expected: no more non-empty colors than a greedy coloring may use, the maximum
        // degree plus one (degree: the other contacts at the two disks).
        let mut per_body = std::collections::HashMap::new();
        for c in &contacts {
            let (mi, mj) = moves(c);
            for (b, m) in [(c.i, mi), (c.j, mj)] {
                if m {
                    *per_body.entry(b).or_insert(0u32) += 1;
                }
            }
        }
        let degree = contacts
            .iter()
            .map(|c| per_body.get(&c.i).unwrap_or(&1) + per_body.get(&c.j).unwrap_or(&1) - 2)
            .max()
            .unwrap_or(0);
        assert!(
            red.colors_mean <= (degree + 1) as f64,
            "step {step}: {} colors for degree {degree}",
            red.colors_mean
        );
        keys.push(contacts.iter().map(|c| (c.i, c.j)).collect::<Vec<_>>());
    }
    // The contacts did change (else this test would only repeat the settled one).
    assert_ne!(keys.first(), keys.last(), "the contact set never changed");
}

#[test]
fn gpu_solver_iteration_costs_one_dispatch_per_color() {
    // The same first step run to 10 and to 20 iterations (a tolerance no f32 run reaches,
    // so both stop at their cap), convergence checked every iteration.
    let s = lattice(12, 11);
    let mut per_run = Vec::new();
    for cap in [10u32, 20] {
        let mut p = gpu_params(Method::ColoredGs);
        p.solver.tol = 1e-30;
        p.solver.max_iter = cap;
        let Some(mut g) = gpu_or_skip("dispatches per iteration", &s, p) else {
            return;
        };
        g.conv_every = 1;
        let red = g.run(1, &Loading::default()).unwrap();
        assert_eq!(red.iterations_sum, cap as u64, "the run stops at its cap");
        let k = g.counters();
        per_run.push((k.dispatches, k.sweep_dispatches, red.colors_mean));
    }
    let ((d10, s10, colors), (d20, s20, colors20)) = (per_run[0], per_run[1]);
    assert_eq!(colors, colors20, "same state, same coloring");
    // Expected: the 10 extra iterations cost the same sweep dispatches each, one per color
    // of more than 64 contacts and one for the smaller ones together (so at least one and
    // at most one per color), plus one convergence test each (conv_every = 1), and nothing
    // else.
    let per_iteration = (s20 - s10) / 10;
    assert_eq!(s20 - s10, 10 * per_iteration, "sweeps {s10} and {s20}");
    assert!(
        (1..=colors as u64).contains(&per_iteration),
        "{per_iteration} sweep dispatches per iteration over {colors} colors"
    );
    assert_eq!(d20 - d10, 10 * (per_iteration + 1), "{colors} colors");
}

#[test]
fn gpu_force_driven_wall_with_hundreds_of_contacts() {
    // 400 disks side by side (not touching each other) resting on a force-driven floor:
    // the floor's incidence list holds 400 contacts, past the 362 at which sorting it
    // in one thread (m^2 / 2 steps) could exceed llvmpipe's per-invocation loop budget.
    let m = 400;
    let mut s = common::scene(0.3);
    for k in 0..m {
        s.disks
            .push(glam::DVec2::new(1.02 * k as f64, 0.5), 0.5, common::RHO)
            .unwrap();
    }
    let mut floor = floor_at(0.0);
    floor.drive = cdlab::model::WallDrive::Force {
        mass: 1000.0,
        force: 0.0,
    };
    s.walls.push(floor);
    s.gravity = glam::DVec2::new(0.0, -G);
    let mut p = gpu_params(Method::ColoredGs);
    p.solver.max_iter = 2;
    let Some(mut g) = gpu_or_skip("force-driven wall", &s, p) else {
        return;
    };
    let red = g.run(1, &Loading::default()).unwrap();
    let contacts = g.raw_contacts().unwrap();
    // Expected: one contact per disk, all on the floor, so pairwise in conflict: 400
    // colors, each used once.
    assert_eq!(contacts.len(), m);
    assert_eq!(check_coloring(&contacts, m as u32), m);
    assert_eq!(red.colors_mean, m as f64);
    // Expected: the floor's velocity is what the impulses of its 400 contacts give it, so
    // its incidence list (which the warm-start gather and the sweeps go through) held all of
    // them: no applied force and no gravity on a wall, its normal +y, so the disks push
    // it down by sum R_n over its mass.
    let sum: f64 = contacts.iter().map(|c| c.rn as f64).sum();
    assert!(sum > 0.0, "the disks press on the floor");
    let out = g.scene().unwrap();
    let want = -sum / 1000.0;
    let got = out.walls[0].vel.y;
    assert!(
        (got - want).abs() <= 1e-4 * want.abs(),
        "floor velocity {got} m/s, from the contact impulses {want} m/s"
    );
}
