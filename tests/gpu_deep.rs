//! The GPU's local updates of deep contacts (`solver.deep_overlap`, docs/method.md, "Deep
//! contacts"): their cost in dispatches, their result against the color-ordered sequential
//! sweep they stand for, and the law they leave the deep contacts in, on both backends.
//! Skips visibly without an adapter (see `gpu_support::gpu_or_skip`).

mod common;
#[path = "gpu_support/mod.rs"]
mod gpu_support;

use cdlab::backend::{Backend, Loading, Reductions};
use cdlab::engine::{CpuEngine, StepParams};
use cdlab::gpu::GpuBackend;
use cdlab::gpu::buffers::GpuContact;
use cdlab::model::{Scene, Wall};
use cdlab::solver::Method;
use common::*;
use glam::DVec2;
use gpu_support::*;

/// Overlap (m) beyond which a loaded contact is deep in these tests: between the 2 mm of a
/// large disk on a small one and the 4 mm of two large ones (see [`bimodal_hex`]), far from
/// both in f32 (positions of a few metres: an ulp is below 1e-6 m).
const DEEP_GAP: f64 = 0.003;

/// A hexagonal packing of `rows` x `cols` disks at a spacing of 1 m on a floor, between two
/// side walls, under gravity, friction 0.5. About half of the disks (seeded) have radius
/// 0.502 m, the others 0.5 m: two large neighbours overlap by 4 mm, a large and a small one
/// by 2 mm, two small ones touch (the floor and walls: 2 mm or 0). So the deep contacts
/// (over [`DEEP_GAP`] and loaded) are those between two large disks, which form chains
/// sharing disks, with the non-deep contacts around them.
fn bimodal_hex(rows: usize, cols: usize, seed: u64) -> Scene {
    let mut rng = Rng(seed);
    let mut s = scene(0.5);
    s.gravity = DVec2::new(0.0, -G);
    for row in 0..rows {
        for col in 0..cols {
            let x = col as f64 + 0.5 * (row % 2) as f64;
            let y = row as f64 * 0.5 * 3f64.sqrt();
            let r = if rng.uniform() < 0.5 { 0.502 } else { 0.5 };
            s.disks.push(DVec2::new(x, y), r, RHO).unwrap();
        }
    }
    s.walls.push(floor_at(-0.5));
    s.walls.push(Wall::fixed(DVec2::new(-0.5, 0.0), DVec2::X));
    s.walls.push(Wall::fixed(DVec2::new(cols as f64, 0.0), -DVec2::X));
    s
}

/// Colored Gauss-Seidel with few iterations (so that the stopping test leaves the deep
/// contacts closing and the local updates have work to do) and `sweeps` local updates.
fn params(deep_gap: f64, sweeps: u32) -> StepParams {
    let mut p = gpu_params(Method::ColoredGs);
    p.solver.max_iter = 16;
    p.solver.deep_gap = deep_gap;
    p.solver.deep_sweeps = sweeps;
    p
}

/// The generalized velocities (vx, vy, spin) of every body: disks, then walls.
fn velocities(s: &Scene) -> Vec<[f64; 3]> {
    let d = &s.disks;
    (0..d.len())
        .map(|k| [d.vel[k].x, d.vel[k].y, d.spin[k]])
        .chain(s.walls.iter().map(|w| [w.vel.x, w.vel.y, 0.0]))
        .collect()
}

/// One GPU step of `scene`: the backend, its contacts and its scene after the step, and the
/// step's reductions.
fn gpu_step(
    test: &str,
    scene: &Scene,
    p: StepParams,
) -> Option<(GpuBackend, Vec<GpuContact>, Scene, Reductions)> {
    let mut g = gpu_or_skip(test, scene, p)?;
    let red = g.run(1, &Loading::default()).unwrap();
    let contacts = g.raw_contacts().unwrap();
    let out = g.scene().unwrap();
    Some((g, contacts, out, red))
}

/// The normal law's residual of a contact (m/s) for the relative normal velocity `un` after
/// the step: a loaded contact must neither close nor open (`U_n + bias_n = 0`), an unloaded
/// one must not close.
fn normal_residual(un: f64, bias_n: f64, rn: f64) -> f64 {
    let u = un + bias_n;
    if rn > 0.0 { u.abs() } else { (-u).max(0.0) }
}

/// Relative velocity (U_n, U_t) of a GPU contact for generalized velocities `v` (f64).
fn relative_velocity(c: &GpuContact, v: &[[f64; 3]]) -> (f64, f64) {
    let (vi, vj) = (v[c.i as usize], v[c.j as usize]);
    let (nx, ny) = (c.nx as f64, c.ny as f64);
    let (dx, dy) = (vi[0] - vj[0], vi[1] - vj[1]);
    (
        dx * nx + dy * ny,
        dx * ny - dy * nx + vi[2] * c.ri as f64 + vj[2] * c.rj as f64,
    )
}

/// Disks that two or more of the `deep` contacts share.
fn shared_disks(deep: &[(u32, u32)], n_disks: u32) -> usize {
    let mut count = vec![0u32; n_disks as usize];
    for &(i, j) in deep {
        for b in [i, j] {
            if b < n_disks {
                count[b as usize] += 1;
            }
        }
    }
    count.iter().filter(|&&c| c >= 2).count()
}

/// The deep phase costs the same dispatches per step whatever `deep_sweeps` and whatever the
/// number of colors: its dispatches are those of a step with local updates less those of
/// the same step without (one step from the same scene: the same iterations and coloring,
/// which the local updates, coming after, do not change), for 1 and 50 sweeps on two
/// packings of different colors. One dispatch per color and sweep would make them
/// 2 + 50 x colors.
#[test]
fn gpu_deep_phase_dispatches_depend_on_neither_sweeps_nor_colors() {
    let mut seen = Vec::new();
    for (rows, cols, seed) in [(12, 12, 1u64), (6, 24, 2)] {
        let s = bimodal_hex(rows, cols, seed);
        let run = |deep_gap: f64, sweeps: u32| {
            let (g, _, _, red) = gpu_step("deep dispatches", &s, params(deep_gap, sweeps))?;
            let k = g.counters();
            // A window run again (a first step that needed more coloring rounds than
            // recorded) records the deep phase again: dispatches per attempt.
            Some((
                k.dispatches / (k.redone + 1),
                k.iterations,
                red.deep_sum,
                red.colors_mean,
                k.redone,
            ))
        };
        let Some((off, it_off, none, colors, redone)) = run(0.0, 1) else {
            return;
        };
        assert_eq!(none, 0);
        for sweeps in [1, 50] {
            let (on, it_on, deep, _, redone_on) = run(DEEP_GAP, sweeps).unwrap();
            assert_eq!(
                redone_on, redone,
                "{rows}x{cols}: the same attempts with and without"
            );
            assert!(deep > 4, "{rows}x{cols}: {deep} deep contacts, expected several");
            assert_eq!(
                it_on, it_off,
                "{rows}x{cols}: the iterations come before the local updates"
            );
            seen.push((rows, cols, sweeps, on - off));
        }
        assert!(colors >= 3.0, "{rows}x{cols}: {colors} colors");
        seen.push((rows, cols, colors as u32, 0));
    }
    eprintln!("deep-phase dispatches per step (rows, cols, sweeps, dispatches; colors with 0): {seen:?}");
    let deep: Vec<u64> = seen.iter().filter(|s| s.3 > 0).map(|s| s.3).collect();
    assert!(
        deep.iter().all(|&d| d == deep[0]),
        "deep-phase dispatches per step vary with sweeps or colors: {seen:?}"
    );
    let colors: Vec<u32> = seen.iter().filter(|s| s.3 == 0).map(|s| s.2).collect();
    assert_ne!(
        colors[0], colors[1],
        "the two packings should differ in colors: {seen:?}"
    );
    // Fewer than one per color of a single sweep: nothing is recorded per color.
    assert!(deep[0] < *colors.iter().min().unwrap() as u64, "{seen:?}");
}

/// The local updates of one GPU step are the color-ordered sequential sweep of the deep
/// contacts: starting from the impulses and velocities the iterations reached (a step
/// without local updates from the same scene: the iterations are the same and come first),
/// `deep_sweeps` sweeps over the colors in increasing order, each deep contact of a color
/// given the exact local update of common.wgsl (`gs_update`, unrelaxed), replayed here in
/// f32 with the GPU's own colors and deep marks, give the GPU's impulses and velocities.
/// Within a color the order does not matter (the contacts share no movable body), across
/// colors it does: a kernel that let colors overlap, or missed a contact, would differ.
#[test]
fn gpu_deep_updates_are_the_color_ordered_sweep_of_the_deep_contacts() {
    let s = bimodal_hex(12, 12, 3);
    let sweeps = 20;
    let Some((_, before, mid, red)) = gpu_step("deep sweep replay", &s, params(0.0, 1)) else {
        return;
    };
    assert_eq!(red.deep_sum, 0);
    let (_, after, out, red) = gpu_step("deep sweep replay", &s, params(DEEP_GAP, sweeps)).unwrap();
    let deep_sum = red.deep_sum;
    assert_eq!(before.len(), after.len());
    let deep: Vec<usize> = (0..after.len()).filter(|&k| after[k].deep == 1).collect();
    assert_eq!(deep.len() as u64, deep_sum);
    let pairs: Vec<(u32, u32)> = deep.iter().map(|&k| (after[k].i, after[k].j)).collect();
    let nd = s.disks.len() as u32;
    assert!(
        deep.len() >= 10 && shared_disks(&pairs, nd) >= 5,
        "{} deep contacts, {} disks shared by two or more: expected chains",
        deep.len(),
        shared_disks(&pairs, nd)
    );
    // The replay, in f32 as the kernel computes.
    let mut v: Vec<[f32; 3]> = velocities(&mid).iter().map(|w| w.map(|x| x as f32)).collect();
    let mut c: Vec<GpuContact> = before.clone();
    for (k, a) in after.iter().enumerate() {
        assert_eq!((c[k].i, c[k].j, c[k].color), (a.i, a.j, a.color), "contact {k}");
    }
    let n_colors = c.iter().map(|c| c.color).max().unwrap() + 1;
    for _ in 0..sweeps {
        for color in 0..n_colors {
            for &k in &deep {
                if c[k].color == color {
                    replay_update(&mut c[k], &mut v);
                }
            }
        }
    }
    // The sweeps change the impulses by far more than the tolerance below.
    let scale = deep.iter().map(|&k| after[k].rn.abs()).fold(0.0f32, f32::max);
    let moved = deep
        .iter()
        .map(|&k| (after[k].rn - before[k].rn).abs())
        .fold(0.0f32, f32::max);
    // A sweep is a few multiply-adds per update, 20 sweeps of a contraction: the driver may
    // fuse them (FMA) where the replay rounds twice, a few ulp (6e-8 relative) per update
    // that the sweeps carry but do not amplify; 1e-5 of the largest impulse bounds that and
    // is far below the change the sweeps make.
    let tol = 1e-5 * scale;
    assert!(
        moved > 100.0 * tol,
        "the local updates moved the impulses by only {moved} N s/m"
    );
    let mut worst = 0.0f32;
    for k in 0..c.len() {
        let d = (c[k].rn - after[k].rn).abs().max((c[k].rt - after[k].rt).abs());
        worst = worst.max(d);
        assert!(
            d <= tol,
            "contact {k} ({}-{}, color {}, deep {}): replay ({}, {}), GPU ({}, {}) N s/m",
            c[k].i,
            c[k].j,
            c[k].color,
            after[k].deep,
            c[k].rn,
            c[k].rt,
            after[k].rn,
            after[k].rt
        );
    }
    let g = velocities(&out);
    let vscale = (G * params(0.0, 1).dt) as f32;
    let mut worst_v = 0.0f32;
    for b in 0..s.disks.len() {
        for a in 0..3 {
            let d = (v[b][a] - g[b][a] as f32).abs();
            worst_v = worst_v.max(d);
            assert!(
                d <= 1e-5 * vscale,
                "disk {b} axis {a}: replay {}, GPU {}",
                v[b][a],
                g[b][a]
            );
        }
    }
    eprintln!(
        "{} deep contacts, {sweeps} sweeps: impulses moved by up to {moved:.3e}, replay off by {worst:.3e} \
         N s/m (largest {scale:.3e}); velocities off by {worst_v:.3e} m/s",
        deep.len()
    );
}

/// common.wgsl's `gs_update(k, 1.0)` of a contact with a diagonal block (the deep ones), in
/// f32 and in the kernel's order of operations.
fn replay_update(c: &mut GpuContact, v: &mut [[f32; 3]]) {
    let (vi, vj) = (v[c.i as usize], v[c.j as usize]);
    let dx = vi[0] - vj[0];
    let dy = vi[1] - vj[1];
    let un = dx * c.nx + dy * c.ny;
    let ut = dx * c.ny - dy * c.nx + vi[2] * c.ri + vj[2] * c.rj;
    let ufn = un - c.wnn * c.rn - c.wnt * c.rt + c.bias_n;
    let uft = ut - c.wnt * c.rn - c.wtt * c.rt + c.bias_t;
    let rn = if ufn < 0.0 { -ufn / c.wnn } else { 0.0 };
    let lim = c.mu * rn;
    let rt = if c.wtt > 0.0 {
        (-uft / c.wtt).clamp(-lim, lim)
    } else {
        0.0
    };
    let (drn, drt) = (rn - c.rn, rt - c.rt);
    if drn != 0.0 || drt != 0.0 {
        let px = drn * c.nx + drt * c.ny;
        let py = drn * c.ny - drt * c.nx;
        let i = c.i as usize;
        v[i] = [vi[0] + c.mi * px, vi[1] + c.mi * py, vi[2] + c.ki * drt];
        if c.mj != 0.0 || c.ma != 0.0 || c.kj != 0.0 {
            let pa = c.ma * (px * c.ax + py * c.ay);
            let j = c.j as usize;
            v[j] = [
                vj[0] - (c.mj * px + pa * c.ax),
                vj[1] - (c.mj * py + pa * c.ay),
                vj[2] + c.kj * drt,
            ];
        }
    }
    c.rn = rn;
    c.rt = rt;
}

/// Both backends leave every deep contact satisfying its normal law after a step of a small
/// loaded packing whose iterations stop short (16): the CPU sweeps its deep contacts in its
/// greedy coloring's order and the GPU in its Jones-Plassmann-Luby colors' order, so the
/// two orders (and the iterates before them, f64 against f32) differ and their impulses need
/// not agree contact by contact (a hyperstatic packing's impulses are not unique); what
/// both must give is the law's residual, the closing or opening velocity `U_n + bias_n` of
/// a loaded deep contact, near 0. Without local updates the same contacts leave the step
/// closing by much more, which is what makes the check able to fail. The deep contacts here
/// form long chains (half the disks are large), along which Gauss-Seidel converges slowly:
/// they get 300 sweeps, enough for both orders to converge.
#[test]
fn gpu_and_cpu_deep_contacts_leave_the_step_satisfying_their_law() {
    let s = bimodal_hex(12, 12, 4);
    let sweeps = 300;
    let vscale = G * params(0.0, 1).dt;
    // The GPU, without and with local updates.
    let Some((_, off, out_off, _)) = gpu_step("deep law", &s, params(0.0, 1)) else {
        return;
    };
    let (_, on, out_on, red) = gpu_step("deep law", &s, params(DEEP_GAP, sweeps)).unwrap();
    let deep: Vec<usize> = (0..on.len()).filter(|&k| on[k].deep == 1).collect();
    assert_eq!(deep.len() as u64, red.deep_sum);
    let residual = |contacts: &[GpuContact], out: &Scene| {
        let v = velocities(out);
        deep.iter()
            .map(|&k| {
                let c = &contacts[k];
                normal_residual(relative_velocity(c, &v).0, c.bias_n as f64, c.rn as f64)
            })
            .fold(0.0, f64::max)
    };
    let (gpu_off, gpu_on) = (residual(&off, &out_off), residual(&on, &out_on));
    // The CPU, the same way; its deep contacts are those it counts (loaded at the end of the
    // iterations and overlapping by more than deep_gap).
    let cpu = |deep_gap: f64| {
        let mut scene = s.clone();
        let mut e = CpuEngine::new(params(deep_gap, sweeps)).unwrap();
        let stats = e.step(&mut scene).unwrap();
        (e.contacts().to_vec(), velocities(&scene), stats.solve.deep)
    };
    let (cpu_contacts, cpu_v, cpu_deep) = cpu(DEEP_GAP);
    let (cpu_off_contacts, cpu_off_v, _) = cpu(0.0);
    // The CPU's selection, made at the end of the iterations (those of the step without
    // local updates: the same iterations).
    let cpu_marked: Vec<usize> = (0..cpu_off_contacts.len())
        .filter(|&k| {
            let c = &cpu_off_contacts[k];
            c.rn > 0.0 && c.gap < -DEEP_GAP && c.wnt == 0.0
        })
        .collect();
    assert_eq!(cpu_marked.len(), cpu_deep as usize);
    assert!(
        cpu_contacts
            .iter()
            .map(|c| c.key())
            .eq(cpu_off_contacts.iter().map(|c| c.key())),
        "the CPU steps with and without local updates found different contacts"
    );
    let cpu_residual = |contacts: &[cdlab::contact::Contact], v: &[[f64; 3]]| {
        let gv: Vec<glam::DVec3> = v.iter().map(|w| glam::DVec3::from_array(*w)).collect();
        cpu_marked
            .iter()
            .map(|&k| {
                let c = &contacts[k];
                normal_residual(c.relative_velocity(&gv).0, c.bias_n, c.rn)
            })
            .fold(0.0, f64::max)
    };
    let cpu_on = cpu_residual(&cpu_contacts, &cpu_v);
    let cpu_off = cpu_residual(&cpu_off_contacts, &cpu_off_v);
    eprintln!(
        "deep contacts: GPU {}, CPU {cpu_deep} (of {} on the CPU); largest normal residual \
         (m/s): GPU {gpu_off:.3e} without, {gpu_on:.3e} with {sweeps} sweeps; CPU {cpu_off:.3e} \
         without, {cpu_on:.3e} with (g dt = {vscale:.3e} m/s)",
        deep.len(),
        cpu_contacts.len()
    );
    assert!(
        deep.len() >= 10 && cpu_deep >= 10,
        "GPU {}, CPU {cpu_deep}",
        deep.len()
    );
    // The same packing, the same selection rule: the two backends mark about the same
    // contacts (a contact loaded on one and unloaded on the other may differ).
    let diff = (deep.len() as i64 - cpu_deep as i64).unsigned_abs();
    assert!(
        diff * 10 <= deep.len() as u64,
        "GPU {} deep contacts, CPU {cpu_deep}",
        deep.len()
    );
    // Without local updates the deep contacts close by a good fraction of g dt (the
    // iterations stop short); with them, below 1e-4 g dt: near 0 (f32 velocities of order
    // g dt round at 1e-7 of it), the sweeps having converged.
    for (name, without, with) in [("GPU", gpu_off, gpu_on), ("CPU", cpu_off, cpu_on)] {
        assert!(
            without > 1e-2 * vscale,
            "{name}: without local updates {without} m/s"
        );
        assert!(
            with < 1e-4 * vscale,
            "{name}: a deep contact leaves at {with} m/s"
        );
    }
}

/// On a software adapter the deep-contact kernel runs only the sweeps that fit its loop
/// budget (`GpuBackend::deep_budget`: llvmpipe ends an invocation's loops after 65,535
/// iterations and goes on silently). With a budget that fits fewer sweeps than asked, the
/// step is the one asked for that many sweeps, bit for bit, and the counters say how many
/// were left out; with no budget every sweep runs, and the cut changes the result.
#[test]
fn deep_sweeps_beyond_the_loop_budget_are_cut_and_counted() {
    let s = bimodal_hex(12, 12, 3);
    let asked = 20;
    let run = |sweeps: u32, budget: u32| {
        let mut g = gpu_or_skip("deep loop budget", &s, params(DEEP_GAP, sweeps))?;
        g.deep_budget = budget;
        let red = g.run(1, &Loading::default()).unwrap();
        let out = g.scene().unwrap();
        Some((velocities(&out), g.counters().deep_sweeps_cut, red.deep_sum))
    };
    let Some((full, none_cut, deep)) = run(asked, 0) else {
        return;
    };
    assert_eq!(none_cut, 0, "no budget, nothing cut");
    assert!(deep > 10, "{deep} deep contacts: too few to need sweeps");
    // About 10 loop iterations to list the colors and 3 per color holding deep contacts per
    // sweep: 100 fits a few sweeps, not 20.
    let (cut_v, cut, _) = run(asked, 100).unwrap();
    assert!(cut > 0 && cut < u64::from(asked), "{cut} sweeps cut of {asked}");
    let ran = asked - cut as u32;
    let (same, same_cut, _) = run(ran, 0).unwrap();
    assert_eq!(same_cut, 0);
    assert_eq!(cut_v, same, "{ran} sweeps within the budget against {ran} asked");
    assert_ne!(cut_v, full, "the cut sweeps would have changed the velocities");
}
