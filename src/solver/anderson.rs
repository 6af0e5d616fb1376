//! Anderson-accelerated nonlinear Gauss-Seidel (docs/method.md, "Anderson-accelerated
//! Gauss-Seidel"), written once against [`ContactSpace`] so that the engine's steps and
//! the Siconos fc2d problems run the same code.
//!
//! One plain Gauss-Seidel sweep over the contacts, in contact order, is a map `G` on the
//! impulses. Near a solution whose active set (open, stick, slide) has settled, `G` acts
//! like Gauss-Seidel on a linear system, and the sweeps converge linearly, slowly when the
//! sticking contacts form a nearly rigid hyperstatic network (high friction). Anderson
//! mixing (type II) combines the last iterates so as to minimise the linearised residual
//! `f = G(x) - x`; on a linear fixed-point problem it is equivalent to GMRES.

use super::law::project_cone;
use super::space::{ContactSpace, local_solution};
use super::{SolveStats, SolverParams};

/// Plain sweeps of a solve before the first mixing: the first sweeps from a warm start
/// change the active set (contacts open, close, start or stop sliding), and a least-squares
/// fit across such changes extrapolates along directions the next sweep undoes. See
/// docs/method.md, "Anderson-accelerated Gauss-Seidel", for how it was chosen.
pub const START: u32 = 2;

/// A mixed iterate is kept if the sweep from it changes the impulses by no more than this
/// times the smallest change of an accepted sweep so far (Euclidean norms of all
/// impulses); otherwise the solve returns to the plain sweep's result the mixing started
/// from and restarts its history. The reference is the smallest change rather than the
/// last one so that accepted iterates cannot let the change grow step after step; the
/// factor leaves room for Anderson mixing, which does not decrease the residual at every
/// iteration even on a linear problem (a factor of 1 refused about half of the mixed
/// iterates at friction 3, docs/method.md, "Anderson-accelerated Gauss-Seidel").
pub const ACCEPT: f64 = 2.0;

/// Smallest pivot, relative to the column's own squared norm, of a difference column kept in
/// the least-squares fit: a column whose component outside the span of the newer ones is
/// below `sqrt(DROP)` of its length is left out, which bounds the condition number of the
/// fitted system by about `1 / sqrt(DROP)` (1e5).
pub const DROP: f64 = 1e-10;

/// Plain sweeps between two mixings: the map that is mixed is `every` sweeps.
pub const EVERY: u32 = 1;

/// Settings of one solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// Tolerance on the relative change of a plain sweep (dimensionless).
    pub tol: f64,
    /// Sweep cap.
    pub max_iter: u32,
    /// Anderson depth `m`: differences of the last `m + 1` iterates enter the fit; 0 is plain
    /// Gauss-Seidel.
    pub depth: usize,
    /// Plain sweeps before the first mixing ([`START`]).
    pub start: u32,
    /// Safeguard factor ([`ACCEPT`]).
    pub accept: f64,
    /// Smallest relative pivot of a column kept in the fit ([`DROP`]).
    pub drop: f64,
    /// Sweeps per application of the mixed map ([`EVERY`]).
    pub every: u32,
}

impl Options {
    /// The options of the engine's solver parameters, with the built-in [`START`] and
    /// [`ACCEPT`].
    pub fn from_params(p: &SolverParams) -> Self {
        Options {
            tol: p.tol,
            max_iter: p.max_iter,
            depth: p.anderson.depth as usize,
            start: START,
            accept: ACCEPT,
            drop: DROP,
            every: EVERY,
        }
    }
}

/// What one solve did, beyond [`SolveStats`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Outcome {
    /// Iterations (each one plain sweep), the last relative change and whether it met `tol`.
    pub stats: SolveStats,
    /// Mixed iterates installed (each costs one rebuild of the velocities from the free ones,
    /// [`ContactSpace::set_all`]).
    pub mixed: u32,
    /// Mixed iterates refused by the safeguard (each costs one more rebuild: the return to
    /// the plain iterate).
    pub rejected: u32,
}

impl Outcome {
    /// Velocity rebuilds, each `set_all`: one per mixed iterate and one per refusal.
    pub fn rebuilds(&self) -> u32 {
        self.mixed + self.rejected
    }
}

/// Solves the space with the engine's parameters ([`Options::from_params`]).
pub fn solve<S: ContactSpace + ?Sized>(s: &mut S, params: &SolverParams) -> SolveStats {
    solve_with(s, &Options::from_params(params)).stats
}

/// One plain Gauss-Seidel sweep in contact order: every contact takes its local solution
/// with the others held ([`local_solution`]). `x` holds the impulses before the sweep on
/// entry and after it on return. Returns (sum of squared changes, sum of squared new
/// impulses), summed in contact order.
fn sweep<S: ContactSpace + ?Sized>(s: &mut S, x: &mut [f64]) -> (f64, f64) {
    let (mut d2, mut r2) = (0.0, 0.0);
    for c in 0..s.len() {
        let (rn, rt) = local_solution(s, c);
        let (on, ot) = (x[2 * c], x[2 * c + 1]);
        d2 += (rn - on) * (rn - on) + (rt - ot) * (rt - ot);
        r2 += rn * rn + rt * rt;
        s.set(c, rn, rt);
        x[2 * c] = rn;
        x[2 * c + 1] = rt;
    }
    (d2, r2)
}

/// The last `depth` differences of residuals `f = G(x) - x` and of images `G(x)` between
/// consecutive iterates, in a ring, with their Gram matrix.
struct History {
    depth: usize,
    dim: usize,
    /// Residual differences, slot after slot (`depth * dim`).
    df: Vec<f64>,
    /// Image differences, slot after slot.
    dg: Vec<f64>,
    /// Gram matrix of the residual differences, `depth x depth`, by slot.
    gram: Vec<f64>,
    /// Slots in use, oldest first.
    order: Vec<usize>,
}

impl History {
    fn new(depth: usize, dim: usize) -> Self {
        History {
            depth,
            dim,
            df: vec![0.0; depth * dim],
            dg: vec![0.0; depth * dim],
            gram: vec![0.0; depth * depth],
            order: Vec::with_capacity(depth),
        }
    }

    fn clear(&mut self) {
        self.order.clear();
    }

    /// Adds the differences `f - f_prev`, `g - g_prev`, dropping the oldest pair when full,
    /// and updates the Gram matrix (one pass over the new column and every kept one).
    fn push(&mut self, f: &[f64], f_prev: &[f64], g: &[f64], g_prev: &[f64]) {
        let slot = if self.order.len() < self.depth {
            self.order.len()
        } else {
            self.order.remove(0)
        };
        let dim = self.dim;
        for i in 0..dim {
            self.df[slot * dim + i] = f[i] - f_prev[i];
            self.dg[slot * dim + i] = g[i] - g_prev[i];
        }
        self.order.push(slot);
        let new = &self.df[slot * dim..(slot + 1) * dim];
        for &k in &self.order {
            let col = &self.df[k * dim..(k + 1) * dim];
            let dot = dot(new, col);
            self.gram[slot * self.depth + k] = dot;
            self.gram[k * self.depth + slot] = dot;
        }
    }

    /// The mixing coefficients `gamma` minimising `|f - dF gamma|`, one per slot in use
    /// (oldest first), by a Cholesky factorisation of the normal equations scaled to a
    /// unit diagonal, columns taken newest first; a column whose pivot falls below
    /// [`DROP`] (nearly in the span of the newer ones) gets `gamma = 0`. Empty when no
    /// column is usable.
    fn coefficients(&self, f: &[f64], drop: f64) -> Vec<f64> {
        let dim = self.dim;
        // Newest first: the newest differences carry the current (settled) behaviour.
        let cols: Vec<usize> = self.order.iter().rev().copied().collect();
        let m = cols.len();
        let scale: Vec<f64> = cols
            .iter()
            .map(|&k| {
                let d = self.gram[k * self.depth + k];
                if d > 0.0 { 1.0 / d.sqrt() } else { 0.0 }
            })
            .collect();
        let rhs: Vec<f64> = cols
            .iter()
            .zip(&scale)
            .map(|(&k, &sc)| sc * dot(&self.df[k * dim..(k + 1) * dim], f))
            .collect();
        // Lower factor of the kept columns, `l[a][b]` for kept a >= b (row-major m x m).
        let mut l = vec![0.0; m * m];
        let mut kept: Vec<usize> = Vec::with_capacity(m);
        for a in 0..m {
            if scale[a] == 0.0 {
                continue;
            }
            let ga = |b: usize| scale[a] * scale[b] * self.gram[cols[a] * self.depth + cols[b]];
            let mut row = vec![0.0; m];
            for (bi, &b) in kept.iter().enumerate() {
                let mut v = ga(b);
                for &c in &kept[..bi] {
                    v -= row[c] * l[b * m + c];
                }
                row[b] = v / l[b * m + b];
            }
            let mut pivot = ga(a);
            for &c in &kept {
                pivot -= row[c] * row[c];
            }
            if pivot <= drop {
                continue;
            }
            row[a] = pivot.sqrt();
            l[a * m..(a + 1) * m].copy_from_slice(&row);
            kept.push(a);
        }
        if kept.is_empty() {
            return Vec::new();
        }
        // Forward then backward substitution over the kept columns.
        let mut y = vec![0.0; m];
        for (ai, &a) in kept.iter().enumerate() {
            let mut v = rhs[a];
            for &c in &kept[..ai] {
                v -= l[a * m + c] * y[c];
            }
            y[a] = v / l[a * m + a];
        }
        for ai in (0..kept.len()).rev() {
            let a = kept[ai];
            let mut v = y[a];
            for &c in &kept[ai + 1..] {
                v -= l[c * m + a] * y[c];
            }
            y[a] = v / l[a * m + a];
        }
        // Back to slot order (oldest first) and unscaled.
        let mut gamma = vec![0.0; m];
        for a in 0..m {
            gamma[m - 1 - a] = y[a] * scale[a];
        }
        gamma
    }
}

/// Dot product in a fixed order: four interleaved partial sums (elements `i mod 4`), added
/// as `(s0 + s1) + (s2 + s3)`, then the tail. Four independent sums let the additions
/// overlap (a single running sum waits on each addition), and the order, hence the
/// result, depends only on the length.
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut s = [0.0; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ta, tb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            s[k] += x[k] * y[k];
        }
    }
    let mut total = (s[0] + s[1]) + (s[2] + s[3]);
    for (x, y) in ta.iter().zip(tb) {
        total += x * y;
    }
    total
}

/// Anderson-accelerated Gauss-Seidel from the impulses the space holds (warm start).
///
/// Each iteration is one plain sweep `x -> g = G(x)`; its relative change
/// `|g - x| / |g|` is the stopping measure (the Gauss-Seidel one, docs/method.md,
/// "Convergence"), and the solve ends on the sweep that meets `opts.tol`, so the space
/// is left at a plain sweep's result with its velocities carried by the sweep. Otherwise,
/// from sweep `opts.start` on and after every `opts.every` sweeps, the next iterate is
/// `g - dG gamma` with `gamma` minimising `|f - dF gamma|`, projected onto every contact's
/// Coulomb cone and installed with [`ContactSpace::set_all`]. Safeguard: when the sweep
/// from a mixed iterate changes the impulses by more than `opts.accept` times the smallest
/// change of an accepted sweep so far, that sweep is discarded (it still counts as an
/// iteration), the space returns to the plain result the mixture came from and the
/// history restarts from it.
pub fn solve_with<S: ContactSpace + ?Sized>(s: &mut S, opts: &Options) -> Outcome {
    solve_until(s, opts, |_, _| false)
}

/// [`solve_with`], also ending after the sweep of iteration `it` when `stop(s, it)` is true
/// (the space then holds that sweep's result): for studies that stop on another measure,
/// such as [`super::space::local_residual`]. `stats.converged` still tells whether `tol`
/// was met.
pub fn solve_until<S: ContactSpace + ?Sized>(
    s: &mut S,
    opts: &Options,
    mut stop: impl FnMut(&S, u32) -> bool,
) -> Outcome {
    let n = s.len();
    let dim = 2 * n;
    let every = opts.every.max(1);
    let mut out = Outcome::default();
    // x: the current impulses; base: the iterate the current block of `every` sweeps
    // started from (the argument of the mixed map, whose image is x at the block's end).
    let mut x: Vec<f64> = (0..n)
        .flat_map(|c| {
            let (rn, rt) = s.impulse(c);
            [rn, rt]
        })
        .collect();
    let mut base = x.clone();
    let mut in_block = 0;
    let mut f = vec![0.0; dim];
    let mut f_prev = vec![0.0; dim];
    let mut g_prev = vec![0.0; dim];
    let mut have_prev = false;
    // Smallest squared change of an accepted sweep so far: the safeguard's reference.
    let mut best = f64::INFINITY;
    let mut mixed_last = false;
    let mut hist = History::new(opts.depth, dim);
    let mut next = vec![(0.0, 0.0); n];
    for it in 1..=opts.max_iter {
        let (d2, r2) = sweep(s, &mut x);
        if out.stats.record_change(it, d2, r2, opts.tol) || stop(s, it) {
            break;
        }
        if mixed_last && d2 > opts.accept * opts.accept * best {
            // The mixed iterate made things worse: back to the plain result it came from.
            for (c, r) in next.iter_mut().enumerate() {
                *r = (g_prev[2 * c], g_prev[2 * c + 1]);
            }
            s.set_all(&next);
            x.copy_from_slice(&g_prev);
            base.copy_from_slice(&g_prev);
            in_block = 0;
            hist.clear();
            have_prev = false;
            mixed_last = false;
            out.rejected += 1;
            continue;
        }
        mixed_last = false;
        best = best.min(d2);
        in_block += 1;
        if in_block < every {
            continue;
        }
        in_block = 0;
        for i in 0..dim {
            f[i] = x[i] - base[i];
        }
        if have_prev && opts.depth > 0 {
            hist.push(&f, &f_prev, &x, &g_prev);
        }
        std::mem::swap(&mut f, &mut f_prev);
        g_prev.copy_from_slice(&x);
        have_prev = true;
        base.copy_from_slice(&x);
        if it < opts.start || hist.order.is_empty() {
            continue;
        }
        let gamma = hist.coefficients(&f_prev, opts.drop);
        if gamma.is_empty() {
            continue;
        }
        for (k, &gk) in hist.order.iter().zip(&gamma) {
            if gk != 0.0 {
                let col = &hist.dg[k * dim..(k + 1) * dim];
                for i in 0..dim {
                    x[i] -= gk * col[i];
                }
            }
        }
        for (c, r) in next.iter_mut().enumerate() {
            *r = project_cone(x[2 * c], x[2 * c + 1], s.mu(c));
            x[2 * c] = r.0;
            x[2 * c + 1] = r.1;
        }
        s.set_all(&next);
        base.copy_from_slice(&x);
        mixed_last = true;
        out.mixed += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn least_squares_recovers_an_exact_combination_and_drops_a_repeated_column() {
        // Columns e1, e2 (and e1 again, dependent): f = 3 e1 - 2 e2 is fitted exactly.
        let dim = 3;
        let mut h = History::new(3, dim);
        let zero = vec![0.0; dim];
        for col in [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]] {
            h.push(&col, &zero, &col, &zero);
        }
        let gamma = h.coefficients(&[3.0, -2.0, 0.0], DROP);
        // Newest first: the third column (e1) is kept, the first (a repeat) dropped.
        assert_eq!(gamma.len(), 3);
        assert_eq!(gamma[0], 0.0);
        assert!(
            (gamma[1] + 2.0).abs() < 1e-14 && (gamma[2] - 3.0).abs() < 1e-14,
            "{gamma:?}"
        );
    }
}
