//! An outside test suite for the contact solver: 2D frictional contact problems given as a
//! Delassus matrix, `u = W r + q` (Siconos fc2d files), solved by nonlinear Gauss-Seidel
//! with the exact local solution of a full 2x2 block ([`crate::solver::law::solve_block`]),
//! and measured with Siconos's own error.

mod parse;

pub use parse::{parse, read};

use crate::solver::law::{project_cone, solve_block};
use crate::solver::space::ContactSpace;

/// A sparse square matrix in compressed columns.
#[derive(Clone, Debug, PartialEq)]
pub struct Csc {
    /// Size.
    pub n: usize,
    /// `col_start[j]..col_start[j+1]` indexes the entries of column j.
    pub col_start: Vec<usize>,
    /// Row of each entry.
    pub row_idx: Vec<usize>,
    /// Value of each entry.
    pub vals: Vec<f64>,
}

impl Csc {
    /// `y += a * W[:, j]`.
    fn axpy_col(&self, j: usize, a: f64, y: &mut [f64]) {
        for k in self.col_start[j]..self.col_start[j + 1] {
            y[self.row_idx[k]] += a * self.vals[k];
        }
    }

    /// `W[i][j]` (0 when not stored).
    pub fn get(&self, i: usize, j: usize) -> f64 {
        (self.col_start[j]..self.col_start[j + 1])
            .filter(|&k| self.row_idx[k] == i)
            .map(|k| self.vals[k])
            .sum()
    }
}

/// A frictional contact problem: find `r` with `u = W r + q` satisfying Signorini and
/// Coulomb at every contact (normal component first, then tangent).
#[derive(Clone, Debug, PartialEq)]
pub struct Problem {
    /// Number of contacts.
    pub nc: usize,
    /// The Delassus matrix (2 nc x 2 nc).
    pub w: Csc,
    /// Free velocities (2 nc).
    pub q: Vec<f64>,
    /// Friction coefficient of each contact.
    pub mu: Vec<f64>,
}

impl Problem {
    /// The 2x2 diagonal block of each contact, `(W_nn, W_tt, W_nt)`. The local solves
    /// assume a symmetric block: the two off-diagonal terms are averaged.
    pub fn blocks(&self) -> Vec<(f64, f64, f64)> {
        (0..self.nc)
            .map(|c| {
                let (a, b) = (2 * c, 2 * c + 1);
                let w = &self.w;
                (w.get(a, a), w.get(b, b), 0.5 * (w.get(a, b) + w.get(b, a)))
            })
            .collect()
    }
}

/// Solver options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveOptions {
    /// Target Siconos error.
    pub tol: f64,
    /// Sweep cap.
    pub max_iter: usize,
    /// Sweeps between two evaluations of the (costlier) error.
    pub check_every: usize,
}

impl Default for SolveOptions {
    fn default() -> Self {
        SolveOptions {
            tol: 1e-5,
            max_iter: 100_000,
            check_every: 10,
        }
    }
}

/// Outcome of a solve.
#[derive(Clone, Debug, PartialEq)]
pub struct Report {
    /// Contacts.
    pub contacts: usize,
    /// Gauss-Seidel sweeps done.
    pub iterations: usize,
    /// Siconos error of the returned impulses.
    pub error: f64,
    /// True when `error < tol`.
    pub converged: bool,
    /// Wall time of the solve (s).
    pub seconds: f64,
    /// The impulses.
    pub r: Vec<f64>,
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// `u = W r + q`.
pub fn velocities(p: &Problem, r: &[f64]) -> Vec<f64> {
    let mut u = p.q.clone();
    for (j, &rj) in r.iter().enumerate() {
        if rj != 0.0 {
            p.w.axpy_col(j, rj, &mut u);
        }
    }
    u
}

/// Siconos's error: for each contact `z = r - (u_n + mu |u_t|, u_t)`, the squared distance
/// between `r` and the projection of `z` on the cone, summed, square-rooted, and divided by
/// |q|, the norm Siconos's fc2d Gauss-Seidel passes to its error (not divided when |q| is
/// below the machine epsilon, as there).
pub fn siconos_error(p: &Problem, r: &[f64]) -> f64 {
    let u = velocities(p, r);
    let mut sum = 0.0;
    for c in 0..p.nc {
        let (rn, rt, un, ut, mu) = (r[2 * c], r[2 * c + 1], u[2 * c], u[2 * c + 1], p.mu[c]);
        let (pn, pt) = project_cone(rn - (un + mu * ut.abs()), rt - ut, mu);
        sum += (rn - pn).powi(2) + (rt - pt).powi(2);
    }
    let q = norm(&p.q);
    if q > f64::EPSILON {
        sum.sqrt() / q
    } else {
        sum.sqrt()
    }
}

/// Nonlinear Gauss-Seidel from `r = 0`, keeping `u = W r + q` up to date column by column.
pub fn solve(p: &Problem, opts: &SolveOptions) -> Report {
    let t0 = std::time::Instant::now();
    let n = 2 * p.nc;
    let blocks = p.blocks();
    let mut r = vec![0.0; n];
    let mut u = p.q.clone();
    let mut iterations = 0;
    let mut error = siconos_error(p, &r);
    while error >= opts.tol && iterations < opts.max_iter {
        for (c, &(wnn, wtt, wnt)) in blocks.iter().enumerate() {
            let (a, b) = (2 * c, 2 * c + 1);
            let ufn = u[a] - wnn * r[a] - wnt * r[b];
            let uft = u[b] - wnt * r[a] - wtt * r[b];
            let (rn, rt) = solve_block(wnn, wtt, wnt, ufn, uft, p.mu[c]);
            let (dn, dt) = (rn - r[a], rt - r[b]);
            if dn != 0.0 {
                p.w.axpy_col(a, dn, &mut u);
            }
            if dt != 0.0 {
                p.w.axpy_col(b, dt, &mut u);
            }
            r[a] = rn;
            r[b] = rt;
        }
        iterations += 1;
        if iterations % opts.check_every.max(1) == 0 || iterations == opts.max_iter {
            error = siconos_error(p, &r);
        }
    }
    Report {
        contacts: p.nc,
        iterations,
        error,
        converged: error < opts.tol,
        seconds: t0.elapsed().as_secs_f64(),
        r,
    }
}

/// A problem with its current impulses `r` and velocities `u = W r + q`, as the iterative
/// solvers of [`crate::solver`] see it (the engine's solvers run on it unchanged).
#[derive(Clone, Debug)]
pub struct Space<'a> {
    p: &'a Problem,
    blocks: Vec<(f64, f64, f64)>,
    r: Vec<f64>,
    u: Vec<f64>,
}

impl<'a> Space<'a> {
    /// The problem with every impulse 0 (`u = q`). The local solves assume symmetric
    /// blocks: the two off-diagonal terms of each are averaged.
    pub fn new(p: &'a Problem) -> Self {
        let blocks = p.blocks();
        Space {
            p,
            blocks,
            r: vec![0.0; 2 * p.nc],
            u: p.q.clone(),
        }
    }

    /// The impulses, `(r_n, r_t)` of each contact in turn.
    pub fn impulses(&self) -> &[f64] {
        &self.r
    }
}

impl ContactSpace for Space<'_> {
    fn len(&self) -> usize {
        self.p.nc
    }
    fn block(&self, c: usize) -> (f64, f64, f64) {
        self.blocks[c]
    }
    fn mu(&self, c: usize) -> f64 {
        self.p.mu[c]
    }
    fn impulse(&self, c: usize) -> (f64, f64) {
        (self.r[2 * c], self.r[2 * c + 1])
    }
    fn velocity(&self, c: usize) -> (f64, f64) {
        (self.u[2 * c], self.u[2 * c + 1])
    }
    fn set(&mut self, c: usize, rn: f64, rt: f64) {
        let (a, b) = (2 * c, 2 * c + 1);
        let (dn, dt) = (rn - self.r[a], rt - self.r[b]);
        if dn != 0.0 {
            self.p.w.axpy_col(a, dn, &mut self.u);
        }
        if dt != 0.0 {
            self.p.w.axpy_col(b, dt, &mut self.u);
        }
        self.r[a] = rn;
        self.r[b] = rt;
    }
    fn set_all(&mut self, r: &[(f64, f64)]) {
        for (c, &(rn, rt)) in r.iter().enumerate() {
            self.r[2 * c] = rn;
            self.r[2 * c + 1] = rt;
        }
        self.u = velocities(self.p, &self.r);
    }
}
