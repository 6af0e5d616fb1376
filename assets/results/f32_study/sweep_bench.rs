// The sweep of the f32 study (README.md beside this file): colored Gauss-Seidel sweeps over
// synthetic colors, timed four ways on one thread with AVX-512F:
//   f64 octs:           eight rows per 512-bit register, the bodies' inverse mass, r / I and
//                       lever read from a per-body table, as cdlab's `sweep_octs`;
//   f64, figures in rows: the same with those figures stored in each row (same results, bit
//                       for bit, which the program checks);
//   f32 sixteens:       sixteen rows per register in f32, the table in f32;
//   f32, figures in rows: sixteen rows in f32, the figures in each row.
// Build and run: rustc -O --edition 2024 sweep_bench.rs && ./sweep_bench BODIES ITERATIONS
#![allow(clippy::all)]
use std::arch::x86_64::*;
use std::time::Instant;

#[repr(C, align(32))] #[derive(Clone, Copy, Default)] struct L64([f64; 4]);
#[repr(C, align(16))] #[derive(Clone, Copy, Default)] struct L32([f32; 4]);
#[repr(C)] #[derive(Clone, Copy, Default)]
struct Q64 { i: [u32; 4], j: [u32; 4], im_i: [f64; 4], k_i: [f64; 4], l_i: [f64; 4], im_j: [f64; 4], k_j: [f64; 4], l_j: [f64; 4], nx: [f64; 4], ny: [f64; 4], inv_wnn: [f64; 4], inv_wtt: [f64; 4], mu: [f64; 4], bias_n: [f64; 4], bias_t: [f64; 4], rn: [f64; 4], rt: [f64; 4] }
#[repr(C, align(64))] #[derive(Clone, Copy, Default)]
struct G16 { i: [u32; 16], j: [u32; 16], im_i: [f32; 16], k_i: [f32; 16], l_i: [f32; 16], im_j: [f32; 16], k_j: [f32; 16], l_j: [f32; 16], nx: [f32; 16], ny: [f32; 16], inv_wnn: [f32; 16], inv_wtt: [f32; 16], mu: [f32; 16], bias_n: [f32; 16], bias_t: [f32; 16], rn: [f32; 16], rt: [f32; 16], mov: [u16; 2] }

macro_rules! law {
    ([$add:path, $sub:path, $mul:path, $max:path, $min:path], $neg:expr, $zero:expr,
     ($vix:expr, $viy:expr, $viz:expr), ($vjx:expr, $vjy:expr, $vjz:expr), ($li:expr, $lj:expr),
     [$nx:expr, $ny:expr, $rn0:expr, $rt0:expr, $bias_n:expr, $inv_wnn:expr, $mu:expr, $bias_t:expr, $inv_wtt:expr]) => {{
        let (nx, ny, rn0, rt0) = ($nx, $ny, $rn0, $rt0);
        let dx = $sub($vix, $vjx);
        let dy = $sub($viy, $vjy);
        let un = $add($mul(dx, nx), $mul(dy, ny));
        let ut = $add($add($sub($mul(dx, ny), $mul(dy, nx)), $mul($viz, $li)), $mul($vjz, $lj));
        let rn = $max($sub(rn0, $mul($add(un, $bias_n), $inv_wnn)), $zero);
        let lim = $mul($mu, rn);
        let rt = $min($max($sub(rt0, $mul($add(ut, $bias_t), $inv_wtt)), $neg(lim)), lim);
        let (drn, drt) = ($sub(rn, rn0), $sub(rt, rt0));
        let px = $add($mul(drn, nx), $mul(drt, ny));
        let py = $sub($mul(drn, ny), $mul(drt, nx));
        let sq = $add($mul(drn, drn), $mul(drt, drt));
        let r2 = $add($mul(rn, rn), $mul(rt, rt));
        (rn, rt, drt, px, py, sq, r2)
    }};
}
macro_rules! t512 {
    ($r:expr) => {{
        let r = $r;
        let t0 = _mm512_unpacklo_pd(r[0], r[1]);
        let t1 = _mm512_unpackhi_pd(r[0], r[1]);
        let t2 = _mm512_unpacklo_pd(r[2], r[3]);
        let t3 = _mm512_unpackhi_pd(r[2], r[3]);
        let even = _mm512_set_epi64(13, 12, 5, 4, 9, 8, 1, 0);
        let odd = _mm512_set_epi64(15, 14, 7, 6, 11, 10, 3, 2);
        [_mm512_permutex2var_pd(t0, even, t2), _mm512_permutex2var_pd(t1, even, t3),
         _mm512_permutex2var_pd(t0, odd, t2), _mm512_permutex2var_pd(t1, odd, t3)]
    }};
}
// 4x4 transpose of 32-bit elements within each 128-bit lane.
macro_rules! t32 {
    ($r:expr) => {{
        let r = $r;
        let t0 = _mm512_unpacklo_ps(r[0], r[1]);
        let t1 = _mm512_unpackhi_ps(r[0], r[1]);
        let t2 = _mm512_unpacklo_ps(r[2], r[3]);
        let t3 = _mm512_unpackhi_ps(r[2], r[3]);
        [_mm512_shuffle_ps::<0x44>(t0, t2), _mm512_shuffle_ps::<0xEE>(t0, t2),
         _mm512_shuffle_ps::<0x44>(t1, t3), _mm512_shuffle_ps::<0xEE>(t1, t3)]
    }};
}

#[target_feature(enable = "avx512f")]
unsafe fn sweep64(qs: &mut [Q64], gv: *mut L64, props: *const L64, acc: &mut (f64, f64)) {
    let zero = _mm512_setzero_pd();
    let sign = _mm512_set1_epi64(i64::MIN);
    let j_sign = _mm512_set_epi64(0, 0, i64::MIN, i64::MIN, 0, 0, i64::MIN, i64::MIN);
    let xor = |x: __m512d, s: __m512i| _mm512_castsi512_pd(_mm512_xor_si512(_mm512_castpd_si512(x), s));
    for oct in qs.chunks_exact_mut(2) {
        let (a, b) = oct.split_at_mut(1);
        let (qa, qb) = (&mut a[0], &mut b[0]);
        unsafe {
            macro_rules! field { ($f:ident) => { _mm512_insertf64x4::<1>(_mm512_castpd256_pd512(_mm256_loadu_pd(qa.$f.as_ptr())), _mm256_loadu_pd(qb.$f.as_ptr())) }; }
            macro_rules! store { ($f:ident, $v:expr) => {{ let v = $v; _mm256_storeu_pd(qa.$f.as_mut_ptr(), _mm512_castpd512_pd256(v)); _mm256_storeu_pd(qb.$f.as_mut_ptr(), _mm512_extractf64x4_pd::<1>(v)); }}; }
            macro_rules! pair { ($base:expr, $side:ident, $l:expr) => { _mm512_insertf64x4::<1>(_mm512_castpd256_pd512(_mm256_load_pd($base.add(qa.$side[$l] as usize).cast())), _mm256_load_pd($base.add(qb.$side[$l] as usize).cast())) }; }
            let vi: [__m512d; 4] = std::array::from_fn(|l| pair!(gv, i, l));
            let vj: [__m512d; 4] = std::array::from_fn(|l| pair!(gv, j, l));
            let bi: [__m512d; 4] = std::array::from_fn(|l| pair!(props, i, l));
            let bj: [__m512d; 4] = std::array::from_fn(|l| pair!(props, j, l));
            let [vix, viy, viz, _] = t512!(vi);
            let [vjx, vjy, vjz, _] = t512!(vj);
            let [_, _, _, li] = t512!(bi);
            let [_, _, _, lj] = t512!(bj);
            let (rn, rt, drt, px, py, sq, r2) = law!([_mm512_add_pd, _mm512_sub_pd, _mm512_mul_pd, _mm512_max_pd, _mm512_min_pd], |x| xor(x, sign), zero,
                (vix, viy, viz), (vjx, vjy, vjz), (li, lj),
                [field!(nx), field!(ny), field!(rn), field!(rt), field!(bias_n), field!(inv_wnn), field!(mu), field!(bias_t), field!(inv_wtt)]);
            store!(rt, rt);
            store!(rn, rn);
            let change = t512!([px, py, drt, zero]);
            macro_rules! put { ($side:ident, $l:expr, $factor:expr, $v:expr, $b:expr) => {{
                let new = _mm512_add_pd($v, _mm512_mul_pd($factor, change[$l]));
                let moves = _mm512_cmp_pd_mask::<_CMP_NEQ_UQ>($b, zero);
                if moves & 0b0000_0101 != 0 { _mm256_store_pd(gv.add(qa.$side[$l] as usize).cast(), _mm512_castpd512_pd256(new)); }
                if moves & 0b0101_0000 != 0 { _mm256_store_pd(gv.add(qb.$side[$l] as usize).cast(), _mm512_extractf64x4_pd::<1>(new)); }
            }}; }
            for l in 0..4 { put!(i, l, bi[l], vi[l], bi[l]); put!(j, l, xor(bj[l], j_sign), vj[l], bj[l]); }
            let mut out = [[0.0; 8]; 2];
            for (o, v) in out.iter_mut().zip([sq, r2]) { _mm512_storeu_pd(o.as_mut_ptr(), v); }
            for (d, r) in out[0].iter().zip(&out[1]) { acc.0 += d; acc.1 += r; }
        }
    }
}

#[target_feature(enable = "avx512f")]
unsafe fn sweep32(gs: &mut [G16], gv: *mut L32, props: *const L32, acc: &mut (__m512, __m512)) {
    let zero = _mm512_setzero_ps();
    let sign = _mm512_set1_epi32(i32::MIN);
    // Body j takes the impulse with the other sign on x and y (elements 0, 1 of each line).
    let j_sign = _mm512_set_epi32(0, 0, i32::MIN, i32::MIN, 0, 0, i32::MIN, i32::MIN, 0, 0, i32::MIN, i32::MIN, 0, 0, i32::MIN, i32::MIN);
    let xor = |x: __m512, s: __m512i| _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(x), s));
    for g in gs.iter_mut() {
        unsafe {
            macro_rules! field { ($f:ident) => { _mm512_load_ps(g.$f.as_ptr()) }; }
            // Register m holds rows m, m+4, m+8, m+12 in its four 128-bit lanes.
            macro_rules! lanes { ($base:expr, $side:ident) => {{
                let b = $base;
                let f = |m: usize| {
                    let x = _mm512_castps128_ps512(_mm_load_ps(b.add(g.$side[m] as usize).cast()));
                    let x = _mm512_insertf32x4::<1>(x, _mm_load_ps(b.add(g.$side[m + 4] as usize).cast()));
                    let x = _mm512_insertf32x4::<2>(x, _mm_load_ps(b.add(g.$side[m + 8] as usize).cast()));
                    _mm512_insertf32x4::<3>(x, _mm_load_ps(b.add(g.$side[m + 12] as usize).cast()))
                };
                [f(0), f(1), f(2), f(3)]
            }}; }
            let vi = lanes!(gv, i);
            let vj = lanes!(gv, j);
            let bi = lanes!(props, i);
            let bj = lanes!(props, j);
            // After the transpose, element 4k + m of each register is row 4k + m, the
            // fields' order.
            let [vix, viy, viz, _] = t32!(vi);
            let [vjx, vjy, vjz, _] = t32!(vj);
            let [_, _, _, li] = t32!(bi);
            let [_, _, _, lj] = t32!(bj);
            let (rn, rt, drt, px, py, sq, r2) = law!([_mm512_add_ps, _mm512_sub_ps, _mm512_mul_ps, _mm512_max_ps, _mm512_min_ps], |x| xor(x, sign), zero,
                (vix, viy, viz), (vjx, vjy, vjz), (li, lj),
                [field!(nx), field!(ny), field!(rn), field!(rt), field!(bias_n), field!(inv_wnn), field!(mu), field!(bias_t), field!(inv_wtt)]);
            _mm512_store_ps(g.rt.as_mut_ptr(), rt);
            _mm512_store_ps(g.rn.as_mut_ptr(), rn);
            let change = t32!([px, py, drt, zero]);
            macro_rules! put { ($side:ident, $m:expr, $factor:expr, $v:expr, $b:expr, $base:expr) => {{
                let new = _mm512_add_ps($v, _mm512_mul_ps($factor, change[$m]));
                // Elements 0 and 2 of each line: inverse mass and r / I.
                let moves = _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>($b, zero);
                if moves & 0x0005 != 0 { _mm_store_ps($base.add(g.$side[$m] as usize).cast(), _mm512_castps512_ps128(new)); }
                if moves & 0x0050 != 0 { _mm_store_ps($base.add(g.$side[$m + 4] as usize).cast(), _mm512_extractf32x4_ps::<1>(new)); }
                if moves & 0x0500 != 0 { _mm_store_ps($base.add(g.$side[$m + 8] as usize).cast(), _mm512_extractf32x4_ps::<2>(new)); }
                if moves & 0x5000 != 0 { _mm_store_ps($base.add(g.$side[$m + 12] as usize).cast(), _mm512_extractf32x4_ps::<3>(new)); }
            }}; }
            for m in 0..4 { put!(i, m, bi[m], vi[m], bi[m], gv); put!(j, m, xor(bj[m], j_sign), vj[m], bj[m], gv); }
            acc.0 = _mm512_add_ps(acc.0, sq);
            acc.1 = _mm512_add_ps(acc.1, r2);
        }
    }
}


#[target_feature(enable = "avx512f")]
unsafe fn sweep32p(gs: &mut [G16], gv: *mut L32, acc: &mut (__m512, __m512)) {
    let zero = _mm512_setzero_ps();
    let sign = _mm512_set1_epi32(i32::MIN);
    let xor = |x: __m512, s: __m512i| _mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(x), s));
    for g in gs.iter_mut() {
        unsafe {
            macro_rules! field { ($f:ident) => { _mm512_load_ps(g.$f.as_ptr()) }; }
            macro_rules! lanes { ($base:expr, $side:ident) => {{
                let b = $base;
                let f = |m: usize| {
                    let x = _mm512_castps128_ps512(_mm_load_ps(b.add(g.$side[m] as usize).cast()));
                    let x = _mm512_insertf32x4::<1>(x, _mm_load_ps(b.add(g.$side[m + 4] as usize).cast()));
                    let x = _mm512_insertf32x4::<2>(x, _mm_load_ps(b.add(g.$side[m + 8] as usize).cast()));
                    _mm512_insertf32x4::<3>(x, _mm_load_ps(b.add(g.$side[m + 12] as usize).cast()))
                };
                [f(0), f(1), f(2), f(3)]
            }}; }
            let vi = lanes!(gv, i);
            let vj = lanes!(gv, j);
            let [vix, viy, viz, _] = t32!(vi);
            let [vjx, vjy, vjz, _] = t32!(vj);
            let (li, lj) = (field!(l_i), field!(l_j));
            let (rn, rt, drt, px, py, sq, r2) = law!([_mm512_add_ps, _mm512_sub_ps, _mm512_mul_ps, _mm512_max_ps, _mm512_min_ps], |x| xor(x, sign), zero,
                (vix, viy, viz), (vjx, vjy, vjz), (li, lj),
                [field!(nx), field!(ny), field!(rn), field!(rt), field!(bias_n), field!(inv_wnn), field!(mu), field!(bias_t), field!(inv_wtt)]);
            _mm512_store_ps(g.rt.as_mut_ptr(), rt);
            _mm512_store_ps(g.rn.as_mut_ptr(), rn);
            let (imi, imj) = (field!(im_i), field!(im_j));
            let ni = t32!([
                _mm512_add_ps(vix, _mm512_mul_ps(imi, px)),
                _mm512_add_ps(viy, _mm512_mul_ps(imi, py)),
                _mm512_add_ps(viz, _mm512_mul_ps(field!(k_i), drt)),
                zero
            ]);
            let nj = t32!([
                _mm512_sub_ps(vjx, _mm512_mul_ps(imj, px)),
                _mm512_sub_ps(vjy, _mm512_mul_ps(imj, py)),
                _mm512_add_ps(vjz, _mm512_mul_ps(field!(k_j), drt)),
                zero
            ]);
            macro_rules! put { ($side:ident, $m:expr, $new:expr, $mask:expr) => {{
                let new = $new;
                let mask = $mask;
                if mask & (1 << $m) != 0 { _mm_store_ps(gv.add(g.$side[$m] as usize).cast(), _mm512_castps512_ps128(new)); }
                if mask & (1 << ($m + 4)) != 0 { _mm_store_ps(gv.add(g.$side[$m + 4] as usize).cast(), _mm512_extractf32x4_ps::<1>(new)); }
                if mask & (1 << ($m + 8)) != 0 { _mm_store_ps(gv.add(g.$side[$m + 8] as usize).cast(), _mm512_extractf32x4_ps::<2>(new)); }
                if mask & (1 << ($m + 12)) != 0 { _mm_store_ps(gv.add(g.$side[$m + 12] as usize).cast(), _mm512_extractf32x4_ps::<3>(new)); }
            }}; }
            for m in 0..4 { put!(i, m, ni[m], g.mov[0]); put!(j, m, nj[m], g.mov[1]); }
            acc.0 = _mm512_add_ps(acc.0, sq);
            acc.1 = _mm512_add_ps(acc.1, r2);
        }
    }
}

#[target_feature(enable = "avx512f")]
unsafe fn sweep64p(qs: &mut [Q64], gv: *mut L64, acc: &mut (f64, f64)) {
    let zero = _mm512_setzero_pd();
    let sign = _mm512_set1_epi64(i64::MIN);
    let xor = |x: __m512d, s: __m512i| _mm512_castsi512_pd(_mm512_xor_si512(_mm512_castpd_si512(x), s));
    for oct in qs.chunks_exact_mut(2) {
        let (a, b) = oct.split_at_mut(1);
        let (qa, qb) = (&mut a[0], &mut b[0]);
        unsafe {
            macro_rules! field { ($f:ident) => { _mm512_insertf64x4::<1>(_mm512_castpd256_pd512(_mm256_loadu_pd(qa.$f.as_ptr())), _mm256_loadu_pd(qb.$f.as_ptr())) }; }
            macro_rules! store { ($f:ident, $v:expr) => {{ let v = $v; _mm256_storeu_pd(qa.$f.as_mut_ptr(), _mm512_castpd512_pd256(v)); _mm256_storeu_pd(qb.$f.as_mut_ptr(), _mm512_extractf64x4_pd::<1>(v)); }}; }
            macro_rules! pair { ($base:expr, $side:ident, $l:expr) => { _mm512_insertf64x4::<1>(_mm512_castpd256_pd512(_mm256_load_pd($base.add(qa.$side[$l] as usize).cast())), _mm256_load_pd($base.add(qb.$side[$l] as usize).cast())) }; }
            let vi: [__m512d; 4] = std::array::from_fn(|l| pair!(gv, i, l));
            let vj: [__m512d; 4] = std::array::from_fn(|l| pair!(gv, j, l));
            let [vix, viy, viz, _] = t512!(vi);
            let [vjx, vjy, vjz, _] = t512!(vj);
            let (li, lj) = (field!(l_i), field!(l_j));
            let (rn, rt, drt, px, py, sq, r2) = law!([_mm512_add_pd, _mm512_sub_pd, _mm512_mul_pd, _mm512_max_pd, _mm512_min_pd], |x| xor(x, sign), zero,
                (vix, viy, viz), (vjx, vjy, vjz), (li, lj),
                [field!(nx), field!(ny), field!(rn), field!(rt), field!(bias_n), field!(inv_wnn), field!(mu), field!(bias_t), field!(inv_wtt)]);
            store!(rt, rt);
            store!(rn, rn);
            let (imi, imj) = (field!(im_i), field!(im_j));
            let ni = t512!([
                _mm512_add_pd(vix, _mm512_mul_pd(imi, px)),
                _mm512_add_pd(viy, _mm512_mul_pd(imi, py)),
                _mm512_add_pd(viz, _mm512_mul_pd(field!(k_i), drt)),
                zero
            ]);
            let nj = t512!([
                _mm512_sub_pd(vjx, _mm512_mul_pd(imj, px)),
                _mm512_sub_pd(vjy, _mm512_mul_pd(imj, py)),
                _mm512_add_pd(vjz, _mm512_mul_pd(field!(k_j), drt)),
                zero
            ]);
            for l in 0..4 {
                _mm256_store_pd(gv.add(qa.i[l] as usize).cast(), _mm512_castpd512_pd256(ni[l]));
                _mm256_store_pd(gv.add(qb.i[l] as usize).cast(), _mm512_extractf64x4_pd::<1>(ni[l]));
                _mm256_store_pd(gv.add(qa.j[l] as usize).cast(), _mm512_castpd512_pd256(nj[l]));
                _mm256_store_pd(gv.add(qb.j[l] as usize).cast(), _mm512_extractf64x4_pd::<1>(nj[l]));
            }
            let mut out = [[0.0; 8]; 2];
            for (o, v) in out.iter_mut().zip([sq, r2]) { _mm512_storeu_pd(o.as_mut_ptr(), v); }
            for (d, r) in out[0].iter().zip(&out[1]) { acc.0 += d; acc.1 += r; }
        }
    }
}

struct Rng(u64);
impl Rng { fn next(&mut self) -> u64 { self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15); let mut z = self.0; z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9); z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB); z ^ (z >> 31) } fn f(&mut self) -> f64 { (self.next() >> 11) as f64 / (1u64 << 53) as f64 } }

fn main() {
    let nb: usize = std::env::args().nth(1).map(|s| s.parse().unwrap()).unwrap_or(5000);
    let per_color: usize = 1024 * nb / 5000; // rows per color, a multiple of 16
    let per_color = per_color / 16 * 16;
    let colors = 10;
    let iters: usize = std::env::args().nth(2).map(|s| s.parse().unwrap()).unwrap_or(400);
    let mut rng = Rng(1);
    // Colors: random pairs of distinct bodies, no body twice in a color, bodies near in index.
    let mut rows: Vec<Vec<(u32, u32, f64, f64)>> = Vec::new();
    for _ in 0..colors {
        let mut used = vec![false; nb];
        let mut c = Vec::new();
        while c.len() < per_color {
            let i = (rng.next() % nb as u64) as usize;
            let j = ((i as i64 + (rng.next() % 80) as i64 - 40).rem_euclid(nb as i64)) as usize;
            if i == j || used[i] || used[j] { continue; }
            used[i] = true; used[j] = true;
            let a = rng.f() * 6.283;
            c.push((i as u32, j as u32, a.cos(), a.sin()));
        }
        c.sort_by_key(|r| r.0);
        rows.push(c);
    }
    let im = 1e-3; let k = 2e-3; let lever = 1.0;
    let mut gv64 = vec![L64::default(); nb];
    let mut gv32 = vec![L32::default(); nb];
    let mut p64 = vec![L64::default(); nb];
    let mut p32 = vec![L32::default(); nb];
    for b in 0..nb {
        let v = [rng.f() - 0.5, rng.f() - 0.5, 0.1 * (rng.f() - 0.5)];
        gv64[b] = L64([v[0], v[1], v[2], 0.0]);
        gv32[b] = L32([v[0] as f32, v[1] as f32, v[2] as f32, 0.0]);
        p64[b] = L64([im, im, k, lever]);
        p32[b] = L32([im as f32, im as f32, k as f32, lever as f32]);
    }
    let inv_wnn = 1.0 / (2.0 * im); let inv_wtt = 1.0 / (2.0 * im + 2.0 * lever * k);
    let mut q64: Vec<Vec<Q64>> = rows.iter().map(|c| c.chunks(4).map(|ch| {
        let mut q = Q64::default();
        for (l, r) in ch.iter().enumerate() { q.i[l] = r.0; q.j[l] = r.1; q.nx[l] = r.2; q.ny[l] = r.3; q.inv_wnn[l] = inv_wnn; q.inv_wtt[l] = inv_wtt; q.mu[l] = 0.3; q.bias_n[l] = 1e-3; q.bias_t[l] = 0.0; q.im_i[l] = im; q.im_j[l] = im; q.k_i[l] = k; q.k_j[l] = k; q.l_i[l] = lever; q.l_j[l] = lever; }
        q }).collect()).collect();
    let mut q64p = q64.clone();
    let mut gv64p = gv64.clone();
    let mut g16: Vec<Vec<G16>> = rows.iter().map(|c| c.chunks(16).map(|ch| {
        let mut g = G16::default();
        for (l, r) in ch.iter().enumerate() { g.i[l] = r.0; g.j[l] = r.1; g.nx[l] = r.2 as f32; g.ny[l] = r.3 as f32; g.inv_wnn[l] = inv_wnn as f32; g.inv_wtt[l] = inv_wtt as f32; g.mu[l] = 0.3; g.bias_n[l] = 1e-3; g.bias_t[l] = 0.0; g.im_i[l] = im as f32; g.im_j[l] = im as f32; g.k_i[l] = k as f32; g.k_j[l] = k as f32; g.l_i[l] = lever as f32; g.l_j[l] = lever as f32; }
        g.mov = [0xffff, 0xffff];
        g }).collect()).collect();
    let mut g16p = g16.clone();
    let mut gv32p = gv32.clone();
    let n_rows = colors * per_color;
    for round in 0..3 {
        let t = Instant::now();
        let mut acc = (0.0, 0.0);
        for _ in 0..iters { for c in q64.iter_mut() { unsafe { sweep64(c, gv64.as_mut_ptr(), p64.as_ptr(), &mut acc) } } }
        let t64 = t.elapsed().as_secs_f64() / (iters * n_rows) as f64 * 1e9;
        let t = Instant::now();
        let mut acc32 = unsafe { (_mm512_setzero_ps(), _mm512_setzero_ps()) };
        for _ in 0..iters { for c in g16.iter_mut() { unsafe { sweep32(c, gv32.as_mut_ptr(), p32.as_ptr(), &mut acc32) } } }
        let t32 = t.elapsed().as_secs_f64() / (iters * n_rows) as f64 * 1e9;
        let t = Instant::now();
        let mut acc64p = (0.0, 0.0);
        for _ in 0..iters { for c in q64p.iter_mut() { unsafe { sweep64p(c, gv64p.as_mut_ptr(), &mut acc64p) } } }
        let t64p = t.elapsed().as_secs_f64() / (iters * n_rows) as f64 * 1e9;
        let same = q64.iter().flatten().zip(q64p.iter().flatten()).all(|(a, b)| a.rn.iter().zip(&b.rn).all(|(x, y)| x.to_bits() == y.to_bits()))
            && gv64.iter().zip(&gv64p).all(|(a, b)| a.0.iter().zip(&b.0).all(|(x, y)| x.to_bits() == y.to_bits()))
            && acc.0.to_bits() == acc64p.0.to_bits();
        let t = Instant::now();
        let mut acc32p = unsafe { (_mm512_setzero_ps(), _mm512_setzero_ps()) };
        for _ in 0..iters { for c in g16p.iter_mut() { unsafe { sweep32p(c, gv32p.as_mut_ptr(), &mut acc32p) } } }
        let t32p = t.elapsed().as_secs_f64() / (iters * n_rows) as f64 * 1e9;
        let (mut dp, mut np) = (0.0f64, 0.0f64);
        for (a, b) in g16.iter().flatten().zip(g16p.iter().flatten()) { for (x, y) in a.rn.iter().zip(&b.rn) { dp += ((x - y) as f64).powi(2); np += (*x as f64).powi(2); } }
        // The two f32 forms, like the two f64 forms, make the same operations.
        let same32 = dp == 0.0;
        let _ = np;
        // Agreement of f32 and f64: the impulses after the same sweeps.
        let (mut d, mut n) = (0.0f64, 0.0f64);
        for (c64, c32) in q64.iter().zip(&g16) {
            let a: Vec<f64> = c64.iter().flat_map(|q| q.rn).collect();
            let b: Vec<f64> = c32.iter().flat_map(|g| g.rn.map(|x| x as f64)).collect();
            for (x, y) in a.iter().zip(&b) { d += (x - y) * (x - y); n += x * x; }
        }
        println!(
            "round {round}: {nb} bodies, {n_rows} rows; ns per row update: f64 octs {t64:.2}, f64 figures in rows {t64p:.2} (x{:.2}, same bits: {same}), f32 sixteens {t32:.2} (x{:.2}), f32 figures in rows {t32p:.2} (x{:.2}, same as f32 sixteens: {same32}); f32 impulses against f64, relative: {:.1e}",
            t64 / t64p, t64 / t32, t64 / t32p, (d / n).sqrt()
        );
    }
}
