//! Iterative sweeps over the contacts of one step.
//!
//! `gv` holds the generalized velocities (vx, vy, spin) of every body: disks first, then
//! walls. On entry it must already include the impulses the contacts carry (warm start).
//!
//! Gauss-Seidel sweeps run on `Row`s, a compact copy of the contacts made once per
//! step: the full [`Contact`] is 192 bytes, three cache lines, and 10,000 of them do not
//! fit in a core's L2 cache. A row keeps only what an update reads and writes (80 bytes),
//! the inverse masses and lever arms live once per body in a small table, and the local
//! law is written without divisions or data-dependent branches: the update is most of a
//! step's time (docs/benchmarks.md, "Compact rows").

use glam::DVec3;
use rayon::prelude::*;

use super::color::{Coloring, Node, color};
use super::{Method, SolveStats, SolverParams, law};
use crate::contact::Contact;

/// Contacts per chunk in parallel sweeps and in every convergence sum: partial sums are
/// always taken over the same chunks in the same order, so the result does not depend on
/// the number of threads. Small enough that a color of about a thousand contacts splits
/// evenly between the members of a thread team (see [`super::team`]).
pub(super) const CHUNK: usize = 64;

/// Marks a row whose contact needs the full 2x2 law (body j translates along an axis
/// oblique to the contact frame: a force-driven wall); `i` then holds the contact's index.
const FULL: u32 = u32::MAX;

/// The part of a contact that a Gauss-Seidel update touches.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
pub(super) struct Row {
    i: u32,
    j: u32,
    nx: f64,
    ny: f64,
    /// `1 / W_nn` and `1 / W_tt` (0 for a direction in which neither body can move).
    inv_wnn: f64,
    inv_wtt: f64,
    mu: f64,
    bias_n: f64,
    bias_t: f64,
    rn: f64,
    rt: f64,
}

/// What a body contributes to an update: inverse mass, `r / I` (spin change per unit
/// tangential impulse), lever arm, and 1 when an impulse may change its velocity.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
pub(super) struct BodyProps {
    inv_mass: f64,
    k: f64,
    lever: f64,
    movable: f64,
}

#[inline(always)]
fn larger(a: f64, b: f64) -> f64 {
    if a > b { a } else { b }
}

#[inline(always)]
fn smaller(a: f64, b: f64) -> f64 {
    if a < b { a } else { b }
}

fn inverse(w: f64) -> f64 {
    if w > 0.0 { 1.0 / w } else { 0.0 }
}

/// The rows of the contacts, in their order, and the table of body properties they refer
/// to.
fn rows(contacts: &[Contact], n_bodies: usize, rows: &mut Vec<Row>, props: &mut Vec<BodyProps>) {
    props.clear();
    props.resize(n_bodies, BodyProps::default());
    rows.clear();
    rows.extend(contacts.iter().enumerate().map(|(k, c)| {
        // The sweeps index the velocities without bounds checks: this pass over every
        // contact is where the indices are checked.
        assert!(
            (c.i as usize) < n_bodies && (c.j as usize) < n_bodies,
            "contact with a body index beyond the velocities"
        );
        if c.ma != 0.0 || c.wnt != 0.0 {
            return Row {
                i: k as u32,
                j: FULL,
                ..Default::default()
            };
        }
        // Every contact of a body sees the same inverse mass, r / I and lever (detection
        // takes them from the body), so later contacts only rewrite the same values.
        props[c.i as usize] = BodyProps {
            inv_mass: c.mi,
            k: c.ki,
            lever: c.ri,
            movable: if c.moves_i() { 1.0 } else { 0.0 },
        };
        props[c.j as usize] = BodyProps {
            inv_mass: c.mj,
            k: c.kj,
            lever: c.rj,
            movable: if c.moves_j() { 1.0 } else { 0.0 },
        };
        Row {
            i: c.i,
            j: c.j,
            nx: c.n.x,
            ny: c.n.y,
            inv_wnn: inverse(c.wnn),
            inv_wtt: inverse(c.wtt),
            mu: c.mu,
            bias_n: c.bias_n,
            bias_t: c.bias_t,
            rn: c.rn,
            rt: c.rt,
        }
    }));
}

/// Copies the impulses of the rows back into their contacts: row `m` is row `order[m]` (or
/// `m` without an order) of the swept rows, which belongs to contact `active[..]` of that
/// (or to the contact of the same index when every contact was swept). Rows marked
/// [`FULL`] were updated in place.
fn store(rows: &[Row], order: Option<&[u32]>, active: Option<&[u32]>, contacts: &mut [Contact]) {
    for (m, r) in rows.iter().enumerate() {
        if r.j != FULL {
            let c = &mut contacts[contact_of(m, order, active)];
            c.rn = r.rn;
            c.rt = r.rt;
        }
    }
}

/// The contact of swept row `m` (see [`store`]).
fn contact_of(m: usize, order: Option<&[u32]>, active: Option<&[u32]>) -> usize {
    let k = order.map_or(m, |o| o[m] as usize);
    active.map_or(k, |a| a[k] as usize)
}

/// `U_n + bias_n` of a row at the velocities `gv`: the local law gives the row a normal
/// impulse from zero only when this is negative.
fn opening(r: &Row, gv: &[DVec3]) -> f64 {
    let (vi, vj) = (gv[r.i as usize], gv[r.j as usize]);
    (vi.x - vj.x) * r.nx + (vi.y - vj.y) * r.ny + r.bias_n
}

/// Moves out of `rows` the open rows that [`SolverParams::open_skip`] leaves out of the
/// sweeps (into `parked`), and lists in `active` the contact index of every row kept.
fn park(rows: &mut Vec<Row>, gv: &[DVec3], open_skip: f64, active: &mut Vec<u32>, parked: &mut Vec<Row>) {
    active.clear();
    parked.clear();
    let mut kept = 0;
    for m in 0..rows.len() {
        let r = rows[m];
        if r.j != FULL && r.rn == 0.0 && r.rt == 0.0 && opening(&r, gv) > open_skip {
            parked.push(r);
        } else {
            rows[kept] = r;
            active.push(m as u32);
            kept += 1;
        }
    }
    rows.truncate(kept);
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
/// # Safety
/// `ctx` must be valid for bodies `r.i` and `r.j` (and contact `r.i` of a [`FULL`] row), and
/// no other thread may write them while this runs (guaranteed by the coloring: contacts of
/// one color share no movable body).
///
/// `RELAXED` selects the relaxed update at compile time: a run-time test of `ctx.relax` in
/// this loop cost 20% per update (bench, 5000 disks).
#[inline(always)]
unsafe fn update<const RELAXED: bool>(r: &mut Row, ctx: Ctx) -> (f64, f64) {
    if r.j == FULL {
        // SAFETY: forwarded from the caller.
        return unsafe { update_full(&mut *ctx.contacts.add(r.i as usize), ctx.gv, ctx.relax) };
    }
    // SAFETY: the caller guarantees validity and exclusive access to the written bodies.
    let (pi, pj) = unsafe { (ctx.gv.add(r.i as usize), ctx.gv.add(r.j as usize)) };
    let (bi, bj) = unsafe { (*ctx.props.add(r.i as usize), *ctx.props.add(r.j as usize)) };
    let (vi, vj) = unsafe { (pi.read(), pj.read()) };
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
        if bi.movable != 0.0 {
            pi.write(vi + DVec3::new(bi.inv_mass * px, bi.inv_mass * py, bi.k * drt));
        }
        if bj.movable != 0.0 {
            pj.write(pj.read() + DVec3::new(-bj.inv_mass * px, -bj.inv_mass * py, bj.k * drt));
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
unsafe fn update_full(c: &mut Contact, gv: *mut DVec3, relax: f64) -> (f64, f64) {
    // SAFETY: the caller guarantees validity and exclusive access to the written bodies.
    let (pi, pj) = unsafe { (gv.add(c.i as usize), gv.add(c.j as usize)) };
    let (vi, vj) = unsafe { (pi.read(), pj.read()) };
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
                pi.write(pi.read() + dvi);
            }
            if c.moves_j() {
                pj.write(pj.read() + dvj);
            }
        }
    }
    c.rn = rn;
    c.rt = rt;
    (drn * drn + drt * drt, rn * rn + rt * rt)
}

/// Raw pointers to what the sweeps read and write, shared by the threads of a team;
/// soundness comes from the coloring (see [`update`]).
#[derive(Clone, Copy)]
pub(super) struct Ctx {
    pub(super) gv: *mut DVec3,
    pub(super) props: *const BodyProps,
    pub(super) contacts: *mut Contact,
    /// Gauss-Seidel relaxation of the current iteration.
    pub(super) relax: f64,
    /// Whether the rows of the proper colors are packed four at a time ([`pack_quads`]),
    /// to be swept in AVX registers.
    pub(super) quads: bool,
}
// SAFETY: see `update`: members of a team write disjoint bodies and contacts.
unsafe impl Send for Ctx {}
unsafe impl Sync for Ctx {}

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

/// [`sweep_chunk`] for a chunk of one color (rows that share no movable body and hold no
/// [`FULL`] row). On x86_64, several rows at a time in the lanes of vector registers, with
/// the same operations in the same order as [`update`], so bit for bit the same result:
/// when the rows are packed ([`Ctx::quads`]), four at a time in AVX registers, then two in
/// SSE2 registers (part of the baseline), then the last row alone: the sweeps are most of
/// a step, and wider updates are what made them cheaper (docs/benchmarks.md, "Vector
/// sweeps"). Elsewhere, row by row.
///
/// # Safety
/// As [`update`], for every row of the chunk; no two rows share a movable body; with
/// `ctx.quads`, the chunk starts a packed quad (it is a chunk of [`pack_quads`]'s layout)
/// and the processor has AVX.
pub(super) unsafe fn sweep_color_chunk(chunk: &mut [Row], ctx: Ctx) -> (f64, f64) {
    // SAFETY: forwarded from the caller.
    #[cfg(not(target_arch = "x86_64"))]
    return unsafe { sweep_chunk(chunk, ctx) };
    #[cfg(target_arch = "x86_64")]
    unsafe {
        if ctx.relax == 1.0 {
            sweep_lanes::<false>(chunk, ctx)
        } else {
            sweep_lanes::<true>(chunk, ctx)
        }
    }
}

/// [`sweep_color_chunk`] for one kind of update: the packed quads, then pairs, then the
/// last row.
///
/// # Safety
/// As [`sweep_color_chunk`].
#[cfg(target_arch = "x86_64")]
unsafe fn sweep_lanes<const RELAXED: bool>(chunk: &mut [Row], ctx: Ctx) -> (f64, f64) {
    let mut acc = (0.0, 0.0);
    let n4 = if ctx.quads { chunk.len() / 4 * 4 } else { 0 };
    let (head, tail) = chunk.split_at_mut(n4);
    // SAFETY: forwarded from the caller, who packed the rows and checked AVX for quads.
    unsafe {
        if n4 > 0 {
            simd::sweep_quads::<RELAXED>(head, ctx, &mut acc);
        }
        simd::sweep_pairs::<RELAXED>(tail, ctx, &mut acc);
    }
    acc
}

/// Four rows laid out field by field in the bytes of four [`Row`]s, so that the AVX sweep
/// loads each field of the four with one instruction.
#[derive(Clone, Copy, Default)]
#[repr(C)]
struct Quad {
    i: [u32; 4],
    j: [u32; 4],
    nx: [f64; 4],
    ny: [f64; 4],
    inv_wnn: [f64; 4],
    inv_wtt: [f64; 4],
    mu: [f64; 4],
    bias_n: [f64; 4],
    bias_t: [f64; 4],
    rn: [f64; 4],
    rt: [f64; 4],
}

const _: () = assert!(std::mem::size_of::<Quad>() == 4 * std::mem::size_of::<Row>());
const _: () = assert!(std::mem::align_of::<Quad>() <= std::mem::align_of::<Row>());
const _: () = assert!(CHUNK.is_multiple_of(4), "chunks must hold whole quads");

/// Whether the colored sweeps run four rows at a time: on x86_64 with AVX (checked once at
/// run time), unless `CDLAB_NO_AVX=1` asks for the pairs (to time or compare them).
pub(super) fn avx() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::sync::OnceLock;
        static AVX: OnceLock<bool> = OnceLock::new();
        *AVX.get_or_init(|| {
            std::arch::is_x86_feature_detected!("avx")
                && std::env::var_os("CDLAB_NO_AVX").is_none_or(|v| v != "1")
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

/// How the colored sweeps of this process update a color: "AVX, 4 contacts at a time",
/// "SSE2, 2 contacts at a time" or "1 contact at a time" (named in the CPU backend's
/// description, so that timings from different processors can be read side by side).
pub fn colored_lanes() -> &'static str {
    if avx() {
        "AVX, 4 contacts at a time"
    } else if cfg!(target_arch = "x86_64") {
        "SSE2, 2 contacts at a time"
    } else {
        "1 contact at a time"
    }
}

/// The whole quads of each of the first `colors` color ranges, counted from the color's
/// first row: the quads of its chunks, since a chunk holds whole quads.
fn quads_of(ranges: &[u32], colors: usize) -> impl Iterator<Item = usize> + '_ {
    ranges.windows(2).take(colors).flat_map(|w| {
        let (a, b) = (w[0] as usize, w[1] as usize);
        (a..a + (b - a) / 4 * 4).step_by(4)
    })
}

/// Packs the rows of the first `colors` color ranges four at a time ([`Quad`]) for the AVX
/// sweeps; [`unpack_quads`] undoes it.
pub(super) fn pack_quads(rows: &mut [Row], ranges: &[u32], colors: usize) {
    for k in quads_of(ranges, colors) {
        let r: [Row; 4] = rows[k..k + 4].try_into().expect("four rows");
        let q = Quad {
            i: r.map(|r| r.i),
            j: r.map(|r| r.j),
            nx: r.map(|r| r.nx),
            ny: r.map(|r| r.ny),
            inv_wnn: r.map(|r| r.inv_wnn),
            inv_wtt: r.map(|r| r.inv_wtt),
            mu: r.map(|r| r.mu),
            bias_n: r.map(|r| r.bias_n),
            bias_t: r.map(|r| r.bias_t),
            rn: r.map(|r| r.rn),
            rt: r.map(|r| r.rt),
        };
        // SAFETY: a Quad fills the bytes of four rows exactly and needs no more alignment
        // (asserted above); the four rows are in bounds.
        unsafe { rows.as_mut_ptr().add(k).cast::<Quad>().write(q) };
    }
}

/// Undoes [`pack_quads`] with the same ranges.
pub(super) fn unpack_quads(rows: &mut [Row], ranges: &[u32], colors: usize) {
    for k in quads_of(ranges, colors) {
        // SAFETY: as in `pack_quads`; these rows hold a packed quad.
        let q = unsafe { rows.as_ptr().add(k).cast::<Quad>().read() };
        for (l, r) in rows[k..k + 4].iter_mut().enumerate() {
            *r = Row {
                i: q.i[l],
                j: q.j[l],
                nx: q.nx[l],
                ny: q.ny[l],
                inv_wnn: q.inv_wnn[l],
                inv_wtt: q.inv_wtt[l],
                mu: q.mu[l],
                bias_n: q.bias_n[l],
                bias_t: q.bias_t[l],
                rn: q.rn[l],
                rt: q.rt[l],
            };
        }
    }
}

/// The vector forms of [`update`] for rows of one color. Each lane repeats the scalar
/// update's operations in its order: `_mm*_max_pd(x, y)` is `if x > y { x } else { y }`,
/// as [`larger`] (min likewise, with the same NaN and signed-zero rules), the sign flipped
/// by xor, and the sums added to the accumulator lane by lane in row order. No fused
/// multiply-add: it would round differently.
#[cfg(target_arch = "x86_64")]
mod simd {
    use super::{BodyProps, Ctx, FULL, Quad, Row, update};
    use glam::DVec3;
    use std::arch::x86_64::*;

    /// Writes body `p` (velocity `v` as read) after an update whose impulse on it has
    /// components (`px`, `py`) times `im`, the inverse mass signed for that body, and spin
    /// change `k drt`; a body that cannot move is never written.
    #[inline(always)]
    unsafe fn write(p: *mut DVec3, v: DVec3, body: BodyProps, im: f64, px: f64, py: f64, drt: f64) {
        if body.movable != 0.0 {
            // SAFETY: the caller owns `p` for this color.
            unsafe { p.write(v + DVec3::new(im * px, im * py, body.k * drt)) };
        }
    }

    /// Four rows at a time, packed as [`Quad`]s (a multiple of four rows), their sums added
    /// to `acc` in row order.
    ///
    /// # Safety
    /// As [`super::sweep_color_chunk`], on a processor with AVX, on packed rows.
    #[target_feature(enable = "avx")]
    pub(super) unsafe fn sweep_quads<const RELAXED: bool>(rows: &mut [Row], ctx: Ctx, acc: &mut (f64, f64)) {
        for quad in rows.chunks_exact_mut(4) {
            // SAFETY: the caller guarantees these rows hold a packed quad (see `Quad`).
            let q = unsafe { &mut *quad.as_mut_ptr().cast::<Quad>() };
            debug_assert!(q.j.iter().all(|&j| j != FULL));
            // SAFETY: the caller guarantees validity; the four rows write disjoint bodies
            // and read the shared ones (never written) only.
            unsafe {
                let pi = q.i.map(|i| ctx.gv.add(i as usize));
                let pj = q.j.map(|j| ctx.gv.add(j as usize));
                let bi = q.i.map(|i| *ctx.props.add(i as usize));
                let bj = q.j.map(|j| *ctx.props.add(j as usize));
                let vi = pi.map(|p| p.read());
                let vj = pj.map(|p| p.read());
                // Lane l is row l of the quad (`_mm256_set_pd` takes the high lane first).
                macro_rules! lanes4 {
                    ($x:expr) => {{
                        let x = $x;
                        _mm256_set_pd(x[3], x[2], x[1], x[0])
                    }};
                }
                macro_rules! field {
                    ($f:ident) => {
                        _mm256_loadu_pd(q.$f.as_ptr())
                    };
                }
                let (nx, ny) = (field!(nx), field!(ny));
                let dx = _mm256_sub_pd(lanes4!(vi.map(|v| v.x)), lanes4!(vj.map(|v| v.x)));
                let dy = _mm256_sub_pd(lanes4!(vi.map(|v| v.y)), lanes4!(vj.map(|v| v.y)));
                let un = _mm256_add_pd(_mm256_mul_pd(dx, nx), _mm256_mul_pd(dy, ny));
                let ut = _mm256_add_pd(
                    _mm256_add_pd(
                        _mm256_sub_pd(_mm256_mul_pd(dx, ny), _mm256_mul_pd(dy, nx)),
                        _mm256_mul_pd(lanes4!(vi.map(|v| v.z)), lanes4!(bi.map(|b| b.lever))),
                    ),
                    _mm256_mul_pd(lanes4!(vj.map(|v| v.z)), lanes4!(bj.map(|b| b.lever))),
                );
                let (rn0, rt0) = (field!(rn), field!(rt));
                let rn = _mm256_max_pd(
                    _mm256_sub_pd(
                        rn0,
                        _mm256_mul_pd(_mm256_add_pd(un, field!(bias_n)), field!(inv_wnn)),
                    ),
                    _mm256_setzero_pd(),
                );
                let lim = _mm256_mul_pd(field!(mu), rn);
                let neg_lim = _mm256_xor_pd(lim, _mm256_set1_pd(-0.0));
                let rt = _mm256_min_pd(
                    _mm256_max_pd(
                        _mm256_sub_pd(
                            rt0,
                            _mm256_mul_pd(_mm256_add_pd(ut, field!(bias_t)), field!(inv_wtt)),
                        ),
                        neg_lim,
                    ),
                    lim,
                );
                let (rn, rt) = if RELAXED && ctx.relax != 1.0 {
                    let w = _mm256_set1_pd(ctx.relax);
                    (
                        _mm256_add_pd(rn0, _mm256_mul_pd(w, _mm256_sub_pd(rn, rn0))),
                        _mm256_add_pd(rt0, _mm256_mul_pd(w, _mm256_sub_pd(rt, rt0))),
                    )
                } else {
                    (rn, rt)
                };
                let (drn, drt) = (_mm256_sub_pd(rn, rn0), _mm256_sub_pd(rt, rt0));
                _mm256_storeu_pd(q.rn.as_mut_ptr(), rn);
                _mm256_storeu_pd(q.rt.as_mut_ptr(), rt);
                let px = _mm256_add_pd(_mm256_mul_pd(drn, nx), _mm256_mul_pd(drt, ny));
                let py = _mm256_sub_pd(_mm256_mul_pd(drn, ny), _mm256_mul_pd(drt, nx));
                let sq = _mm256_add_pd(_mm256_mul_pd(drn, drn), _mm256_mul_pd(drt, drt));
                let r2 = _mm256_add_pd(_mm256_mul_pd(rn, rn), _mm256_mul_pd(rt, rt));
                let mut out = [[0.0; 4]; 5];
                for (o, v) in out.iter_mut().zip([px, py, drt, sq, r2]) {
                    _mm256_storeu_pd(o.as_mut_ptr(), v);
                }
                let [px, py, drt, sq, r2] = out;
                for l in 0..4 {
                    write(pi[l], vi[l], bi[l], bi[l].inv_mass, px[l], py[l], drt[l]);
                    write(pj[l], vj[l], bj[l], -bj[l].inv_mass, px[l], py[l], drt[l]);
                    acc.0 += sq[l];
                    acc.1 += r2[l];
                }
            }
        }
    }

    /// Two rows at a time, then the last one alone, their sums added to `acc` in row
    /// order.
    ///
    /// # Safety
    /// As [`super::sweep_color_chunk`].
    pub(super) unsafe fn sweep_pairs<const RELAXED: bool>(rows: &mut [Row], ctx: Ctx, acc: &mut (f64, f64)) {
        let mut pairs = rows.chunks_exact_mut(2);
        for pair in &mut pairs {
            let [a, b] = pair else { unreachable!() };
            debug_assert!(a.j != FULL && b.j != FULL);
            // SAFETY: the caller guarantees validity; the two rows write disjoint bodies and
            // read the shared ones (never written) only.
            unsafe {
                let (pia, pja) = (ctx.gv.add(a.i as usize), ctx.gv.add(a.j as usize));
                let (pib, pjb) = (ctx.gv.add(b.i as usize), ctx.gv.add(b.j as usize));
                let (bia, bja) = (*ctx.props.add(a.i as usize), *ctx.props.add(a.j as usize));
                let (bib, bjb) = (*ctx.props.add(b.i as usize), *ctx.props.add(b.j as usize));
                let (via, vja, vib, vjb) = (pia.read(), pja.read(), pib.read(), pjb.read());
                // Lane 0 is row a, lane 1 row b (`_mm_set_pd` takes the high lane first).
                let pair = |x: f64, y: f64| _mm_set_pd(y, x);
                let (add, sub, mul) = (_mm_add_pd, _mm_sub_pd, _mm_mul_pd);
                let dx = sub(pair(via.x, vib.x), pair(vja.x, vjb.x));
                let dy = sub(pair(via.y, vib.y), pair(vja.y, vjb.y));
                let (nx, ny) = (pair(a.nx, b.nx), pair(a.ny, b.ny));
                let un = add(mul(dx, nx), mul(dy, ny));
                let ut = add(
                    add(
                        sub(mul(dx, ny), mul(dy, nx)),
                        mul(pair(via.z, vib.z), pair(bia.lever, bib.lever)),
                    ),
                    mul(pair(vja.z, vjb.z), pair(bja.lever, bjb.lever)),
                );
                let (rn0, rt0) = (pair(a.rn, b.rn), pair(a.rt, b.rt));
                let rn = _mm_max_pd(
                    sub(
                        rn0,
                        mul(add(un, pair(a.bias_n, b.bias_n)), pair(a.inv_wnn, b.inv_wnn)),
                    ),
                    _mm_setzero_pd(),
                );
                let lim = mul(pair(a.mu, b.mu), rn);
                let neg_lim = _mm_xor_pd(lim, _mm_set1_pd(-0.0));
                let rt = _mm_min_pd(
                    _mm_max_pd(
                        sub(
                            rt0,
                            mul(add(ut, pair(a.bias_t, b.bias_t)), pair(a.inv_wtt, b.inv_wtt)),
                        ),
                        neg_lim,
                    ),
                    lim,
                );
                let (rn, rt) = if RELAXED && ctx.relax != 1.0 {
                    let w = _mm_set1_pd(ctx.relax);
                    (add(rn0, mul(w, sub(rn, rn0))), add(rt0, mul(w, sub(rt, rt0))))
                } else {
                    (rn, rt)
                };
                let (drn, drt) = (sub(rn, rn0), sub(rt, rt0));
                let px = add(mul(drn, nx), mul(drt, ny));
                let py = sub(mul(drn, ny), mul(drt, nx));
                let lanes = |v: __m128d| {
                    let mut out = [0.0; 2];
                    _mm_storeu_pd(out.as_mut_ptr(), v);
                    out
                };
                let (px, py, drt_l) = (lanes(px), lanes(py), lanes(drt));
                // Each body is read once: no other row of the pair writes it, so `v` is
                // what [`update`] reads back before writing j.
                write(pia, via, bia, bia.inv_mass, px[0], py[0], drt_l[0]);
                write(pja, vja, bja, -bja.inv_mass, px[0], py[0], drt_l[0]);
                write(pib, vib, bib, bib.inv_mass, px[1], py[1], drt_l[1]);
                write(pjb, vjb, bjb, -bjb.inv_mass, px[1], py[1], drt_l[1]);
                let (rn_l, rt_l) = (lanes(rn), lanes(rt));
                a.rn = rn_l[0];
                a.rt = rt_l[0];
                b.rn = rn_l[1];
                b.rt = rt_l[1];
                let d = lanes(add(mul(drn, drn), mul(drt, drt)));
                let q = lanes(add(mul(rn, rn), mul(rt, rt)));
                acc.0 += d[0];
                acc.1 += q[0];
                acc.0 += d[1];
                acc.1 += q[1];
            }
        }
        for r in pairs.into_remainder() {
            // SAFETY: forwarded from the caller.
            let (d, q) = unsafe { update::<RELAXED>(r, ctx) };
            acc.0 += d;
            acc.1 += q;
        }
    }
}

/// How many of the color `ranges` (`ranges[c]..ranges[c+1]`) from the first are colors
/// proper, whose rows share no movable body: all but the serial group, when there is one
/// (its rows share their force-driven wall).
pub(super) fn proper_colors(ranges: &[u32], serial_last: bool) -> usize {
    ranges
        .len()
        .saturating_sub(1)
        .saturating_sub(usize::from(serial_last))
}

/// One Gauss-Seidel sweep over `rows` in order, where consecutive `ranges` are colors
/// (a single range for plain order), on the calling thread. Returns the chunked sums
/// (change^2, impulse^2); [`super::team`] sweeps colors on several threads with the same
/// chunks and the same order of summation. `colors` ranges from the first are colors
/// proper (rows that share no movable body); the others are swept row by row.
fn sweep(rows: &mut [Row], ranges: &[u32], colors: usize, ctx: Ctx) -> (f64, f64) {
    let mut total = (0.0, 0.0);
    for (c, w) in ranges.windows(2).enumerate() {
        let part = &mut rows[w[0] as usize..w[1] as usize];
        for ch in part.chunks_mut(CHUNK) {
            // SAFETY: one thread; indices checked by `solve`; rows of a color share no
            // movable body.
            let (d, r) = if c < colors {
                unsafe { sweep_color_chunk(ch, ctx) }
            } else {
                unsafe { sweep_chunk(ch, ctx) }
            };
            total.0 += d;
            total.1 += r;
        }
    }
    total
}

/// Scratch buffers of the Gauss-Seidel sweeps, kept between steps so that a step
/// allocates nothing once sizes settle.
#[derive(Clone, Debug, Default)]
pub struct Workspace {
    rows: Vec<Row>,
    props: Vec<BodyProps>,
    sorted: Vec<Row>,
    coloring: Coloring,
    /// Contact index of each swept row when some rows are parked.
    active: Vec<u32>,
    /// Rows left out of the sweeps ([`SolverParams::open_skip`]).
    parked: Vec<Row>,
    /// The velocity test's copy of the last iterate.
    iterate: Vec<DVec3>,
}

impl Workspace {
    /// The coloring of the last colored solve (empty ranges after another method).
    pub fn coloring(&self) -> &Coloring {
        &self.coloring
    }
}

impl SolveStats {
    /// Records Gauss-Seidel iteration `it` with its sums (change^2, impulse^2) and tells
    /// whether the relative change, divided by the iteration's relaxation, met `tol`.
    fn record(&mut self, it: u32, d2: f64, r2: f64, params: &SolverParams) -> bool {
        let w = params.relax_at(it);
        self.record_change(it, d2 / (w * w), r2, params.tol)
    }

    /// Records iteration `it` with its sums (change^2, impulse^2) and tells whether the
    /// relative change met `tol`.
    fn record_change(&mut self, it: u32, d2: f64, r2: f64, tol: f64) -> bool {
        self.iterations = it;
        self.residual = relative_change(d2, r2);
        self.converged = self.residual <= tol;
        self.converged
    }
}

/// The velocity test of [`SolverParams::velocity_tol`]: keeps the iterate of the last
/// iteration and compares the next one with it.
struct VelocityTest<'a> {
    tol: f64,
    after: u32,
    prev: &'a mut Vec<DVec3>,
}

impl<'a> VelocityTest<'a> {
    /// `gv` is the iterate before the first iteration, the reference of the first test
    /// when the test applies from the first iteration; `prev` is the workspace's buffer.
    fn new(params: &SolverParams, gv: &[DVec3], prev: &'a mut Vec<DVec3>) -> Self {
        prev.clear();
        if params.velocity_tol > 0.0 && params.gs_relax_after == 0 {
            prev.extend_from_slice(gv);
        }
        VelocityTest {
            // The test applies to relaxed iterations only, whose changes are `gs_relax` of
            // the way to the local solutions: like the impulse test, it bounds the change
            // divided by the relaxation, so that `velocity_tol` means the same at any
            // relaxation.
            tol: params.velocity_tol * params.gs_relax,
            after: params.gs_relax_after,
            prev,
        }
    }

    /// Called after iteration `it` with the iterate `gv`: true when the test applies and no
    /// body's velocity changed by more than `velocity_tol x gs_relax` since the previous
    /// iteration. Bodies no contact can move keep their velocity, so every body may be
    /// compared.
    fn settled(&mut self, it: u32, gv: &[DVec3], props: &[BodyProps]) -> bool {
        if self.tol <= 0.0 || it < self.after {
            return false;
        }
        let settled = it > self.after
            && self.prev.len() == gv.len()
            && gv.iter().zip(self.prev.iter()).zip(props).all(|((v, p), b)| {
                let d = *v - *p;
                d.x * d.x + d.y * d.y + (b.lever * d.z).powi(2) <= self.tol * self.tol
            });
        self.prev.clear();
        self.prev.extend_from_slice(gv);
        settled
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

/// Solves the contact problem: plain Gauss-Seidel sweeps the contacts in their order,
/// colored Gauss-Seidel colors them first ([`color`]) and sweeps the colors in order, on a
/// thread team when the problem is large enough; Jacobi rebuilds the velocities from the
/// free velocities `gv0` every iteration.
pub fn solve(
    params: &SolverParams,
    contacts: &mut [Contact],
    gv0: &[DVec3],
    gv: &mut [DVec3],
    work: &mut Workspace,
) -> SolveStats {
    work.coloring.ranges.clear();
    work.coloring.order.clear();
    work.coloring.serial_last = false;
    if params.method == Method::Jacobi {
        return jacobi(params, contacts, gv0, gv);
    }
    let n_bodies = gv.len();
    rows(contacts, n_bodies, &mut work.rows, &mut work.props);
    let parking = params.open_skip > 0.0;
    if parking {
        park(
            &mut work.rows,
            gv,
            params.open_skip,
            &mut work.active,
            &mut work.parked,
        );
    }
    let whole = [0, work.rows.len() as u32];
    let colored = params.method == Method::ColoredGs;
    if colored {
        let props = &work.props;
        let nodes = work.rows.iter().map(|r| {
            let serial = r.j == FULL;
            Node {
                i: r.i,
                j: r.j,
                moves_i: !serial && props[r.i as usize].movable != 0.0,
                moves_j: !serial && props[r.j as usize].movable != 0.0,
                serial,
            }
        });
        color(nodes, n_bodies, &mut work.coloring);
        work.sorted.clear();
        work.sorted
            .extend(work.coloring.order.iter().map(|&k| work.rows[k as usize]));
    }
    let proper_colors = if colored {
        proper_colors(&work.coloring.ranges, work.coloring.serial_last)
    } else {
        0
    };
    let (rows, ranges, serial_last) = if colored {
        let c = &work.coloring;
        (&mut work.sorted, &c.ranges[..], c.serial_last)
    } else {
        (&mut work.rows, &whole[..], false)
    };
    let quads = colored && avx();
    if quads {
        pack_quads(rows, ranges, proper_colors);
    }
    let ctx = Ctx {
        gv: gv.as_mut_ptr(),
        props: work.props.as_ptr(),
        contacts: contacts.as_mut_ptr(),
        relax: 1.0,
        quads,
    };
    let mut stats = SolveStats {
        colors: if colored { (ranges.len() - 1) as u32 } else { 0 },
        ..Default::default()
    };
    let team = params.team_size();
    // SAFETY: no sweep runs yet.
    let start = unsafe { std::slice::from_raw_parts(ctx.gv, n_bodies) };
    let mut velocity = VelocityTest::new(params, start, &mut work.iterate);
    let props = &work.props[..];
    let mut done = |it: u32, d2: f64, r2: f64| {
        if stats.record(it, d2, r2, params) {
            return true;
        }
        // SAFETY: called between sweeps, when no thread writes the velocities.
        let gv = unsafe { std::slice::from_raw_parts(ctx.gv, n_bodies) };
        stats.converged = velocity.settled(it, gv, props);
        stats.converged
    };
    if colored && team > 1 && contacts.len() >= params.parallel_min {
        super::team::sweep_iterations(rows, ranges, serial_last, ctx, team, params, done);
    } else {
        for it in 1..=params.max_iter {
            let ctx = Ctx {
                relax: params.relax_at(it),
                ..ctx
            };
            let (d2, r2) = sweep(rows, ranges, proper_colors, ctx);
            if done(it, d2, r2) {
                break;
            }
        }
    }
    if quads {
        unpack_quads(rows, ranges, proper_colors);
    }
    let order = colored.then_some(&work.coloring.order[..]);
    let active = parking.then_some(&work.active[..]);
    if params.deep_updates() {
        let deep: Vec<usize> = (0..rows.len())
            .filter(|&m| {
                let r = &rows[m];
                r.j != FULL && r.rn > 0.0 && contacts[contact_of(m, order, active)].gap < -params.deep_gap
            })
            .collect();
        stats.deep = deep.len() as u32;
        let ctx = Ctx { relax: 1.0, ..ctx };
        for _ in 0..params.deep_sweeps {
            for &m in &deep {
                // SAFETY: no other sweep runs; the row's bodies are in range (checked in rows()).
                unsafe {
                    update::<false>(&mut rows[m], ctx);
                }
            }
        }
    }
    store(rows, order, active, contacts);
    if parking && work.parked.iter().any(|r| opening(r, gv) < 0.0) {
        // A parked contact would close: solve again with every contact, from the
        // impulses and velocities reached, so that none is missed.
        let every = SolverParams {
            open_skip: 0.0,
            ..*params
        };
        let again = solve(&every, contacts, gv0, gv, work);
        return SolveStats {
            iterations: stats.iterations + again.iterations,
            unparked: true,
            ..again
        };
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
        if stats.record_change(it, d2, r2, params.tol) {
            break;
        }
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A small xorshift generator: the test's data need no statistical quality, only
    /// variety and reproducibility.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 << 13;
            self.0 ^= self.0 >> 7;
            self.0 ^= self.0 << 17;
            (self.0 >> 11) as f64 / (1u64 << 53) as f64
        }
        fn signed(&mut self) -> f64 {
            2.0 * self.next() - 1.0
        }
    }

    /// One color of `n` rows on `2n` movable disks and 3 fixed walls shared by some rows,
    /// with impulses that are zero, inside the Coulomb interval or on its edge, and
    /// relative velocities that open, close or slide the contacts.
    fn color_of(n: usize, seed: u64) -> (Vec<Row>, Vec<DVec3>, Vec<BodyProps>) {
        let mut rng = Rng(seed);
        let bodies = 2 * n + 3;
        let gv: Vec<DVec3> = (0..bodies)
            .map(|_| DVec3::new(rng.signed(), rng.signed(), 3.0 * rng.signed()))
            .collect();
        let props: Vec<BodyProps> = (0..bodies)
            .map(|b| BodyProps {
                inv_mass: 0.5 + rng.next(),
                k: 2.0 * rng.next(),
                lever: 0.1 + rng.next(),
                movable: if b < 2 * n { 1.0 } else { 0.0 },
            })
            .collect();
        let rows = (0..n)
            .map(|m| {
                let a = rng.next() * std::f64::consts::TAU;
                let mu = [0.0, 0.01, 0.3, 12.0][m % 4];
                let rn = if m % 3 == 0 { 0.0 } else { rng.next() };
                let rt = match m % 5 {
                    0 => mu * rn,
                    1 => -mu * rn,
                    _ => mu * rn * rng.signed(),
                };
                Row {
                    i: (2 * m) as u32,
                    // Every seventh row touches a wall, shared with other rows.
                    j: if m % 7 == 0 {
                        (2 * n + m % 3) as u32
                    } else {
                        (2 * m + 1) as u32
                    },
                    nx: a.cos(),
                    ny: a.sin(),
                    inv_wnn: 0.2 + rng.next(),
                    inv_wtt: if m % 11 == 0 { 0.0 } else { 0.3 + rng.next() },
                    mu,
                    bias_n: 0.5 * rng.signed(),
                    bias_t: 0.1 * rng.signed(),
                    rn,
                    rt,
                }
            })
            .collect();
        (rows, gv, props)
    }

    /// How a color is swept: one row at a time, with the vector lanes on unpacked rows
    /// (pairs), or on rows packed four at a time.
    #[derive(Clone, Copy, Debug, PartialEq)]
    enum Width {
        Rows,
        Pairs,
        Quads,
    }

    /// The sums, velocities and impulses after three sweeps over the color, chunk by chunk
    /// as [`sweep`] goes.
    fn three_sweeps(n: usize, seed: u64, relax: f64, width: Width) -> Vec<u64> {
        let (mut rows, mut gv, props) = color_of(n, seed);
        let ranges = [0, n as u32];
        let quads = width == Width::Quads;
        if quads {
            pack_quads(&mut rows, &ranges, 1);
        }
        let ctx = Ctx {
            gv: gv.as_mut_ptr(),
            props: props.as_ptr(),
            contacts: std::ptr::null_mut(),
            relax,
            quads,
        };
        let mut bits = Vec::new();
        for _ in 0..3 {
            let (mut d, mut q) = (0.0, 0.0);
            for chunk in rows.chunks_mut(CHUNK) {
                // SAFETY: one thread; the rows of `color_of` share no movable body and
                // index bodies within `gv` and `props`; packed as `ctx.quads` says, on a
                // processor with AVX for the quads (checked by the caller).
                let (dc, qc) = unsafe {
                    match width {
                        Width::Rows => sweep_chunk(chunk, ctx),
                        _ => sweep_color_chunk(chunk, ctx),
                    }
                };
                d += dc;
                q += qc;
            }
            bits.extend([d.to_bits(), q.to_bits()]);
        }
        if quads {
            unpack_quads(&mut rows, &ranges, 1);
        }
        bits.extend(gv.iter().flat_map(|v| v.to_array()).map(f64::to_bits));
        bits.extend(rows.iter().flat_map(|r| [r.rn.to_bits(), r.rt.to_bits()]));
        bits
    }

    /// The vector sweeps of a color give the scalar update's result bit for bit (the CPU
    /// path's determinism across machines rests on it: a processor without AVX sweeps in
    /// pairs), for every remainder of four and two, relaxed or not; packing and unpacking
    /// the quads gives the rows back as they were.
    #[test]
    fn vector_sweeps_equal_the_scalar_update_bit_for_bit() {
        let mut widths = vec![Width::Pairs];
        if avx() {
            widths.push(Width::Quads);
        } else {
            // Past the test harness's capture (eprintln! shows only on failure), so that a
            // plain `cargo test` says which comparison did not run.
            let _ = std::io::Write::write_all(
                &mut std::io::stderr(),
                b"NOTE: no AVX here (or CDLAB_NO_AVX=1): packed quads not compared\n",
            );
        }
        for n in [1, 2, 3, 4, 5, 6, 7, 64, 67, 130] {
            for relax in [1.0, 0.5] {
                let seed = 7 + n as u64;
                let reference = three_sweeps(n, seed, relax, Width::Rows);
                assert!(reference.iter().any(|&b| b != 0), "{n} rows did nothing");
                for &w in &widths {
                    let other = three_sweeps(n, seed, relax, w);
                    let first = reference.iter().zip(&other).position(|(a, b)| a != b);
                    assert_eq!(
                        first, None,
                        "{w:?}, {n} rows, relax {relax}: first differing value"
                    );
                }
            }
        }
        let (rows, _, _) = color_of(67, 1);
        let mut packed = rows.clone();
        pack_quads(&mut packed, &[0, 67], 1);
        assert_ne!(
            format!("{packed:?}"),
            format!("{rows:?}"),
            "packing moved nothing"
        );
        unpack_quads(&mut packed, &[0, 67], 1);
        assert_eq!(format!("{packed:?}"), format!("{rows:?}"));
    }
}
