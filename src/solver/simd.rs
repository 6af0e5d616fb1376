//! The vector forms of the diagonal update ([`super::update::update`]) for the rows of one
//! color, on x86_64. Each lane repeats the scalar update's operations in its order:
//! `_mm*_max_pd(x, y)` is `if x > y { x } else { y }`, as the scalar update's comparisons
//! (min likewise, with the same NaN and signed-zero rules), the sign flipped by xor, and
//! the sums added to the accumulator lane by lane in row order. No fused multiply-add: it
//! would round differently. The bit-for-bit test is in [`super::lanes`].

use glam::DVec3;
use std::arch::x86_64::*;

use super::ctx::{Ctx, Line};
use super::quads::Quad;
use super::rows::{BodyProps, FULL, Row};
use super::update::update;

/// Writes body `p` (velocity `v` as read) after an update whose impulse on it has
/// components (`px`, `py`) times `im`, the inverse mass signed for that body, and spin
/// change `k drt`; a body that cannot move is never written.
#[inline(always)]
unsafe fn write(p: *mut Line, v: DVec3, body: BodyProps, im: f64, px: f64, py: f64, drt: f64) {
    if body.movable() {
        // SAFETY: the caller owns `p` for this color.
        unsafe { (*p).v = v + DVec3::new(im * px, im * py, body.k * drt) };
    }
}

/// The diagonal law on vectors of rows, lane by lane the scalar update's operations in its
/// order: from the velocities of bodies i and j (x, y, spin), their levers and the rows'
/// fields, the new impulses, the tangential change, the impulse's x and y components and
/// the two sums (`(rn, rt, drt, px, py, sq, r2)`). The first argument names the width (128,
/// 256 or 512 bits of `f64`, or `512f32`: its add, sub, mul, max, min and broadcast); `$neg` flips the sign of
/// every lane; `$relax` is `Some(omega)` for a relaxed update.
macro_rules! law {
    // Packed rows: the nine fields from the caller's `field!`, which loads one of them for
    // every lane.
    ($width:tt packed; $neg:expr, $zero:expr, $relax:expr, $vi:tt, $vj:tt, $levers:tt $(,)?) => {
        law!($width; $neg, $zero, $relax, $vi, $vj, $levers, [
            field!(nx), field!(ny), field!(rn), field!(rt), field!(bias_n), field!(inv_wnn),
            field!(mu), field!(bias_t), field!(inv_wtt)
        ])
    };
    // Rows without friction and without tangential impulse (`Ctx::frictionless`): the
    // scalar law gives them `R_t` = +0 whatever `U_t` is (the interval [-0 x R_n, 0 x R_n]
    // clamps every trial to +0, relaxed or not), so `dR_t` is +0 and only the normal part
    // is computed; `x + dR_t y` keeps its product with the +0 so that a zero keeps the sign
    // the full law gives it, and the sums drop `dR_t^2` and `R_t^2`, which add +0 to a
    // square. It gives `(rn, drt, px, py, sq, r2)`, `drt` the +0: the rows keep their +0
    // `R_t`, so nothing is stored for it.
    ($width:tt packed normal; $zero:expr, $relax:expr, ($vix:expr, $viy:expr), ($vjx:expr, $vjy:expr) $(,)?) => {
        law!($width normal; $zero, $relax, ($vix, $viy), ($vjx, $vjy), [
            field!(nx), field!(ny), field!(rn), field!(bias_n), field!(inv_wnn)
        ])
    };
    (
        [$add:path, $sub:path, $mul:path, $max:path, $min:path, $set1:path] normal,
        $zero:expr, $relax:expr, ($vix:expr, $viy:expr), ($vjx:expr, $vjy:expr),
        [$nx:expr, $ny:expr, $rn0:expr, $bias_n:expr, $inv_wnn:expr]
    ) => {{
        let (nx, ny, rn0, zero) = ($nx, $ny, $rn0, $zero);
        let dx = $sub($vix, $vjx);
        let dy = $sub($viy, $vjy);
        let un = $add($mul(dx, nx), $mul(dy, ny));
        let rn = $max($sub(rn0, $mul($add(un, $bias_n), $inv_wnn)), zero);
        let rn = match $relax {
            Some(omega) => $add(rn0, $mul($set1(omega), $sub(rn, rn0))),
            None => rn,
        };
        let drn = $sub(rn, rn0);
        let px = $add($mul(drn, nx), $mul(zero, ny));
        let py = $sub($mul(drn, ny), $mul(zero, nx));
        (rn, zero, px, py, $mul(drn, drn), $mul(rn, rn))
    }};
    // Each width's operations, for either form (none, or `normal`).
    (128 $($form:ident)?; $($rest:tt)*) => {
        law!([_mm_add_pd, _mm_sub_pd, _mm_mul_pd, _mm_max_pd, _mm_min_pd, _mm_set1_pd] $($form)?, $($rest)*)
    };
    (256 $($form:ident)?; $($rest:tt)*) => {
        law!([_mm256_add_pd, _mm256_sub_pd, _mm256_mul_pd, _mm256_max_pd, _mm256_min_pd, _mm256_set1_pd] $($form)?, $($rest)*)
    };
    (512 $($form:ident)?; $($rest:tt)*) => {
        law!([_mm512_add_pd, _mm512_sub_pd, _mm512_mul_pd, _mm512_max_pd, _mm512_min_pd, _mm512_set1_pd] $($form)?, $($rest)*)
    };
    // Sixteen f32 lanes ([`super::single`]; its relaxation an `f32`).
    (512f32 $($form:ident)?; $($rest:tt)*) => {
        law!([_mm512_add_ps, _mm512_sub_ps, _mm512_mul_ps, _mm512_max_ps, _mm512_min_ps, _mm512_set1_ps] $($form)?, $($rest)*)
    };
    (
        [$add:path, $sub:path, $mul:path, $max:path, $min:path, $set1:path],
        $neg:expr, $zero:expr, $relax:expr,
        ($vix:expr, $viy:expr, $viz:expr), ($vjx:expr, $vjy:expr, $vjz:expr), ($lever_i:expr, $lever_j:expr),
        [$nx:expr, $ny:expr, $rn0:expr, $rt0:expr, $bias_n:expr, $inv_wnn:expr, $mu:expr, $bias_t:expr, $inv_wtt:expr]
    ) => {{
        let (nx, ny, rn0, rt0) = ($nx, $ny, $rn0, $rt0);
        let dx = $sub($vix, $vjx);
        let dy = $sub($viy, $vjy);
        let un = $add($mul(dx, nx), $mul(dy, ny));
        let ut = $add(
            $add($sub($mul(dx, ny), $mul(dy, nx)), $mul($viz, $lever_i)),
            $mul($vjz, $lever_j),
        );
        let rn = $max($sub(rn0, $mul($add(un, $bias_n), $inv_wnn)), $zero);
        let lim = $mul($mu, rn);
        let rt = $min($max($sub(rt0, $mul($add(ut, $bias_t), $inv_wtt)), $neg(lim)), lim);
        let (rn, rt) = match $relax {
            Some(omega) => {
                let w = $set1(omega);
                (
                    $add(rn0, $mul(w, $sub(rn, rn0))),
                    $add(rt0, $mul(w, $sub(rt, rt0))),
                )
            }
            None => (rn, rt),
        };
        let (drn, drt) = ($sub(rn, rn0), $sub(rt, rt0));
        let px = $add($mul(drn, nx), $mul(drt, ny));
        let py = $sub($mul(drn, ny), $mul(drt, nx));
        let sq = $add($mul(drn, drn), $mul(drt, drt));
        let r2 = $add($mul(rn, rn), $mul(rt, rt));
        (rn, rt, drt, px, py, sq, r2)
    }};
}
// The f32 sweeps run the same law in other lanes.
pub(super) use law;

/// The 4x4 transpose of four registers: lane `l` of output `f` is lane `f` of input `l`
/// (four bodies' lines become their x, y, spin and fourth fields, and back).
macro_rules! transpose {
    ($r:expr) => {{
        let r = $r;
        let t0 = _mm256_unpacklo_pd(r[0], r[1]);
        let t1 = _mm256_unpackhi_pd(r[0], r[1]);
        let t2 = _mm256_unpacklo_pd(r[2], r[3]);
        let t3 = _mm256_unpackhi_pd(r[2], r[3]);
        [
            _mm256_permute2f128_pd::<0x20>(t0, t2),
            _mm256_permute2f128_pd::<0x20>(t1, t3),
            _mm256_permute2f128_pd::<0x31>(t0, t2),
            _mm256_permute2f128_pd::<0x31>(t1, t3),
        ]
    }};
}

/// Four rows at a time, packed as [`Quad`]s (a multiple of four rows), their sums added
/// to `acc` in row order. Each body's velocity [`Line`] and table entry are one aligned
/// load each, turned into lanes by a transpose; each body written gets its whole change
/// in one multiply, one add and one store, the products and sums those of the scalar
/// update.
///
/// # Safety
/// As [`super::lanes::sweep_color_chunk`], on a processor with AVX, on packed rows.
#[target_feature(enable = "avx")]
pub(super) unsafe fn sweep_quads<const RELAXED: bool, const FRICTION: bool>(
    rows: &mut [Row],
    ctx: Ctx,
    acc: &mut (f64, f64),
) {
    let zero = _mm256_setzero_pd();
    // Flips the sign of the x and y factors: body j takes the impulse with the other sign
    // (`_mm256_set_pd` takes the high lane first).
    let j_sign = _mm256_set_pd(0.0, 0.0, -0.0, -0.0);
    for quad in rows.chunks_exact_mut(4) {
        // SAFETY: the caller guarantees these rows hold a packed quad (see `Quad`).
        let q = unsafe { &mut *quad.as_mut_ptr().cast::<Quad>() };
        debug_assert!(q.j.iter().all(|&j| j != FULL));
        // SAFETY: the caller guarantees validity; the four rows write disjoint bodies
        // and read the shared ones (never written) only. Lines and table entries are
        // 32-byte aligned (`Line`, `BodyProps`).
        unsafe {
            let pi = q.i.map(|i| ctx.gv.add(i as usize).cast::<f64>());
            let pj = q.j.map(|j| ctx.gv.add(j as usize).cast::<f64>());
            let bi =
                q.i.map(|i| _mm256_load_pd(ctx.props.add(i as usize).cast::<f64>()));
            let bj =
                q.j.map(|j| _mm256_load_pd(ctx.props.add(j as usize).cast::<f64>()));
            let vi = pi.map(|p| _mm256_load_pd(p));
            let vj = pj.map(|p| _mm256_load_pd(p));
            let [vix, viy, viz, _] = transpose!(vi);
            let [vjx, vjy, vjz, _] = transpose!(vj);
            macro_rules! field {
                ($f:ident) => {
                    _mm256_loadu_pd(q.$f.as_ptr())
                };
            }
            let relax = (RELAXED && ctx.relax != 1.0).then_some(ctx.relax);
            let (rn, drt, px, py, sq, r2) = if FRICTION {
                let [_, _, _, lever_i] = transpose!(bi);
                let [_, _, _, lever_j] = transpose!(bj);
                let neg = |x: __m256d| _mm256_xor_pd(x, _mm256_set1_pd(-0.0));
                let (rn, rt, drt, px, py, sq, r2) = law!(256 packed;
                    neg,
                    zero,
                    relax,
                    (vix, viy, viz),
                    (vjx, vjy, vjz),
                    (lever_i, lever_j),
                );
                _mm256_storeu_pd(q.rt.as_mut_ptr(), rt);
                (rn, drt, px, py, sq, r2)
            } else {
                law!(256 packed normal; zero, relax, (vix, viy), (vjx, vjy))
            };
            _mm256_storeu_pd(q.rn.as_mut_ptr(), rn);
            // Row l's impulse as (p_x, p_y, dR_t, 0): times a body's table entry
            // (1/m, 1/m, r/I, lever) it is the scalar update's change, and 0 for the padding.
            let change = transpose!([px, py, drt, zero]);
            for l in 0..4 {
                // Lanes 0 and 2 of a table entry: inverse mass and r / I (`movable`).
                let moves =
                    |b: __m256d| _mm256_movemask_pd(_mm256_cmp_pd::<_CMP_NEQ_UQ>(b, zero)) & 0b101 != 0;
                if moves(bi[l]) {
                    _mm256_store_pd(pi[l], _mm256_add_pd(vi[l], _mm256_mul_pd(bi[l], change[l])));
                }
                if moves(bj[l]) {
                    let m = _mm256_xor_pd(bj[l], j_sign);
                    _mm256_store_pd(pj[l], _mm256_add_pd(vj[l], _mm256_mul_pd(m, change[l])));
                }
            }
            let mut out = [[0.0; 4]; 2];
            for (o, v) in out.iter_mut().zip([sq, r2]) {
                _mm256_storeu_pd(o.as_mut_ptr(), v);
            }
            for (d, r) in out[0].iter().zip(&out[1]) {
                acc.0 += d;
                acc.1 += r;
            }
        }
    }
}

/// The 4x4 transposes of the two 256-bit halves of four 512-bit registers at once: lane
/// `l` of output `f` is lane `f` of input `l` within each half (eight bodies' lines, four
/// in each half, become their x, y, spin and fourth fields in row order, and back).
macro_rules! transpose512 {
    ($r:expr) => {{
        let r = $r;
        let t0 = _mm512_unpacklo_pd(r[0], r[1]);
        let t1 = _mm512_unpackhi_pd(r[0], r[1]);
        let t2 = _mm512_unpacklo_pd(r[2], r[3]);
        let t3 = _mm512_unpackhi_pd(r[2], r[3]);
        // Elements 0-7 from the first operand, 8-15 from the second.
        let even = _mm512_set_epi64(13, 12, 5, 4, 9, 8, 1, 0);
        let odd = _mm512_set_epi64(15, 14, 7, 6, 11, 10, 3, 2);
        [
            _mm512_permutex2var_pd(t0, even, t2),
            _mm512_permutex2var_pd(t1, even, t3),
            _mm512_permutex2var_pd(t0, odd, t2),
            _mm512_permutex2var_pd(t1, odd, t3),
        ]
    }};
}

/// Eight rows at a time: two consecutive packed [`Quad`]s in 512-bit registers, the first
/// quad's rows in the lower halves, their sums added to `acc` in row order. As in
/// [`sweep_quads`], each body's line and table entry are one aligned load each, turned into
/// lanes by a transpose, and each body written gets its whole change in one multiply, one
/// add and one store, the products and sums of the scalar update, so the result is
/// [`sweep_quads`]'s bit for bit. The two quads read before either writes, which the color
/// allows: its rows share no movable body, and the bodies they share are never written.
///
/// # Safety
/// As [`sweep_quads`], on a processor with AVX-512F, on a multiple of eight packed rows.
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn sweep_octs<const RELAXED: bool, const FRICTION: bool>(
    rows: &mut [Row],
    ctx: Ctx,
    acc: &mut (f64, f64),
) {
    let zero = _mm512_setzero_pd();
    let sign = _mm512_set1_epi64(i64::MIN);
    // Flips the sign of the x and y factors: body j takes the impulse with the other sign.
    let j_sign = _mm512_set_epi64(0, 0, i64::MIN, i64::MIN, 0, 0, i64::MIN, i64::MIN);
    let xor = |x: __m512d, s: __m512i| _mm512_castsi512_pd(_mm512_xor_si512(_mm512_castpd_si512(x), s));
    for oct in rows.chunks_exact_mut(8) {
        let (a, b) = oct.split_at_mut(4);
        // SAFETY: the caller guarantees these rows hold two packed quads (see `Quad`).
        let (qa, qb) = unsafe {
            (
                &mut *a.as_mut_ptr().cast::<Quad>(),
                &mut *b.as_mut_ptr().cast::<Quad>(),
            )
        };
        debug_assert!(qa.j.iter().chain(&qb.j).all(|&j| j != FULL));
        // SAFETY: the caller guarantees validity; the eight rows write disjoint bodies
        // and read the shared ones (never written) only. Lines and table entries are
        // 32-byte aligned (`Line`, `BodyProps`).
        unsafe {
            macro_rules! field {
                ($f:ident) => {
                    _mm512_insertf64x4::<1>(
                        _mm512_castpd256_pd512(_mm256_loadu_pd(qa.$f.as_ptr())),
                        _mm256_loadu_pd(qb.$f.as_ptr()),
                    )
                };
            }
            macro_rules! store {
                ($f:ident, $v:expr) => {{
                    let v = $v;
                    _mm256_storeu_pd(qa.$f.as_mut_ptr(), _mm512_castpd512_pd256(v));
                    _mm256_storeu_pd(qb.$f.as_mut_ptr(), _mm512_extractf64x4_pd::<1>(v));
                }};
            }
            // Row l of each quad: its body's 4 f64 from `base`, the first quad's below.
            macro_rules! pair {
                ($base:expr, $side:ident, $l:expr) => {
                    _mm512_insertf64x4::<1>(
                        _mm512_castpd256_pd512(_mm256_load_pd($base.add(qa.$side[$l] as usize).cast())),
                        _mm256_load_pd($base.add(qb.$side[$l] as usize).cast()),
                    )
                };
            }
            let vi: [__m512d; 4] = std::array::from_fn(|l| pair!(ctx.gv, i, l));
            let vj: [__m512d; 4] = std::array::from_fn(|l| pair!(ctx.gv, j, l));
            let bi: [__m512d; 4] = std::array::from_fn(|l| pair!(ctx.props, i, l));
            let bj: [__m512d; 4] = std::array::from_fn(|l| pair!(ctx.props, j, l));
            let [vix, viy, viz, _] = transpose512!(vi);
            let [vjx, vjy, vjz, _] = transpose512!(vj);
            let relax = (RELAXED && ctx.relax != 1.0).then_some(ctx.relax);
            let (rn, drt, px, py, sq, r2) = if FRICTION {
                let [_, _, _, lever_i] = transpose512!(bi);
                let [_, _, _, lever_j] = transpose512!(bj);
                let (rn, rt, drt, px, py, sq, r2) = law!(512 packed;
                    |x| xor(x, sign),
                    zero,
                    relax,
                    (vix, viy, viz),
                    (vjx, vjy, vjz),
                    (lever_i, lever_j),
                );
                store!(rt, rt);
                (rn, drt, px, py, sq, r2)
            } else {
                law!(512 packed normal; zero, relax, (vix, viy), (vjx, vjy))
            };
            store!(rn, rn);
            // Row l's impulse as (p_x, p_y, dR_t, 0), in each half: times a body's table
            // entry (1/m, 1/m, r/I, lever) it is the scalar update's change.
            let change = transpose512!([px, py, drt, zero]);
            macro_rules! put {
                ($side:ident, $l:expr, $factor:expr, $v:expr, $b:expr) => {{
                    let new = _mm512_add_pd($v, _mm512_mul_pd($factor, change[$l]));
                    // Lanes 0 and 2 of each half's table entry: inverse mass and r / I.
                    let moves = _mm512_cmp_pd_mask::<_CMP_NEQ_UQ>($b, zero);
                    if moves & 0b0000_0101 != 0 {
                        _mm256_store_pd(
                            ctx.gv.add(qa.$side[$l] as usize).cast(),
                            _mm512_castpd512_pd256(new),
                        );
                    }
                    if moves & 0b0101_0000 != 0 {
                        _mm256_store_pd(
                            ctx.gv.add(qb.$side[$l] as usize).cast(),
                            _mm512_extractf64x4_pd::<1>(new),
                        );
                    }
                }};
            }
            for l in 0..4 {
                put!(i, l, bi[l], vi[l], bi[l]);
                put!(j, l, xor(bj[l], j_sign), vj[l], bj[l]);
            }
            let mut out = [[0.0; 8]; 2];
            for (o, v) in out.iter_mut().zip([sq, r2]) {
                _mm512_storeu_pd(o.as_mut_ptr(), v);
            }
            for (d, r) in out[0].iter().zip(&out[1]) {
                acc.0 += d;
                acc.1 += r;
            }
        }
    }
}

/// Two rows at a time, then the last one alone, their sums added to `acc` in row
/// order.
///
/// # Safety
/// As [`super::lanes::sweep_color_chunk`].
#[inline] // Its only caller is in another module: keep it in the color sweep's loop.
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
            let (via, vja, vib, vjb) = ((*pia).v, (*pja).v, (*pib).v, (*pjb).v);
            // Lane 0 is row a, lane 1 row b (`_mm_set_pd` takes the high lane first).
            let pair = |x: f64, y: f64| _mm_set_pd(y, x);
            let relax = (RELAXED && ctx.relax != 1.0).then_some(ctx.relax);
            let neg = |x: __m128d| _mm_xor_pd(x, _mm_set1_pd(-0.0));
            let (rn, rt, drt, px, py, sq, r2) = law!(128;
                neg,
                _mm_setzero_pd(),
                relax,
                (pair(via.x, vib.x), pair(via.y, vib.y), pair(via.z, vib.z)),
                (pair(vja.x, vjb.x), pair(vja.y, vjb.y), pair(vja.z, vjb.z)),
                (pair(bia.lever, bib.lever), pair(bja.lever, bjb.lever)),
                [
                    pair(a.nx, b.nx),
                    pair(a.ny, b.ny),
                    pair(a.rn, b.rn),
                    pair(a.rt, b.rt),
                    pair(a.bias_n, b.bias_n),
                    pair(a.inv_wnn, b.inv_wnn),
                    pair(a.mu, b.mu),
                    pair(a.bias_t, b.bias_t),
                    pair(a.inv_wtt, b.inv_wtt)
                ]
            );
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
            let (d, q) = (lanes(sq), lanes(r2));
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
