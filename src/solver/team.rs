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
use super::ctx::Ctx;
use super::lanes::{proper_colors, sweep_color_chunk};
use super::resident::{Resident, wait_until};
use super::rows::Row;
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
    rows: *mut Row,
    partial: *mut (f64, f64),
}
// SAFETY: see the struct's comment; the barrier orders every write before every read.
unsafe impl Send for Shared {}
unsafe impl Sync for Shared {}

/// The chunks of every color: `chunks[k]` is a contact range, and color `c` owns chunks
/// `first[c]..first[c + 1]`.
struct Layout {
    chunks: Vec<(usize, usize)>,
    first: Vec<usize>,
    /// The last color is a serial group (see [`super::color::color`]).
    serial_last: bool,
}

impl Layout {
    fn new(ranges: &[u32], serial_last: bool) -> Self {
        let mut chunks = Vec::new();
        let mut first = vec![0];
        for w in ranges.windows(2) {
            let (a, b) = (w[0] as usize, w[1] as usize);
            let mut s = a;
            while s < b {
                chunks.push((s, (s + CHUNK).min(b)));
                s += CHUNK;
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

/// Sweeps colored Gauss-Seidel iterations on the members of `team` until `done` says stop
/// after an iteration or `params.max_iter` is reached, each iteration with its relaxation
/// ([`SolverParams::relax_at`]). `done` receives the iteration number and the sums
/// (change^2, impulse^2) and is called by the calling thread only.
pub(super) fn sweep_iterations(
    rows: &mut [Row],
    ranges: &[u32],
    serial_last: bool,
    ctx: Ctx,
    team: &Resident,
    params: &SolverParams,
    done: impl FnMut(u32, f64, f64) -> bool,
) {
    let threads = team.size();
    let max_iter = params.max_iter;
    let layout = Layout::new(ranges, serial_last);
    let n_colors = ranges.len().saturating_sub(1);
    let proper_colors = proper_colors(ranges, serial_last);
    // One slot per chunk: the barrier after the caller has summed an iteration keeps every
    // member from writing the next one's partials before then.
    let mut partial = vec![(0.0, 0.0); layout.chunks.len()];
    let shared = Shared {
        rows: rows.as_mut_ptr(),
        partial: partial.as_mut_ptr(),
    };
    let barrier = SpinBarrier::new(
        std::iter::once(std::thread::current())
            .chain(team.threads().cloned())
            .collect(),
    );
    let done = CallerOnly(std::cell::RefCell::new(done));
    let stop = AtomicBool::new(false);
    let n_chunks = layout.chunks.len();

    let member = |t: usize, on_iteration: &mut dyn FnMut(u32, f64, f64) -> bool| {
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
                        let chunk = std::slice::from_raw_parts_mut(shared.rows.add(a), b - a);
                        if c < proper_colors {
                            sweep_color_chunk(chunk, ctx)
                        } else {
                            sweep_chunk(chunk, ctx)
                        }
                    };
                    unsafe { shared.partial.add(k).write(sums) };
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
                let finished = on_iteration(it, d2, r2) || it == max_iter;
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
            member(t, &mut |_, _, _| false);
        }
    });
}
