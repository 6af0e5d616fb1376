//! Colored sweeps in single precision, sixteen rows at a time in 512-bit registers: a
//! measured experiment, off unless `CDLAB_SWEEPS_F32=1` on a processor with AVX-512F
//! (docs/benchmarks.md, "Single precision in the sweeps").
//!
//! The rows of each color proper are copied into [`Group`]s of sixteen, field by field in
//! `f32`, with the figures of both bodies (inverse mass, `r / I`, lever) in the group, so
//! that an update reads no body table; the last group of a color is filled with lanes that
//! touch nothing. The sweeps work on an `f32` copy of the velocities ([`Line32`]); after
//! them each body's `f64` velocity receives the change of its `f32` copy, so a body that no
//! update moved keeps its velocity exactly, and each row its new impulses.
//!
//! The solve falls back to the `f64` sweeps for a problem with a serial group (contacts of
//! a force-driven wall), and the deep contacts' updates and the store stay in `f64`.

#[cfg(target_arch = "x86_64")]
use std::arch::x86_64::*;

#[cfg(target_arch = "x86_64")]
use super::simd::law;

use super::ctx::Line;
use super::rows::{BodyProps, FULL, Row};
use super::update::CHUNK;

/// Rows per [`Group`].
pub(super) const LANES: usize = 16;

/// Groups per chunk of the sweeps: a chunk holds the same [`CHUNK`] rows as the `f64`
/// sweeps', so a color splits between the members of a team as it does there.
pub(super) const GROUP_CHUNK: usize = CHUNK / LANES;

const _: () = assert!(CHUNK.is_multiple_of(LANES));

/// Whether the colored sweeps of this process run in `f32` ([`self`]): asked with
/// `CDLAB_SWEEPS_F32=1`, on a processor with AVX-512F (checked once).
pub(super) fn enabled() -> bool {
    use std::sync::OnceLock;
    static ON: OnceLock<bool> = OnceLock::new();
    *ON.get_or_init(|| {
        #[cfg(target_arch = "x86_64")]
        let avx512 = std::arch::is_x86_feature_detected!("avx512f");
        #[cfg(not(target_arch = "x86_64"))]
        let avx512 = false;
        avx512 && std::env::var_os("CDLAB_SWEEPS_F32").is_some_and(|v| v == "1")
    })
}

/// A body's velocity `(v_x, v_y, omega)` in `f32`, padded to 16 bytes (one 128-bit load),
/// the padding zero.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(16))]
pub(super) struct Line32(pub(super) [f32; 4]);

impl Line32 {
    /// The line of `l`'s velocity rounded to `f32`.
    pub(super) fn of(l: &Line) -> Self {
        Line32([l.v.x as f32, l.v.y as f32, l.v.z as f32, 0.0])
    }

    /// This line's velocity in `f64`, exactly.
    pub(super) fn wide(&self) -> Line {
        let [x, y, z, _] = self.0.map(f64::from);
        Line::of(glam::DVec3::new(x, y, z))
    }
}

/// Sixteen rows of one color field by field in `f32`, with their bodies' figures: inverse
/// mass, `r / I` and lever of body i and of body j (0 for a body that cannot move, as in
/// [`BodyProps`]).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
pub(super) struct Group {
    pub(super) i: [u32; LANES],
    pub(super) j: [u32; LANES],
    pub(super) im_i: [f32; LANES],
    pub(super) k_i: [f32; LANES],
    pub(super) l_i: [f32; LANES],
    pub(super) im_j: [f32; LANES],
    pub(super) k_j: [f32; LANES],
    pub(super) l_j: [f32; LANES],
    pub(super) nx: [f32; LANES],
    pub(super) ny: [f32; LANES],
    pub(super) inv_wnn: [f32; LANES],
    pub(super) inv_wtt: [f32; LANES],
    pub(super) mu: [f32; LANES],
    pub(super) bias_n: [f32; LANES],
    pub(super) bias_t: [f32; LANES],
    pub(super) rn: [f32; LANES],
    pub(super) rt: [f32; LANES],
}

/// The `f32` copy of one solve: its groups, the color ranges in groups, and the velocities.
#[derive(Clone, Debug, Default)]
pub(super) struct Single {
    pub(super) groups: Vec<Group>,
    /// Color `c` is `groups[ranges[c]..ranges[c + 1]]`.
    pub(super) ranges: Vec<u32>,
    pub(super) lines: Vec<Line32>,
}

impl Single {
    /// Copies the rows of the colors `ranges` (in rows; every range a color proper, with no
    /// [`FULL`](super::rows::FULL) row) into groups, with the bodies' figures from
    /// `figures` (one entry per row, as [`super::rows::ColorRows::figures`] gives them) or
    /// else from `props`, and the velocities `lines` into `f32`.
    pub(super) fn fill(
        &mut self,
        rows: &[Row],
        ranges: &[u32],
        props: &[BodyProps],
        figures: Option<&[[f32; 6]]>,
        lines: &[Line],
    ) {
        assert!(
            figures.is_none_or(|f| f.len() == rows.len()),
            "figures for other rows"
        );
        let figure = |m: usize, r: &Row| match figures {
            Some(f) => f[m],
            None => {
                let (bi, bj) = (props[r.i as usize], props[r.j as usize]);
                [bi.inv_mass, bi.k, bi.lever, bj.inv_mass, bj.k, bj.lever].map(|x| x as f32)
            }
        };
        self.groups.clear();
        self.ranges.clear();
        self.ranges.push(0);
        for w in ranges.windows(2) {
            for (p, part) in rows[w[0] as usize..w[1] as usize].chunks(LANES).enumerate() {
                let first = w[0] as usize + p * LANES;
                // Lanes past the color's rows read body i of its first row, with zero
                // figures and fields: they move no body and their sums are +0.
                let mut g = Group {
                    i: [part[0].i; LANES],
                    j: [part[0].i; LANES],
                    ..Group::default()
                };
                for (l, r) in part.iter().enumerate() {
                    // The sweeps index the lines with `j` unchecked: a full-block row's is
                    // no body.
                    assert!(r.j != FULL, "a full-block row among the f32 sweeps' colors");
                    let [im_i, k_i, l_i, im_j, k_j, l_j] = figure(first + l, r);
                    g.i[l] = r.i;
                    g.j[l] = r.j;
                    g.im_i[l] = im_i;
                    g.k_i[l] = k_i;
                    g.l_i[l] = l_i;
                    g.im_j[l] = im_j;
                    g.k_j[l] = k_j;
                    g.l_j[l] = l_j;
                    g.nx[l] = r.nx as f32;
                    g.ny[l] = r.ny as f32;
                    g.inv_wnn[l] = r.inv_wnn as f32;
                    g.inv_wtt[l] = r.inv_wtt as f32;
                    g.mu[l] = r.mu as f32;
                    g.bias_n[l] = r.bias_n as f32;
                    g.bias_t[l] = r.bias_t as f32;
                    g.rn[l] = r.rn as f32;
                    g.rt[l] = r.rt as f32;
                }
                self.groups.push(g);
            }
            self.ranges.push(self.groups.len() as u32);
        }
        self.lines.clear();
        self.lines.extend(lines.iter().map(Line32::of));
    }

    /// One sweep over every color on the calling thread, chunk by chunk as a team sweeps
    /// them, the chunks' sums added in order: the same sums as a team's.
    ///
    /// # Safety
    /// As [`sweep_chunk`] for every chunk: the groups' bodies lie within `self.lines`, and
    /// nothing else touches them meanwhile.
    pub(super) unsafe fn sweep(&mut self, relax: f64) -> (f64, f64) {
        let lines = self.lines.as_mut_ptr();
        let mut total = (0.0, 0.0);
        for w in self.ranges.windows(2) {
            for ch in self.groups[w[0] as usize..w[1] as usize].chunks_mut(GROUP_CHUNK) {
                // SAFETY: forwarded from the caller.
                let (d, r) = unsafe { sweep_chunk(ch, lines, relax) };
                total.0 += d;
                total.1 += r;
            }
        }
        total
    }

    /// Gives the rows of the colors `ranges` (as given to [`Single::fill`]) their new
    /// impulses, and each body's velocity in `lines` the change of its `f32` copy.
    pub(super) fn finish(&self, rows: &mut [Row], ranges: &[u32], lines: &mut [Line]) {
        for (w, g) in ranges.windows(2).zip(self.ranges.windows(2)) {
            let part = &mut rows[w[0] as usize..w[1] as usize];
            let groups = &self.groups[g[0] as usize..g[1] as usize];
            for (rows, g) in part.chunks_mut(LANES).zip(groups) {
                for (l, r) in rows.iter_mut().enumerate() {
                    r.rn = f64::from(g.rn[l]);
                    r.rt = f64::from(g.rt[l]);
                }
            }
        }
        for (l, s) in lines.iter_mut().zip(&self.lines) {
            let start = Line32::of(l);
            if *s != start {
                // The change in `f64`: the `f32` values are exact in it.
                l.v += s.wide().v - start.wide().v;
            }
        }
    }
}

/// [`sweep_groups`] where the `f32` sweeps run: a chunk of groups of one color.
///
/// # Safety
/// As [`sweep_groups`]; only called when [`enabled`] said yes.
pub(super) unsafe fn sweep_chunk(groups: &mut [Group], lines: *mut Line32, relax: f64) -> (f64, f64) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: forwarded from the caller; `enabled` checked AVX-512F.
    return unsafe { sweep_groups(groups, lines, relax) };
    #[cfg(not(target_arch = "x86_64"))]
    {
        let _ = (groups, lines, relax);
        unreachable!("the f32 sweeps need AVX-512F (`single::enabled`)")
    }
}

/// The 4x4 transposes of 32-bit elements within each 128-bit lane of four registers: lane
/// `q` of output `f` holds element `f` of lane `q` of each input in turn (sixteen bodies'
/// lines, four per register, become their x, y, spin and padding in row order, and back).
macro_rules! transpose32 {
    ($r:expr) => {{
        let r = $r;
        let t0 = _mm512_unpacklo_ps(r[0], r[1]);
        let t1 = _mm512_unpackhi_ps(r[0], r[1]);
        let t2 = _mm512_unpacklo_ps(r[2], r[3]);
        let t3 = _mm512_unpackhi_ps(r[2], r[3]);
        [
            _mm512_shuffle_ps::<0x44>(t0, t2),
            _mm512_shuffle_ps::<0xEE>(t0, t2),
            _mm512_shuffle_ps::<0x44>(t1, t3),
            _mm512_shuffle_ps::<0xEE>(t1, t3),
        ]
    }};
}

/// Sweeps `groups` (a chunk of one color) in order and returns the sums (change^2,
/// impulse^2) of their rows in `f64`, lane by lane in a fixed order, so that the result
/// depends on the chunk, not on the thread that sweeps it. The law is the diagonal update
/// of [`super::update::update`] in `f32`, operation for operation (`reference` in the
/// tests); `relax` 1 is plain Gauss-Seidel.
///
/// # Safety
/// The processor has AVX-512F; `lines` is valid for every body of the groups; the rows of
/// the groups share no movable body, and no other thread writes their bodies meanwhile
/// (as [`super::ctx`] asks of the `f64` sweeps).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
pub(super) unsafe fn sweep_groups(groups: &mut [Group], lines: *mut Line32, relax: f64) -> (f64, f64) {
    let zero = _mm512_setzero_ps();
    let sign = _mm512_set1_epi32(i32::MIN);
    let neg = |x: __m512| _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(x), sign));
    let omega = (relax != 1.0).then_some(relax as f32);
    let mut acc = [_mm512_setzero_pd(); 4];
    for g in groups.iter_mut() {
        // SAFETY: the caller guarantees validity and exclusive access; a group's fields are
        // 64-byte aligned, a line 16-byte aligned.
        unsafe {
            macro_rules! field {
                ($f:ident) => {
                    _mm512_load_ps(g.$f.as_ptr())
                };
            }
            // Register m holds, in its 128-bit lane q, the line of row m + 4q's body.
            macro_rules! lines_of {
                ($side:ident) => {{
                    let f = |m: usize| {
                        let at = |q: usize| _mm_load_ps(lines.add(g.$side[m + 4 * q] as usize).cast());
                        let x = _mm512_castps128_ps512(at(0));
                        let x = _mm512_insertf32x4::<1>(x, at(1));
                        let x = _mm512_insertf32x4::<2>(x, at(2));
                        _mm512_insertf32x4::<3>(x, at(3))
                    };
                    [f(0), f(1), f(2), f(3)]
                }};
            }
            let [vix, viy, viz, _] = transpose32!(lines_of!(i));
            let [vjx, vjy, vjz, _] = transpose32!(lines_of!(j));
            // The f64 sweeps' law, operation for operation, in sixteen f32 lanes.
            let (rn, rt, drt, px, py, sq, r2) = law!(512f32 packed;
                neg,
                zero,
                omega,
                (vix, viy, viz),
                (vjx, vjy, vjz),
                (field!(l_i), field!(l_j)),
            );
            _mm512_store_ps(g.rn.as_mut_ptr(), rn);
            _mm512_store_ps(g.rt.as_mut_ptr(), rt);
            let (imi, ki, imj, kj) = (field!(im_i), field!(k_i), field!(im_j), field!(k_j));
            // A body moves when its inverse mass or its r / I is not zero (`BodyProps::movable`).
            let moves = |im: __m512, k: __m512| {
                _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(im, zero) | _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(k, zero)
            };
            let (mi, mj) = (moves(imi, ki), moves(imj, kj));
            let new_i = transpose32!([
                _mm512_add_ps(vix, _mm512_mul_ps(imi, px)),
                _mm512_add_ps(viy, _mm512_mul_ps(imi, py)),
                _mm512_add_ps(viz, _mm512_mul_ps(ki, drt)),
                zero,
            ]);
            let new_j = transpose32!([
                _mm512_sub_ps(vjx, _mm512_mul_ps(imj, px)),
                _mm512_sub_ps(vjy, _mm512_mul_ps(imj, py)),
                _mm512_add_ps(vjz, _mm512_mul_ps(kj, drt)),
                zero,
            ]);
            macro_rules! put {
                ($side:ident, $new:expr, $mask:expr) => {{
                    let (new, mask) = ($new, $mask);
                    for m in 0..4 {
                        let lane = |q: usize, v: __m128| {
                            if mask & (1 << (m + 4 * q)) != 0 {
                                _mm_store_ps(lines.add(g.$side[m + 4 * q] as usize).cast(), v);
                            }
                        };
                        lane(0, _mm512_castps512_ps128(new[m]));
                        lane(1, _mm512_extractf32x4_ps::<1>(new[m]));
                        lane(2, _mm512_extractf32x4_ps::<2>(new[m]));
                        lane(3, _mm512_extractf32x4_ps::<3>(new[m]));
                    }
                }};
            }
            put!(i, new_i, mi);
            put!(j, new_j, mj);
            // Rows 0-7 and 8-15 widened to f64 and added to their accumulators.
            let wide = |x: __m512| {
                (
                    _mm512_cvtps_pd(_mm512_castps512_ps256(x)),
                    _mm512_cvtps_pd(_mm256_castpd_ps(_mm512_extractf64x4_pd::<1>(_mm512_castps_pd(x)))),
                )
            };
            let ((s0, s1), (q0, q1)) = (wide(sq), wide(r2));
            acc = [
                _mm512_add_pd(acc[0], s0),
                _mm512_add_pd(acc[1], s1),
                _mm512_add_pd(acc[2], q0),
                _mm512_add_pd(acc[3], q1),
            ];
        }
    }
    let mut out = [[0.0f64; 8]; 4];
    for (o, a) in out.iter_mut().zip(acc) {
        // SAFETY: `o` holds eight f64.
        unsafe { _mm512_storeu_pd(o.as_mut_ptr(), a) };
    }
    let sum = |a: &[f64; 8], b: &[f64; 8]| a.iter().chain(b).fold(0.0, |s, x| s + x);
    (sum(&out[0], &out[1]), sum(&out[2], &out[3]))
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;

    /// The diagonal law of [`super::super::update::update`] in `f32`, one row at a time,
    /// the operations of [`sweep_groups`] in their order: the reference its lanes must
    /// equal bit for bit. Returns the row's (change^2, impulse^2).
    fn reference(g: &mut Group, l: usize, lines: &mut [Line32], relax: f32) -> (f32, f32) {
        let larger = |a: f32, b: f32| if a > b { a } else { b };
        let smaller = |a: f32, b: f32| if a < b { a } else { b };
        let (bi, bj) = (g.i[l] as usize, g.j[l] as usize);
        let (vi, vj) = (lines[bi].0, lines[bj].0);
        let (nx, ny, rn0, rt0) = (g.nx[l], g.ny[l], g.rn[l], g.rt[l]);
        let (dx, dy) = (vi[0] - vj[0], vi[1] - vj[1]);
        let un = dx * nx + dy * ny;
        let ut = dx * ny - dy * nx + vi[2] * g.l_i[l] + vj[2] * g.l_j[l];
        let rn = larger(rn0 - (un + g.bias_n[l]) * g.inv_wnn[l], 0.0);
        let lim = g.mu[l] * rn;
        let rt = smaller(larger(rt0 - (ut + g.bias_t[l]) * g.inv_wtt[l], -lim), lim);
        let (rn, rt) = if relax != 1.0 {
            (rn0 + relax * (rn - rn0), rt0 + relax * (rt - rt0))
        } else {
            (rn, rt)
        };
        let (drn, drt) = (rn - rn0, rt - rt0);
        let px = drn * nx + drt * ny;
        let py = drn * ny - drt * nx;
        if g.im_i[l] != 0.0 || g.k_i[l] != 0.0 {
            lines[bi].0 = [
                vi[0] + g.im_i[l] * px,
                vi[1] + g.im_i[l] * py,
                vi[2] + g.k_i[l] * drt,
                0.0,
            ];
        }
        if g.im_j[l] != 0.0 || g.k_j[l] != 0.0 {
            lines[bj].0 = [
                vj[0] - g.im_j[l] * px,
                vj[1] - g.im_j[l] * py,
                vj[2] + g.k_j[l] * drt,
                0.0,
            ];
        }
        g.rn[l] = rn;
        g.rt[l] = rt;
        (drn * drn + drt * drt, rn * rn + rt * rt)
    }

    /// Whether this processor has AVX-512F; when not, says which comparison did not run,
    /// past the test harness's capture (so a plain `cargo test` shows it).
    fn avx512_here(what: &str) -> bool {
        let here = std::arch::is_x86_feature_detected!("avx512f");
        if !here {
            let note = format!("NOTE: no AVX-512F here: {what}\n");
            let _ = std::io::Write::write_all(&mut std::io::stderr(), note.as_bytes());
        }
        here
    }

    /// One color of `n` rows ([`super::super::lanes::tests::color_of`]: disks that move,
    /// disks that only spin, and walls shared by some rows; impulses at zero, inside the
    /// Coulomb interval and on its edge), as rows, body table and lines.
    fn color_of(n: usize, seed: u64) -> (Vec<Row>, Vec<BodyProps>, Vec<Line>) {
        let (rows, lines, props) = super::super::lanes::tests::color_of(n, seed, false);
        (rows, props, lines)
    }

    /// The sixteen-wide sweep gives, lane by lane, the scalar `f32` law's impulses and
    /// velocities bit for bit, and its sums are those of the real rows (the filler lanes
    /// add nothing and move nothing), for colors of every remainder of sixteen, relaxed or
    /// not.
    #[test]
    fn sixteen_lanes_equal_the_scalar_f32_law_bit_for_bit() {
        if !avx512_here("the f32 sweeps not compared with the scalar f32 law") {
            return;
        }
        for n in [1, 2, 15, 16, 17, 31, 64, 67, 130] {
            for relax in [1.0, 0.5] {
                let (rows, props, lines) = color_of(n, 11 + n as u64);
                let ranges = [0, n as u32];
                let mut fast = Single::default();
                fast.fill(&rows, &ranges, &props, None, &lines);
                let mut slow = fast.clone();
                for sweep in 0..3 {
                    // SAFETY: this processor has AVX-512F (checked); one thread; the rows of
                    // `color_of` share no movable body and index bodies within the lines.
                    let (d, q) = unsafe { sweep_groups(&mut fast.groups, fast.lines.as_mut_ptr(), relax) };
                    let (mut d_ref, mut q_ref) = (0.0f64, 0.0f64);
                    for g in 0..slow.groups.len() {
                        for l in 0..LANES.min(n - g * LANES) {
                            let (d, q) = reference(&mut slow.groups[g], l, &mut slow.lines, relax as f32);
                            d_ref += f64::from(d);
                            q_ref += f64::from(q);
                        }
                    }
                    let rel = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
                    assert!(
                        rel(d, d_ref) && rel(q, q_ref),
                        "{n} rows, relax {relax}, sweep {sweep}: sums {d} {q} against {d_ref} {q_ref}"
                    );
                    assert!(
                        d_ref > 0.0 || sweep > 0 || n < 15,
                        "{n} rows: the first sweep changed nothing"
                    );
                    assert!(
                        fast.lines == slow.lines,
                        "{n} rows, relax {relax}, sweep {sweep}: velocities"
                    );
                    let bits = |s: &Single| -> Vec<u32> {
                        s.groups
                            .iter()
                            .flat_map(|g| g.rn.iter().chain(&g.rt).map(|x| x.to_bits()))
                            .collect()
                    };
                    assert_eq!(
                        bits(&fast),
                        bits(&slow),
                        "{n} rows, relax {relax}, sweep {sweep}: impulses"
                    );
                }
            }
        }
    }

    /// Three sweeps in `f32`, filled from the rows and body table and finished, follow the
    /// `f64` update ([`super::super::update::sweep_chunk`]) on the same rows within `f32`
    /// rounding: each impulse and velocity within 1e-5 of the `f64` one (the values are of
    /// order 1; `f32` keeps about 6e-8 of a value, and three sweeps compound it a little).
    #[test]
    fn f32_sweeps_follow_the_f64_update() {
        if !avx512_here("the f32 sweeps not compared with the f64 update") {
            return;
        }
        for relax in [1.0, 0.5] {
            let (rows, props, lines) = color_of(67, 9);
            let ranges = [0, 67];
            let (mut rows64, mut lines64) = (rows.clone(), lines.clone());
            let ctx = super::super::ctx::Ctx {
                gv: lines64.as_mut_ptr(),
                props: props.as_ptr(),
                contacts: std::ptr::null_mut(),
                relax,
                quads: false,
                frictionless: false,
            };
            let (mut rows32, mut lines32) = (rows.clone(), lines.clone());
            let mut s = Single::default();
            s.fill(&rows32, &ranges, &props, None, &lines32);
            for _ in 0..3 {
                // SAFETY: one thread; the rows share no movable body and index bodies within
                // the lines; AVX-512F checked.
                unsafe {
                    super::super::update::sweep_chunk(&mut rows64, ctx);
                    sweep_groups(&mut s.groups, s.lines.as_mut_ptr(), relax);
                }
            }
            s.finish(&mut rows32, &ranges, &mut lines32);
            let mut worst = 0.0f64;
            for (a, b) in rows32.iter().zip(&rows64) {
                worst = worst.max((a.rn - b.rn).abs()).max((a.rt - b.rt).abs());
            }
            for (a, b) in lines32.iter().zip(&lines64) {
                worst = worst.max((a.v - b.v).abs().max_element());
            }
            assert!(worst <= 1e-5, "relax {relax}: largest difference {worst}");
            assert!(
                lines64.iter().zip(&lines).any(|(a, b)| a != b),
                "the sweeps moved nothing"
            );
        }
    }

    /// Filling and finishing without a sweep gives every row its impulses rounded to `f32`
    /// and leaves every velocity exactly as it was; a body whose `f32` copy moved receives
    /// that change, and one that did not keeps its `f64` value bit for bit.
    #[test]
    fn finishing_gives_back_the_f32_changes_and_nothing_else() {
        let (mut rows, props, mut lines) = color_of(37, 5);
        let ranges = [0, 20, 37];
        let mut s = Single::default();
        s.fill(&rows, &ranges, &props, None, &lines);
        assert_eq!(s.ranges, vec![0, 2, 4], "groups per color");
        let before = lines.clone();
        let want: Vec<(f64, f64)> = rows
            .iter()
            .map(|r| (f64::from(r.rn as f32), f64::from(r.rt as f32)))
            .collect();
        s.finish(&mut rows, &ranges, &mut lines);
        assert!(lines == before, "velocities moved without a sweep");
        assert_eq!(rows.iter().map(|r| (r.rn, r.rt)).collect::<Vec<_>>(), want);
        s.lines[4].0[1] += 0.25;
        s.finish(&mut rows, &ranges, &mut lines);
        let moved = f64::from(before[4].v.y as f32 + 0.25) - f64::from(before[4].v.y as f32);
        assert_eq!(lines[4].v.y, before[4].v.y + moved);
        assert_eq!(lines[4].v.x.to_bits(), before[4].v.x.to_bits());
        assert!(
            lines
                .iter()
                .zip(&before)
                .enumerate()
                .all(|(k, (a, b))| k == 4 || a == b)
        );
    }
}
