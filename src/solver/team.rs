//! Colored Gauss-Seidel on a team of threads that meet at a barrier after each color.
//!
//! Forking and joining a thread pool once per color costs more than the color's work on
//! samples of a few thousand disks (docs/benchmarks.md, "Thread team"). Here the threads
//! are those of a team kept from step to step ([`super::resident`]); each sweeps a fixed
//! contiguous share of every color and waits for the others at a barrier between colors.
//!
//! The result is bit-identical to the sequential sweep: contacts of one color share no
//! movable body, so their updates commute, and the convergence sums are the per-chunk
//! partial sums added in chunk order, exactly as the sweep on one thread
//! ([`super::gauss_seidel`]) adds them. Why the members may write the velocities at the
//! same time: [`super::ctx`].

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

use super::SolverParams;
use super::convergence::VelocityShare;
use super::ctx::Ctx;
use super::lanes::{proper_colors, sweep_color_chunk};
use super::resident::{Resident, wait_until};
use super::rows::Row;
use super::single::{self, GROUP_CHUNK, Group, Line32};
use super::update::{CHUNK, sweep_chunk};

/// A reusable barrier that spins briefly, then sleeps: the waits between colors are
/// short (a few microseconds of work per color and thread on a 5000-disk sample), but on
/// a loaded machine a descheduled team member must not be waited for by spinning or
/// yielding through whole time slices. The last thread to arrive wakes the sleepers.
struct SpinBarrier {
    n: usize,
    count: AtomicUsize,
    generation: AtomicUsize,
    /// Every member's thread, woken by the last to arrive.
    members: Vec<std::thread::Thread>,
}

impl SpinBarrier {
    fn new(members: Vec<std::thread::Thread>) -> Self {
        SpinBarrier {
            n: members.len(),
            count: AtomicUsize::new(0),
            generation: AtomicUsize::new(0),
            members,
        }
    }

    fn wait(&self) {
        let generation = self.generation.load(Ordering::Acquire);
        if self.count.fetch_add(1, Ordering::AcqRel) + 1 == self.n {
            self.count.store(0, Ordering::Relaxed);
            self.generation.fetch_add(1, Ordering::Release);
            // Waking itself only leaves this thread a token for its next wait.
            for t in &self.members {
                t.unpark();
            }
            return;
        }
        // Spin for up to SPIN before sleeping: a color's work per thread is a few
        // microseconds on a 5000-disk sample, and a sleep/wake pair through the kernel costs
        // more than that; the spin is bounded in time, not in pauses, whose length varies by
        // processor (docs/benchmarks.md, "Thread team").
        const SPIN: std::time::Duration = std::time::Duration::from_micros(100);
        wait_until(SPIN, SPIN, || {
            self.generation.load(Ordering::Acquire) != generation
        });
    }
}

/// What only member 0 touches: it runs on the calling thread ([`Resident::run`]), so the
/// caller's convergence test need not be sendable.
struct CallerOnly<T>(std::cell::RefCell<T>);
// SAFETY: only member 0 reaches the cell, and member 0 is the calling thread.
unsafe impl<T> Sync for CallerOnly<T> {}

impl<T> CallerOnly<T> {
    fn with<R>(&self, f: impl FnOnce(&mut T) -> R) -> R {
        f(&mut self.0.borrow_mut())
    }
}

/// Raw pointers shared by the team; each member writes only its own chunks (disjoint
/// rows, disjoint partial-sum slots) between two barriers.
#[derive(Clone, Copy)]
struct Shared {
    swept: SweptAt,
    partial: *mut (f64, f64),
    /// Each member's answer to the velocity test on its bodies.
    settled: *mut bool,
}
// SAFETY: see the struct's comment; the barrier orders every write before every read.
unsafe impl Send for Shared {}
unsafe impl Sync for Shared {}

/// The chunks of every color: `chunks[k]` is a range of rows (or of groups of rows), and
/// color `c` owns chunks `first[c]..first[c + 1]`.
struct Layout {
    chunks: Vec<(usize, usize)>,
    first: Vec<usize>,
    /// The last color is a serial group (see [`super::color::color`]).
    serial_last: bool,
}

impl Layout {
    fn new(ranges: &[u32], serial_last: bool, chunk: usize) -> Self {
        let mut chunks = Vec::new();
        let mut first = vec![0];
        for w in ranges.windows(2) {
            let (a, b) = (w[0] as usize, w[1] as usize);
            let mut s = a;
            while s < b {
                chunks.push((s, (s + chunk).min(b)));
                s += chunk;
            }
            first.push(chunks.len());
        }
        Layout {
            chunks,
            first,
            serial_last,
        }
    }

    /// Member `t` of `n`'s share of color `c`: a contiguous run of its chunks (all of them
    /// for member 0 in a serial group, whose contacts share a body).
    fn share(&self, c: usize, t: usize, n: usize) -> std::ops::Range<usize> {
        let (a, b) = (self.first[c], self.first[c + 1]);
        if self.serial_last && c + 2 == self.first.len() {
            return if t == 0 { a..b } else { b..b };
        }
        let len = b - a;
        a + len * t / n..a + len * (t + 1) / n
    }
}

/// What a team sweeps: rows of the `f64` sweeps, with the color ranges in rows, or the
/// groups of the `f32` sweeps ([`super::single`]) and their velocities, with the ranges in
/// groups.
pub(super) enum Swept<'a> {
    Rows(&'a mut [Row]),
    Groups(&'a mut [Group], *mut Line32),
}

/// [`Swept`] as the members share it: where its rows, or groups and velocities, start.
#[derive(Clone, Copy)]
enum SweptAt {
    Rows(*mut Row),
    Groups(*mut Group, *mut Line32),
}

/// Sweeps colored Gauss-Seidel iterations on the members of `team` until `done` says stop
/// after an iteration or `params.max_iter` is reached, each iteration with its relaxation
/// ([`SolverParams::relax_at`]). `done` receives the iteration number, the sums
/// (change^2, impulse^2) and the answer of the `velocity` test, which the members run each
/// on a share of the bodies after the iterations it applies to; it is called by the
/// calling thread only.
#[allow(clippy::too_many_arguments)]
pub(super) fn sweep_iterations(
    swept: Swept,
    ranges: &[u32],
    serial_last: bool,
    ctx: Ctx,
    team: &Resident,
    params: &SolverParams,
    velocity: VelocityShare,
    done: impl FnMut(u32, f64, f64, bool) -> bool,
) {
    let threads = team.size();
    let max_iter = params.max_iter;
    let (swept, chunk) = match swept {
        Swept::Rows(r) => (SweptAt::Rows(r.as_mut_ptr()), CHUNK),
        Swept::Groups(g, l) => (SweptAt::Groups(g.as_mut_ptr(), l), GROUP_CHUNK),
    };
    let layout = Layout::new(ranges, serial_last, chunk);
    let n_colors = ranges.len().saturating_sub(1);
    let proper_colors = proper_colors(ranges, serial_last);
    // One slot per chunk: the barrier after the caller has summed an iteration keeps every
    // member from writing the next one's partials before then.
    let mut partial = vec![(0.0, 0.0); layout.chunks.len()];
    let mut settled = vec![false; threads];
    let shared = Shared {
        swept,
        partial: partial.as_mut_ptr(),
        settled: settled.as_mut_ptr(),
    };
    let barrier = SpinBarrier::new(
        std::iter::once(std::thread::current())
            .chain(team.threads().cloned())
            .collect(),
    );
    let done = CallerOnly(std::cell::RefCell::new(done));
    let stop = AtomicBool::new(false);
    let n_chunks = layout.chunks.len();

    let member = |t: usize, on_iteration: &mut dyn FnMut(u32, f64, f64, bool) -> bool| {
        let (shared, ctx) = (shared, ctx);
        for it in 1..=max_iter {
            let ctx = Ctx {
                relax: params.relax_at(it),
                ..ctx
            };
            for c in 0..n_colors {
                for k in layout.share(c, t, threads) {
                    let (a, b) = layout.chunks[k];
                    // SAFETY: chunk k belongs to this member alone in this color; the
                    // contacts of a color share no movable body (coloring), so the
                    // velocity writes of different members never alias.
                    let sums = unsafe {
                        match shared.swept {
                            SweptAt::Groups(groups, lines) => {
                                let chunk = std::slice::from_raw_parts_mut(groups.add(a), b - a);
                                single::sweep_chunk(chunk, lines, ctx.relax)
                            }
                            SweptAt::Rows(rows) => {
                                let chunk = std::slice::from_raw_parts_mut(rows.add(a), b - a);
                                if c < proper_colors {
                                    sweep_color_chunk(chunk, ctx)
                                } else {
                                    sweep_chunk(chunk, ctx)
                                }
                            }
                        }
                    };
                    unsafe { shared.partial.add(k).write(sums) };
                }
                barrier.wait();
            }
            let tested = velocity.runs_at(it);
            if tested {
                let n = velocity.len();
                // SAFETY: the test holds one line per body of `ctx` (the caller made it from
                // the same velocities); every member passed the last color's barrier, and
                // none writes a velocity before the barrier after the decision; each member
                // keeps its own range of bodies, and writes its own answer's slot.
                unsafe {
                    let range = n * t / threads..n * (t + 1) / threads;
                    let s = match shared.swept {
                        SweptAt::Rows(_) => velocity.bodies(it, ctx.gv, ctx.props, range),
                        SweptAt::Groups(_, lines) => velocity.bodies_f32(it, lines, ctx.props, range),
                    };
                    shared.settled.add(t).write(s);
                }
                barrier.wait();
            }
            if t == 0 {
                let (mut d2, mut r2) = (0.0, 0.0);
                for k in 0..n_chunks {
                    // SAFETY: every member passed the last color's barrier after writing.
                    let (d, r) = unsafe { shared.partial.add(k).read() };
                    d2 += d;
                    r2 += r;
                }
                // SAFETY: every member wrote its answer before the barrier just passed.
                let settled = tested && (0..threads).all(|m| unsafe { shared.settled.add(m).read() });
                let finished = on_iteration(it, d2, r2, settled) || it == max_iter;
                stop.store(finished, Ordering::Release);
            }
            barrier.wait();
            if stop.load(Ordering::Acquire) {
                return;
            }
        }
    };

    team.run(&|t| {
        if t == 0 {
            // Only the caller's share reports: `done` is the caller's.
            done.with(|done| member(0, done));
        } else {
            member(t, &mut |_, _, _, _| false);
        }
    });
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;
    use crate::solver::convergence::VelocityTest;
    use crate::solver::ctx::Line;
    use crate::solver::rows::BodyProps;

    /// A chain of 40 disks pressed together, the last bodies of 80: the first 40 have no
    /// contact and never move. Its contacts alternate between two colors.
    fn chain() -> (Vec<Row>, Vec<u32>, Vec<Line>, Vec<BodyProps>) {
        let (n, first) = (80, 40);
        let gv = (0..n)
            .map(|k| Line::of(DVec3::new((k as f64 * 0.7).sin(), 0.1, 0.0)))
            .collect();
        let props = (0..n).map(|_| BodyProps::of(1.0, 0.5, 0.5)).collect();
        let row = |k: usize| Row {
            i: (k + 1) as u32,
            j: k as u32,
            nx: 1.0,
            inv_wnn: 0.5,
            inv_wtt: 0.25,
            mu: 0.3,
            ..Default::default()
        };
        let even = (first..n - 1).step_by(2).map(row);
        let odd = (first + 1..n - 1).step_by(2).map(row);
        let rows: Vec<Row> = even.chain(odd).collect();
        let ranges = vec![0, 20, rows.len() as u32];
        (rows, ranges, gv, props)
    }

    /// The velocity test on a team answers after each iteration as on one thread, though
    /// only the last member's bodies move (a member that answered for all would stop the
    /// team at the first test).
    #[test]
    fn the_team_s_velocity_test_answers_as_one_thread_s() {
        let params = SolverParams {
            velocity_tol: 1e-6,
            max_iter: 300,
            ..SolverParams::default()
        };
        let params = SolverParams {
            gauss_seidel: crate::solver::GaussSeidelSettings {
                relax_after: 2,
                ..params.gauss_seidel
            },
            ..params
        };
        let run = |team: Option<&Resident>| {
            let (mut rows, ranges, mut gv, props) = chain();
            let ctx = Ctx {
                gv: gv.as_mut_ptr(),
                props: props.as_ptr(),
                contacts: std::ptr::null_mut(),
                relax: 1.0,
                quads: false,
                frictionless: false,
            };
            let mut prev = Vec::new();
            let mut velocity = VelocityTest::new(&params, &gv, &mut prev);
            let mut answers = Vec::new();
            match team {
                Some(team) => {
                    let share = velocity.share();
                    sweep_iterations(
                        Swept::Rows(&mut rows),
                        &ranges,
                        false,
                        ctx,
                        team,
                        &params,
                        share,
                        |it, _, _, s| {
                            answers.push((it, s));
                            s
                        },
                    );
                }
                None => {
                    for it in 1..=params.max_iter {
                        let ctx = Ctx {
                            relax: params.relax_at(it),
                            ..ctx
                        };
                        for w in ranges.windows(2) {
                            // SAFETY: one thread; the chain's bodies are within `gv`.
                            unsafe { sweep_chunk(&mut rows[w[0] as usize..w[1] as usize], ctx) };
                        }
                        // SAFETY: no sweep runs.
                        let lines = unsafe { std::slice::from_raw_parts(ctx.gv, gv.len()) };
                        let s = velocity.settled(it, lines, &props);
                        answers.push((it, s));
                        if s {
                            break;
                        }
                    }
                }
            }
            let bits: Vec<u64> = gv.iter().flat_map(|l| l.v.to_array()).map(f64::to_bits).collect();
            (answers, bits)
        };
        let (one, one_bits) = run(None);
        let stop = one.last().unwrap().0;
        assert!(
            one.last().unwrap().1 && stop > params.gauss_seidel.relax_after + 3,
            "the chain settled at iteration {stop}: the test decided too soon to tell"
        );
        for n in [2, 3] {
            let team = Resident::new(n);
            let (answers, bits) = run(Some(&team));
            assert_eq!(answers, one, "team of {n}: the answers");
            assert!(bits == one_bits, "team of {n}: the velocities");
        }
    }
}
