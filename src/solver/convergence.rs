//! When the iterations of a step stop: the relative change of the impulses
//! (docs/method.md, "Convergence") and the velocity test (docs/method.md, "Relaxation and
//! the velocity test").

use super::ctx::Line;
use super::rows::BodyProps;
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
        prev.clear();
        if params.velocity_tol > 0.0 && params.gauss_seidel.relax_after == 0 {
            prev.extend_from_slice(gv);
        }
        VelocityTest {
            // The test applies to relaxed iterations only, whose changes are `gs_relax` of
            // the way to the local solutions: like the impulse test, it bounds the change
            // divided by the relaxation, so that `velocity_tol` means the same at any
            // relaxation.
            tol: params.velocity_tol * params.gauss_seidel.relax,
            after: params.gauss_seidel.relax_after,
            prev,
        }
    }

    /// Called after iteration `it` with the iterate `gv`: true when the test applies and no
    /// body's velocity changed by more than `velocity_tol x gs_relax` since the previous
    /// iteration. Bodies no contact can move keep their velocity, so every body may be
    /// compared.
    pub(super) fn settled(&mut self, it: u32, gv: &[Line], props: &[BodyProps]) -> bool {
        if self.tol <= 0.0 || it < self.after {
            return false;
        }
        let settled = it > self.after
            && self.prev.len() == gv.len()
            && gv.iter().zip(self.prev.iter()).zip(props).all(|((v, p), b)| {
                let d = v.v - p.v;
                d.x * d.x + d.y * d.y + (b.lever * d.z).powi(2) <= self.tol * self.tol
            });
        self.prev.clear();
        self.prev.extend_from_slice(gv);
        settled
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
