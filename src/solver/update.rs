//! The local update of one row, the one description of the local law that the sweeps run
//! (docs/method.md, "The local law and its exact solution"): the division-free form for a
//! diagonal Delassus block, and the full 2x2 law for contacts with a force-driven wall.
//! The vector lanes ([`super::simd`]) repeat the diagonal form operation for operation.

use glam::DVec3;

use super::ctx::{Ctx, Line};
use super::law;
use super::rows::{FULL, Row};
use crate::contact::Contact;

/// Contacts per chunk in parallel sweeps and in every convergence sum: partial sums are
/// always taken over the same chunks in the same order, so the result does not depend on
/// the number of threads. Small enough that a color of about a thousand contacts splits
/// evenly between the members of a thread team (see [`super::team`]).
pub(super) const CHUNK: usize = 64;

#[inline(always)]
fn larger(a: f64, b: f64) -> f64 {
    if a > b { a } else { b }
}

#[inline(always)]
fn smaller(a: f64, b: f64) -> f64 {
    if a < b { a } else { b }
}

/// Updates one row from the current velocities: solves the local law with its own impulse
/// removed, applies the impulse change to both bodies and returns the squared change and
/// the squared new impulse.
///
/// With a diagonal Delassus block, `R_n = max(0, -U_free_n / W_nn)` where
/// `U_free_n = U_n - W_nn R_n^old + bias_n`, i.e. `R_n^old - (U_n + bias_n) / W_nn`; the
/// tangential part likewise, clamped to the Coulomb interval (docs/method.md, "The local
/// law and its exact solution").
///
/// `RELAXED` selects the relaxed update at compile time: a run-time test of `ctx.relax`
/// in this loop costs a fifth of the update.
///
/// # Safety
/// `ctx` must be valid for bodies `r.i` and `r.j` (and contact `r.i` of a [`FULL`] row),
/// and no other thread may write them while this runs (see [`super::ctx`]).
#[inline(always)]
pub(super) unsafe fn update<const RELAXED: bool>(r: &mut Row, ctx: Ctx) -> (f64, f64) {
    if r.j == FULL {
        // SAFETY: forwarded from the caller.
        return unsafe { update_full(&mut *ctx.contacts.add(r.i as usize), ctx.gv, ctx.relax) };
    }
    // SAFETY: the caller guarantees validity and exclusive access to the written bodies.
    let (pi, pj) = unsafe { (ctx.gv.add(r.i as usize), ctx.gv.add(r.j as usize)) };
    let (bi, bj) = unsafe { (*ctx.props.add(r.i as usize), *ctx.props.add(r.j as usize)) };
    let (vi, vj) = unsafe { ((*pi).v, (*pj).v) };
    let (dx, dy) = (vi.x - vj.x, vi.y - vj.y);
    let un = dx * r.nx + dy * r.ny;
    let ut = dx * r.ny - dy * r.nx + vi.z * bi.lever + vj.z * bj.lever;
    // Comparisons rather than f64::max/min, whose NaN rules cost four instructions each in
    // this loop; a NaN velocity is caught after the solve (`check_finite`).
    let rn = larger(r.rn - (un + r.bias_n) * r.inv_wnn, 0.0);
    let lim = r.mu * rn;
    let rt = smaller(larger(r.rt - (ut + r.bias_t) * r.inv_wtt, -lim), lim);
    let (rn, rt) = if RELAXED {
        relaxed(ctx.relax, (r.rn, r.rt), (rn, rt))
    } else {
        (rn, rt)
    };
    let (drn, drt) = (rn - r.rn, rt - r.rt);
    let px = drn * r.nx + drt * r.ny;
    let py = drn * r.ny - drt * r.nx;
    // Bodies that cannot move are shared by the contacts of a color and never written.
    unsafe {
        if bi.movable() {
            (*pi).v = vi + DVec3::new(bi.inv_mass * px, bi.inv_mass * py, bi.k * drt);
        }
        if bj.movable() {
            (*pj).v += DVec3::new(-bj.inv_mass * px, -bj.inv_mass * py, bj.k * drt);
        }
    }
    r.rn = rn;
    r.rt = rt;
    (drn * drn + drt * drt, rn * rn + rt * rt)
}

/// The impulse `old + relax (local - old)`. Both lie in the Coulomb cone, which is convex,
/// so the result does too. Plain Gauss-Seidel (`relax` 1) takes the local solution itself:
/// `old + (local - old)` may differ from it in the last bit.
#[inline(always)]
fn relaxed(relax: f64, old: (f64, f64), local: (f64, f64)) -> (f64, f64) {
    if relax == 1.0 {
        local
    } else {
        (
            old.0 + relax * (local.0 - old.0),
            old.1 + relax * (local.1 - old.1),
        )
    }
}

/// [`update`] for a contact with a full Delassus block, on the contact itself.
///
/// # Safety
/// As [`update`].
unsafe fn update_full(c: &mut Contact, gv: *mut Line, relax: f64) -> (f64, f64) {
    // SAFETY: the caller guarantees validity and exclusive access to the written bodies.
    let (pi, pj) = unsafe { (gv.add(c.i as usize), gv.add(c.j as usize)) };
    let (vi, vj) = unsafe { ((*pi).v, (*pj).v) };
    let (un, ut) = c.relative_velocity_of(vi, vj);
    let ufn = un - c.wnn * c.rn - c.wnt * c.rt + c.bias_n;
    let uft = ut - c.wnt * c.rn - c.wtt * c.rt + c.bias_t;
    let (rn, rt) = law::solve(c.wnn, c.wtt, c.wnt, ufn, uft, c.mu);
    let (rn, rt) = relaxed(relax, (c.rn, c.rt), (rn, rt));
    let (drn, drt) = (rn - c.rn, rt - c.rt);
    if drn != 0.0 || drt != 0.0 {
        let (dvi, dvj) = c.velocity_changes(drn, drt);
        unsafe {
            if c.moves_i() {
                (*pi).v += dvi;
            }
            if c.moves_j() {
                (*pj).v += dvj;
            }
        }
    }
    c.rn = rn;
    c.rt = rt;
    (drn * drn + drt * drt, rn * rn + rt * rt)
}

/// Updates the rows of one chunk in order and returns their summed (change^2, impulse^2).
///
/// # Safety
/// As [`update`], for every row of the chunk.
pub(super) unsafe fn sweep_chunk(chunk: &mut [Row], ctx: Ctx) -> (f64, f64) {
    // SAFETY: forwarded from the caller.
    unsafe {
        if ctx.relax == 1.0 {
            sweep_rows::<false>(chunk, ctx)
        } else {
            sweep_rows::<true>(chunk, ctx)
        }
    }
}

/// [`sweep_chunk`] for one kind of update.
///
/// # Safety
/// As [`update`], for every row of the chunk.
unsafe fn sweep_rows<const RELAXED: bool>(chunk: &mut [Row], ctx: Ctx) -> (f64, f64) {
    let mut acc = (0.0, 0.0);
    for r in chunk {
        // SAFETY: forwarded from the caller.
        let (d, q) = unsafe { update::<RELAXED>(r, ctx) };
        acc.0 += d;
        acc.1 += q;
    }
    acc
}
