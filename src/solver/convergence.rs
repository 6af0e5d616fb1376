//! When the iterations of a step stop: the relative change of the impulses
//! (docs/method.md, "Convergence") and the velocity test (docs/method.md, "Relaxation and
//! the velocity test").

use super::ctx::Line;
use super::rows::BodyProps;
use super::single::Line32;
use super::{SolveStats, SolverParams};

impl SolveStats {
    /// Records Gauss-Seidel iteration `it` with its sums (change^2, impulse^2) and tells
    /// whether the relative change, divided by the iteration's relaxation, met `tol`.
    pub(super) fn record(&mut self, it: u32, d2: f64, r2: f64, params: &SolverParams) -> bool {
        let w = params.relax_at(it);
        self.record_change(it, d2 / (w * w), r2, params.tol)
    }

    /// Records iteration `it` with its sums (change^2, impulse^2) and tells whether the
    /// relative change met `tol`.
    pub(super) fn record_change(&mut self, it: u32, d2: f64, r2: f64, tol: f64) -> bool {
        self.iterations = it;
        self.residual = relative_change(d2, r2);
        self.converged = self.residual <= tol;
        self.converged
    }
}

/// The velocity test of [`SolverParams::velocity_tol`]: keeps the iterate of the last
/// iteration and compares the next one with it.
pub(super) struct VelocityTest<'a> {
    tol: f64,
    after: u32,
    prev: &'a mut Vec<Line>,
}

impl<'a> VelocityTest<'a> {
    /// `gv` is the iterate before the first iteration, the reference of the first test
    /// when the test applies from the first iteration; `prev` is the workspace's buffer.
    pub(super) fn new(params: &SolverParams, gv: &[Line], prev: &'a mut Vec<Line>) -> Self {
        let (tol, after) = (params.velocity_tol, params.gauss_seidel.relax_after);
        if tol > 0.0 {
            // Its contents before the first keep are never compared, so a buffer of the
            // right size is only resized, not refilled, each step (at 50,000 disks a fill is
            // 1.6 MB of writes).
            if prev.len() != gv.len() {
                prev.clear();
                prev.resize(gv.len(), Line::default());
            }
            if after == 0 {
                prev.copy_from_slice(gv);
            }
        }
        VelocityTest {
            // The test applies to relaxed iterations only, whose changes are `gs_relax` of
            // the way to the local solutions: like the impulse test, it bounds the change
            // divided by the relaxation, so that `velocity_tol` means the same at any
            // relaxation.
            tol: tol * params.gauss_seidel.relax,
            after,
            prev,
        }
    }

    /// Called after iteration `it` with the iterate `gv`: true when the test applies and no
    /// body's velocity changed by more than `velocity_tol x gs_relax` since the previous
    /// iteration. Bodies no contact can move keep their velocity, so every body may be
    /// compared.
    pub(super) fn settled(&mut self, it: u32, gv: &[Line], props: &[BodyProps]) -> bool {
        let share = self.share();
        if !share.runs_at(it) {
            return false;
        }
        assert!(gv.len() == share.len && props.len() >= gv.len());
        // SAFETY: the kept iterate, `gv` and `props` cover every body (checked), and this
        // thread alone holds the test.
        unsafe { share.bodies(it, gv.as_ptr(), props.as_ptr(), 0..gv.len()) }
    }

    /// The test for the members of a team, each on its own bodies ([`VelocityShare`]);
    /// it points into this test's kept iterate, so serves only while this test is not used.
    pub(super) fn share(&mut self) -> VelocityShare {
        VelocityShare {
            tol: self.tol,
            after: self.after,
            prev: self.prev.as_mut_ptr(),
            len: self.prev.len(),
        }
    }
}

/// [`VelocityTest`] for a thread team: after an iteration's last color, each member
/// compares and keeps its own range of bodies, and the test holds when it holds on every
/// range. The same comparisons as on one thread, so the same answer: the ranges' answers
/// are combined by `and`.
#[derive(Clone, Copy)]
pub(super) struct VelocityShare {
    tol: f64,
    after: u32,
    prev: *mut Line,
    len: usize,
}

// SAFETY: members touch disjoint ranges of the kept iterate ([`VelocityShare::bodies`]).
unsafe impl Send for VelocityShare {}
unsafe impl Sync for VelocityShare {}

impl VelocityShare {
    /// Whether the test runs after iteration `it`: from iteration `after` (which only
    /// keeps the iterate) on, when the test is on.
    pub(super) fn runs_at(&self, it: u32) -> bool {
        self.tol > 0.0 && it >= self.after
    }

    /// How many bodies the kept iterate holds.
    pub(super) fn len(&self) -> usize {
        self.len
    }

    /// Compares bodies `range` of the iterate `gv` with the kept one and keeps them: true
    /// when none changed by more than the tolerance, false after iteration `after`, which
    /// has nothing to compare with.
    ///
    /// # Safety
    /// `gv` and `props` are valid for `range`, within [`Self::len`]; no other thread
    /// touches these bodies' kept iterate, or writes their velocities, meanwhile.
    pub(super) unsafe fn bodies(
        &self,
        it: u32,
        gv: *const Line,
        props: *const BodyProps,
        range: std::ops::Range<usize>,
    ) -> bool {
        // SAFETY: forwarded from the caller.
        unsafe { self.compare(it, props, range, |k| *gv.add(k)) }
    }

    /// [`Self::bodies`] on the `f32` copy of the velocities ([`super::single`]): each
    /// line compared and kept as its exact `f64` value.
    ///
    /// # Safety
    /// As [`Self::bodies`].
    pub(super) unsafe fn bodies_f32(
        &self,
        it: u32,
        gv: *const Line32,
        props: *const BodyProps,
        range: std::ops::Range<usize>,
    ) -> bool {
        // SAFETY: forwarded from the caller.
        unsafe { self.compare(it, props, range, |k| (*gv.add(k)).wide()) }
    }

    /// [`Self::bodies`] with body `k`'s line read by `line(k)`.
    ///
    /// # Safety
    /// As [`Self::bodies`], `line` reading the iterate.
    #[inline(always)]
    unsafe fn compare(
        &self,
        it: u32,
        props: *const BodyProps,
        range: std::ops::Range<usize>,
        line: impl Fn(usize) -> Line,
    ) -> bool {
        debug_assert!(range.end <= self.len);
        let tol2 = self.tol * self.tol;
        // Compared up to the first body that moved, as `Iterator::all` would; kept whole.
        let mut settled = it > self.after;
        for k in range {
            let v = line(k);
            // SAFETY: forwarded from the caller.
            let (kept, b) = unsafe { (&mut *self.prev.add(k), &*props.add(k)) };
            if settled {
                let d = v.v - kept.v;
                settled = d.x * d.x + d.y * d.y + (b.lever * d.z).powi(2) <= tol2;
            }
            *kept = v;
        }
        settled
    }

    /// Keeps the iterate given by `line(k)` for every body, as the reference of the next
    /// test (the `f32` sweeps start from their copy, not from the `f64` velocities).
    ///
    /// # Safety
    /// No other thread touches the kept iterate meanwhile.
    pub(super) unsafe fn keep(&self, line: impl Fn(usize) -> Line) {
        for k in 0..self.len {
            // SAFETY: forwarded from the caller; k is within the kept iterate.
            unsafe { *self.prev.add(k) = line(k) };
        }
    }
}

/// Relative quadratic change of one iteration (or distance, `sqrt(d2 / r2)`); 0 when
/// nothing carries or changes impulse, infinite when only the change is nonzero.
pub(super) fn relative_change(d2: f64, r2: f64) -> f64 {
    if d2 == 0.0 {
        0.0
    } else if r2 == 0.0 {
        f64::INFINITY
    } else {
        (d2 / r2).sqrt()
    }
}

#[cfg(test)]
mod tests {
    use glam::DVec3;

    use super::*;

    /// `n` bodies' lines, each coordinate from a simple sequence scaled by `scale`.
    fn lines(n: usize, scale: f64) -> Vec<Line> {
        (0..n)
            .map(|k| {
                let x = (k as f64 * 0.37).sin();
                Line::of(DVec3::new(x, 0.5 * x, -2.0 * x) * scale)
            })
            .collect()
    }

    /// On the `f32` copy of the velocities the test answers as on the `f64` lines of the
    /// same values, and a reference kept with `keep` serves the first comparison.
    #[test]
    fn the_velocity_test_on_f32_lines_answers_as_on_their_f64_values() {
        let n = 40;
        let props: Vec<BodyProps> = (0..n).map(|_| BodyProps::of(1.0, 2.0, 0.5)).collect();
        let params = SolverParams {
            velocity_tol: 1e-3,
            ..SolverParams::default()
        };
        let after = params.gauss_seidel.relax_after;
        let tol = params.velocity_tol * params.gauss_seidel.relax;
        let wide = |l: &[Line32]| -> Vec<Line> { l.iter().map(Line32::wide).collect() };
        let start: Vec<Line32> = lines(n, 1.0).iter().map(Line32::of).collect();
        for by in [0.5, 2.0] {
            let mut next = start.clone();
            next[7].0[1] += (by * tol) as f32;
            let (mut p64, mut p32) = (Vec::new(), Vec::new());
            let t64 = VelocityTest::new(&params, &wide(&start), &mut p64).share();
            let t32 = VelocityTest::new(&params, &wide(&start), &mut p32).share();
            // SAFETY: one thread; the lines, the table and the kept iterates hold n bodies.
            let (a, b) = unsafe {
                t64.keep(|k| wide(&start)[k]);
                t32.keep(|k| wide(&start)[k]);
                (
                    t64.bodies(after + 1, wide(&next).as_ptr(), props.as_ptr(), 0..n),
                    t32.bodies_f32(after + 1, next.as_ptr(), props.as_ptr(), 0..n),
                )
            };
            assert_eq!(a, b, "moved by {by} x tol");
            assert_eq!(a, by < 1.0, "moved by {by} x tol");
            assert!(p64 == p32, "the kept iterates");
        }
    }

    /// The test split into ranges (a team's members) answers as on one thread, and keeps the
    /// same iterate: a body that moved beyond the tolerance in any range, and only such a
    /// body, makes it fail.
    #[test]
    fn the_velocity_test_split_into_ranges_answers_as_the_whole() {
        let n = 101;
        let props: Vec<BodyProps> = (0..n)
            .map(|k| BodyProps::of(1.0, 2.0, 0.5 + k as f64 * 1e-3))
            .collect();
        let params = SolverParams {
            velocity_tol: 1e-3,
            ..SolverParams::default()
        };
        let after = params.gauss_seidel.relax_after;
        let tol = params.velocity_tol * params.gauss_seidel.relax;
        let start = lines(n, 1.0);
        for (moved, by) in [
            (None, 0.0),
            (Some(0), 2.0),
            (Some(50), 2.0),
            (Some(100), 2.0),
            (Some(100), 0.5),
        ] {
            let mut next = lines(n, 1.0 + 1e-5);
            if let Some(k) = moved {
                next[k].v.x += by * tol;
            }
            let expected = moved.is_none() || by < 1.0;
            for parts in [1, 2, 3, 7] {
                let mut prev = Vec::new();
                let mut test = VelocityTest::new(&params, &start, &mut prev);
                assert!(
                    !test.settled(after, &start, &props),
                    "compared before a first keep"
                );
                let share = test.share();
                // Every range runs, as every member does, whatever the others answer.
                let answer = (0..parts).fold(true, |all, t| {
                    let range = n * t / parts..n * (t + 1) / parts;
                    // SAFETY: one thread; the ranges cover the bodies once.
                    let here = unsafe { share.bodies(after + 1, next.as_ptr(), props.as_ptr(), range) };
                    all & here
                });
                assert_eq!(answer, expected, "moved {moved:?} by {by} x tol, {parts} ranges");
                assert!(prev == next, "the kept iterate, {parts} ranges");
            }
        }
    }
}
