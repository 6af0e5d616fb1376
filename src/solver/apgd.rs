//! Accelerated projected Jacobi on the Coulomb fixed point (docs/method.md, "Accelerated
//! projected Jacobi (apgd)"): every contact takes a damped step of its own law from the
//! same velocities, the velocities are rebuilt once (one matrix product `u = W R + q`), and
//! Nesterov momentum with adaptive restart carries the iterates across the sample faster
//! than one contact layer per iteration.
//!
//! Written once against [`ContactSpace`], so the engine (through [`super::space::BodySpace`])
//! and the Siconos fc2d problems ([`crate::fc2d::Space`]) run the same code. Every
//! per-contact computation is independent of the others and every sum runs in contact
//! order, so the result is bit-reproducible and the contact loops can be split across
//! threads or GPU invocations without changing it if the sums keep that order.

use super::law::{self, project_cone};
use super::space::ContactSpace;
use super::{SolveStats, SolverParams};

/// How each contact steps from the extrapolated point `y` (docs/method.md, "Accelerated
/// projected Jacobi (apgd)", "The step").
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// The exact local law of the contact with its Delassus block scaled by the step
    /// factor `L`: the proximal step in the metric of the block, whose fixed points are
    /// exactly the Coulomb solutions (the De Saxce shift `mu |u_t|` is taken at the trial
    /// velocity, solved for exactly by [`law::solve`]). The default.
    Local,
    /// The explicit De Saxce map `R_c <- P_K(y_c - (u_n + mu |u_t|, u_t) / (L d_c))`, with
    /// the shift taken at the velocities of `y` and `d_c` the largest eigenvalue of the
    /// contact's block, projected on the Coulomb cone in the Euclidean metric. Same fixed
    /// points; kept for comparison.
    DeSaxce,
}

/// Options of the solver besides the common [`SolverParams`] (`tol`, `max_iter`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Options {
    /// The contact step.
    pub step: Step,
    /// Nesterov momentum; off gives the plain projected (damped) Jacobi iteration with the
    /// same step control, for comparison.
    pub momentum: bool,
    /// Restart the momentum also when the residual grew over the iteration (besides the
    /// gradient test, which is always on when momentum is).
    pub residual_restart: bool,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            step: Step::Local,
            momentum: true,
            residual_restart: false,
        }
    }
}

/// What the solver did, beyond [`SolveStats`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Report {
    /// The common statistics: `iterations` counts trial steps, each one matrix product
    /// (rejected trials included); `residual` is the local residual of the returned
    /// impulses ([`super::space::local_residual`]).
    pub stats: SolveStats,
    /// Matrix products `u = W R + q` (velocity rebuilds): `iterations`, plus one when the
    /// best iterate had to be restored at the cap.
    pub products: u32,
    /// Trial steps rejected by the step-size test.
    pub rejected: u32,
    /// Momentum restarts.
    pub restarts: u32,
    /// Step factor `L` at the end (dimensionless: a bound on the largest eigenvalue of `W`
    /// in the metric of its diagonal blocks, as found by the step-size test).
    pub step_factor: f64,
}

/// Starting step factor: the full Jacobi step, which is exact when contacts do not
/// interact; the step-size test raises it as the coupling demands.
const L_START: f64 = 1.0;
/// Factor by which `L` shrinks after each accepted step, so that it follows the coupling of
/// the contacts the iterates actually move (as in the APGD of Mazhar et al., 2015, which
/// uses 0.9). 0.95 rejected fewer steps and needed fewer products on both the fc2d
/// problems and captured engine states (docs/method.md, "Accelerated projected Jacobi
/// (apgd)").
const L_SHRINK: f64 = 0.95;
/// Margin over the measured Rayleigh quotient when a trial step is rejected.
const L_GROW: f64 = 1.5;

/// Solves with the default [`Options`] and returns the common statistics.
pub fn solve<S: ContactSpace + ?Sized>(s: &mut S, params: &SolverParams) -> SolveStats {
    solve_with(s, params, &Options::default()).stats
}

/// Per contact: block, friction, and the scale `d_c` of the explicit step.
#[derive(Clone, Copy)]
struct Blk {
    wnn: f64,
    wtt: f64,
    wnt: f64,
    mu: f64,
    d: f64,
}

impl Blk {
    /// `x' W_cc z`.
    fn dot(&self, x: (f64, f64), z: (f64, f64)) -> f64 {
        x.0 * (self.wnn * z.0 + self.wnt * z.1) + x.1 * (self.wnt * z.0 + self.wtt * z.1)
    }
    /// The metric of the step: the block itself (local step) or `d_c` times the identity
    /// (explicit step).
    fn metric(&self, step: Step, x: (f64, f64), z: (f64, f64)) -> f64 {
        match step {
            Step::Local => self.dot(x, z),
            Step::DeSaxce => self.d * (x.0 * z.0 + x.1 * z.1),
        }
    }
}

/// The exact local solution of a contact at impulse `r` and velocity `u` with its block
/// scaled by `l` (`l = 1`: [`super::space::local_solution`]).
fn local(b: &Blk, l: f64, r: (f64, f64), u: (f64, f64)) -> (f64, f64) {
    if b.wnn <= 0.0 {
        return (0.0, 0.0);
    }
    let (wnn, wtt, wnt) = (l * b.wnn, l * b.wtt, l * b.wnt);
    law::solve(
        wnn,
        wtt,
        wnt,
        u.0 - wnn * r.0 - wnt * r.1,
        u.1 - wnt * r.0 - wtt * r.1,
        b.mu,
    )
}

/// The trial impulse of a contact from the point `y` with velocity `u(y)` and step factor
/// `l`.
fn trial(b: &Blk, step: Step, l: f64, y: (f64, f64), u: (f64, f64)) -> (f64, f64) {
    if b.wnn <= 0.0 {
        return (0.0, 0.0);
    }
    match step {
        Step::Local => local(b, l, y, u),
        Step::DeSaxce => {
            let h = 1.0 / (l * b.d);
            project_cone(y.0 - h * (u.0 + b.mu * u.1.abs()), y.1 - h * u.1, b.mu)
        }
    }
}

/// The relative distance of impulses `r` (velocities `u`) to their local solutions, with
/// the same sums in the same order as [`super::space::local_residual`].
fn residual(blk: &[Blk], r: &[(f64, f64)], u: &[(f64, f64)]) -> f64 {
    let (mut d2, mut l2) = (0.0, 0.0);
    for ((b, &rc), &uc) in blk.iter().zip(r).zip(u) {
        let (ln, lt) = local(b, 1.0, rc, uc);
        d2 += (ln - rc.0).powi(2) + (lt - rc.1).powi(2);
        l2 += ln * ln + lt * lt;
    }
    super::convergence::relative_change(d2, l2)
}

/// Sets the impulses `r` in the space (one matrix product) and reads the velocities back.
fn product<S: ContactSpace + ?Sized>(s: &mut S, r: &[(f64, f64)], u: &mut [(f64, f64)]) {
    s.set_all(r);
    for (c, uc) in u.iter_mut().enumerate() {
        *uc = s.velocity(c);
    }
}

/// Accelerated projected Jacobi from the impulses the space holds (warm start). Stops when
/// the local residual of the current iterate is at most `params.tol`, or after
/// `params.max_iter` trial steps; the space is left holding the returned impulses (the last
/// iterate when converged, otherwise the one of smallest local residual) and their
/// velocities.
pub fn solve_with<S: ContactSpace + ?Sized>(s: &mut S, params: &SolverParams, opts: &Options) -> Report {
    let n = s.len();
    let mut rep = Report {
        step_factor: L_START,
        ..Report::default()
    };
    if n == 0 {
        rep.stats.converged = true;
        return rep;
    }
    let blk: Vec<Blk> = (0..n)
        .map(|c| {
            let (wnn, wtt, wnt) = s.block(c);
            // Largest eigenvalue of the symmetric 2x2 block.
            let d = 0.5 * (wnn + wtt) + (0.25 * (wnn - wtt).powi(2) + wnt * wnt).sqrt();
            Blk {
                wnn,
                wtt,
                wnt,
                mu: s.mu(c),
                d,
            }
        })
        .collect();
    // x: current iterate, xp: previous, y: extrapolated point; u* their velocities.
    let mut x: Vec<(f64, f64)> = (0..n).map(|c| s.impulse(c)).collect();
    let mut ux: Vec<(f64, f64)> = (0..n).map(|c| s.velocity(c)).collect();
    let mut y = x.clone();
    let mut uy = ux.clone();
    let mut xn = vec![(0.0, 0.0); n];
    let mut un = vec![(0.0, 0.0); n];
    let mut res = residual(&blk, &x, &ux);
    let mut best = (res, x.clone());
    rep.stats.residual = res;
    if res <= params.tol {
        rep.stats.converged = true;
        return rep;
    }
    let mut l = L_START;
    let mut theta = 1.0_f64;
    // Whether the space holds the best iterate (it holds the last trial).
    let mut holds_best = true;
    while rep.stats.iterations < params.max_iter {
        for c in 0..n {
            xn[c] = trial(&blk[c], opts.step, l, y[c], uy[c]);
        }
        product(s, &xn, &mut un);
        holds_best = false;
        rep.stats.iterations += 1;
        rep.products += 1;
        // Step-size test, exact for the convex part of the problem: the step must not move
        // further in W than its metric allows, `d' W d <= L d' M d` with d = xn - y
        // (`W d = u(xn) - u(y)`, no extra product).
        let (mut wdd, mut mdd) = (0.0, 0.0);
        for c in 0..n {
            let d = (xn[c].0 - y[c].0, xn[c].1 - y[c].1);
            let wd = (un[c].0 - uy[c].0, un[c].1 - uy[c].1);
            wdd += d.0 * wd.0 + d.1 * wd.1;
            mdd += blk[c].metric(opts.step, d, d);
        }
        if wdd > l * mdd && mdd > 0.0 {
            rep.rejected += 1;
            l = (L_GROW * wdd / mdd).max(2.0 * l);
            continue;
        }
        let res_new = residual(&blk, &xn, &un);
        if res_new < best.0 {
            best.0 = res_new;
            best.1.copy_from_slice(&xn);
            holds_best = true;
        }
        rep.stats.residual = res_new;
        if res_new <= params.tol {
            rep.stats.converged = true;
            break;
        }
        // Gradient restart (O'Donoghue and Candes, 2015): the gradient mapping `y - xn`
        // points along the last move `xn - x`, i.e. the momentum now works uphill.
        let mut g = 0.0;
        for c in 0..n {
            let gy = (y[c].0 - xn[c].0, y[c].1 - xn[c].1);
            let dx = (xn[c].0 - x[c].0, xn[c].1 - x[c].1);
            g += blk[c].metric(opts.step, gy, dx);
        }
        let restart = !opts.momentum || g > 0.0 || (opts.residual_restart && res_new > res);
        std::mem::swap(&mut x, &mut xn);
        std::mem::swap(&mut ux, &mut un);
        // Now x, ux: new iterate; xn, un: the previous one.
        if restart {
            if opts.momentum {
                rep.restarts += 1;
            }
            theta = 1.0;
            y.copy_from_slice(&x);
            uy.copy_from_slice(&ux);
        } else {
            let t2 = theta * theta;
            let theta_new = 0.5 * (-t2 + theta * (t2 + 4.0).sqrt());
            let beta = theta * (1.0 - theta) / (t2 + theta_new);
            theta = theta_new;
            // u is affine in R, so u(y) follows from the two products already made.
            for c in 0..n {
                y[c] = (
                    x[c].0 + beta * (x[c].0 - xn[c].0),
                    x[c].1 + beta * (x[c].1 - xn[c].1),
                );
                uy[c] = (
                    ux[c].0 + beta * (ux[c].0 - un[c].0),
                    ux[c].1 + beta * (ux[c].1 - un[c].1),
                );
            }
        }
        res = res_new;
        l *= L_SHRINK;
    }
    rep.step_factor = l;
    if !rep.stats.converged {
        if !holds_best {
            product(s, &best.1, &mut un);
            rep.products += 1;
        }
        rep.stats.residual = best.0;
    }
    rep
}
