//! Iterative sweeps over the contacts of one step.
//!
//! `gv` holds the generalized velocities (vx, vy, spin) of every body: disks first, then
//! walls. On entry it must already include the impulses the contacts carry (warm start).

use glam::DVec3;
use rayon::prelude::*;

use super::{Method, SolveStats, SolverParams, law};
use crate::contact::Contact;

/// Contacts per chunk in parallel sweeps and in every convergence sum: partial sums are
/// always taken over the same chunks in the same order, so the result does not depend on
/// the number of threads. Small enough that a color of about a thousand contacts splits
/// evenly between the members of a thread team (see [`super::team`]).
pub(super) const CHUNK: usize = 64;

/// Updates one contact from the current velocities: solves the local law with its own
/// impulse removed, applies the impulse change to both bodies and returns the squared
/// change and the squared new impulse.
///
/// # Safety
/// `gv` must be valid for bodies `c.i` and `c.j`, and no other thread may write them while
/// this runs (guaranteed by the coloring: contacts of one color share no movable body).
#[inline]
unsafe fn update(c: &mut Contact, gv: *mut DVec3) -> (f64, f64) {
    // SAFETY: the caller guarantees validity and exclusive access to the written bodies.
    let (pi, pj) = unsafe { (gv.add(c.i as usize), gv.add(c.j as usize)) };
    let (vi, vj) = unsafe { (pi.read(), pj.read()) };
    let (un, ut) = c.relative_velocity_of(vi, vj);
    let ufn = un - c.wnn * c.rn - c.wnt * c.rt + c.bias_n;
    let uft = ut - c.wnt * c.rn - c.wtt * c.rt + c.bias_t;
    let (rn, rt) = law::solve(c.wnn, c.wtt, c.wnt, ufn, uft, c.mu);
    let (drn, drt) = (rn - c.rn, rt - c.rt);
    if drn != 0.0 || drt != 0.0 {
        let (dvi, dvj) = c.velocity_changes(drn, drt);
        unsafe {
            pi.write(pi.read() + dvi);
            if c.moves_j() {
                pj.write(pj.read() + dvj);
            }
        }
    }
    c.rn = rn;
    c.rt = rt;
    (drn * drn + drt * drt, rn * rn + rt * rt)
}

/// A raw pointer to the velocities that may cross threads; soundness comes from the
/// coloring (see [`update`]).
#[derive(Clone, Copy)]
pub(super) struct SharedVel(pub(super) *mut DVec3);
unsafe impl Send for SharedVel {}
unsafe impl Sync for SharedVel {}

pub(super) fn sweep_chunk(chunk: &mut [Contact], gv: SharedVel) -> (f64, f64) {
    let mut acc = (0.0, 0.0);
    for c in chunk {
        // SAFETY: indices come from detection over this `gv`; exclusivity from the caller.
        let (d, r) = unsafe { update(c, gv.0) };
        acc.0 += d;
        acc.1 += r;
    }
    acc
}

/// One Gauss-Seidel sweep over `contacts` in order, where consecutive `ranges` are colors
/// (a single range for plain order), on the calling thread. Returns the chunked sums
/// (change^2, impulse^2); [`super::team`] sweeps colors on several threads with the same
/// chunks and the same order of summation.
fn sweep(contacts: &mut [Contact], ranges: &[u32], gv: &mut [DVec3]) -> (f64, f64) {
    let n_bodies = gv.len();
    let ptr = SharedVel(gv.as_mut_ptr());
    debug_assert!(
        contacts
            .iter()
            .all(|c| (c.i as usize) < n_bodies && (c.j as usize) < n_bodies)
    );
    let mut total = (0.0, 0.0);
    for w in ranges.windows(2) {
        let part = &mut contacts[w[0] as usize..w[1] as usize];
        for ch in part.chunks_mut(CHUNK) {
            let (d, r) = sweep_chunk(ch, ptr);
            total.0 += d;
            total.1 += r;
        }
    }
    total
}

impl SolveStats {
    /// Records iteration `it` with its sums (change^2, impulse^2) and tells whether the
    /// relative change met `tol`.
    fn record(&mut self, it: u32, d2: f64, r2: f64, tol: f64) -> bool {
        self.iterations = it;
        self.residual = relative_change(d2, r2);
        self.converged = self.residual <= tol;
        self.converged
    }
}

/// Relative quadratic change of one iteration; 0 when nothing carries or changes impulse.
fn relative_change(d2: f64, r2: f64) -> f64 {
    if d2 == 0.0 {
        0.0
    } else if r2 == 0.0 {
        f64::INFINITY
    } else {
        (d2 / r2).sqrt()
    }
}

/// Solves the contact problem. For colored Gauss-Seidel `ranges` gives the color
/// boundaries (contacts must be sorted by color) and `serial_last` says whether the last
/// range is a serial group (contacts sharing a force-driven wall); both are ignored
/// otherwise. `gv0` are the free velocities (needed by Jacobi, which rebuilds the
/// velocities every iteration).
pub fn solve(
    params: &SolverParams,
    contacts: &mut [Contact],
    ranges: &[u32],
    serial_last: bool,
    gv0: &[DVec3],
    gv: &mut [DVec3],
) -> SolveStats {
    let whole = [0, contacts.len() as u32];
    let ranges = match params.method {
        Method::Gs => &whole[..],
        Method::ColoredGs => ranges,
        Method::Jacobi => return jacobi(params, contacts, gv0, gv),
    };
    let mut stats = SolveStats {
        colors: (ranges.len() - 1) as u32,
        ..Default::default()
    };
    let team = params.team_size();
    if params.method == Method::ColoredGs && team > 1 && contacts.len() >= params.parallel_min {
        super::team::sweep_iterations(
            contacts,
            ranges,
            serial_last,
            gv,
            team,
            params.max_iter,
            |it, d2, r2| stats.record(it, d2, r2, params.tol),
        );
        return stats;
    }
    for it in 1..=params.max_iter {
        let (d2, r2) = sweep(contacts, ranges, gv);
        if stats.record(it, d2, r2, params.tol) {
            break;
        }
    }
    stats
}

/// Relaxed Jacobi: every contact is solved from the velocities of the previous iteration,
/// the impulses are relaxed, and the velocities are rebuilt from the free velocities by a
/// sequential gather (deterministic, no float atomics).
fn jacobi(params: &SolverParams, contacts: &mut [Contact], gv0: &[DVec3], gv: &mut [DVec3]) -> SolveStats {
    let omega = params.relax;
    let mut stats = SolveStats::default();
    let mut fresh = vec![(0.0, 0.0); contacts.len()];
    for it in 1..=params.max_iter {
        let solve_one = |(c, out): (&Contact, &mut (f64, f64))| {
            let (un, ut) = c.relative_velocity(gv);
            let ufn = un - c.wnn * c.rn - c.wnt * c.rt + c.bias_n;
            let uft = ut - c.wnt * c.rn - c.wtt * c.rt + c.bias_t;
            let (rn, rt) = law::solve(c.wnn, c.wtt, c.wnt, ufn, uft, c.mu);
            *out = (c.rn + omega * (rn - c.rn), c.rt + omega * (rt - c.rt));
        };
        if params.parallel && contacts.len() >= params.parallel_min {
            contacts.par_iter().zip(fresh.par_iter_mut()).for_each(solve_one);
        } else {
            contacts.iter().zip(fresh.iter_mut()).for_each(solve_one);
        }
        let (mut d2, mut r2) = (0.0, 0.0);
        gv.copy_from_slice(gv0);
        for (c, &(rn, rt)) in contacts.iter_mut().zip(&fresh) {
            d2 += (rn - c.rn).powi(2) + (rt - c.rt).powi(2);
            r2 += rn * rn + rt * rt;
            c.rn = rn;
            c.rt = rt;
            c.apply(gv, rn, rt);
        }
        if stats.record(it, d2, r2, params.tol) {
            break;
        }
    }
    stats
}
