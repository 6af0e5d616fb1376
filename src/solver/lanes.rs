//! How wide the colored sweeps update a color: the rows of a color share no movable body,
//! so on x86_64 several of them are updated at once in the lanes of vector registers
//! ([`super::simd`]), with the scalar update's result bit for bit: when the rows are
//! packed ([`super::quads`]), eight at a time in 512-bit registers on a processor with
//! AVX-512F, four at a time in AVX registers on one with AVX; two at a time in SSE2
//! registers (part of the baseline) otherwise. Elsewhere, row by row.

use super::ctx::Ctx;
use super::rows::Row;
#[cfg(target_arch = "x86_64")]
use super::simd;
#[cfg(not(target_arch = "x86_64"))]
use super::update::sweep_chunk;

/// How many rows the colored sweeps of this process update at once on packed rows: 8 with
/// AVX-512F, 4 with AVX (each checked once at run time), 2 in SSE2 (the x86_64 baseline),
/// 1 elsewhere. `CDLAB_NO_AVX=1` asks for the pairs and `CDLAB_NO_AVX512=1` for four at a
/// time (to time or compare them).
fn width() -> usize {
    #[cfg(target_arch = "x86_64")]
    {
        use std::sync::OnceLock;
        static WIDTH: OnceLock<usize> = OnceLock::new();
        *WIDTH.get_or_init(|| {
            let allowed = |off: &str| std::env::var_os(off).is_none_or(|v| v != "1");
            if !(std::arch::is_x86_feature_detected!("avx") && allowed("CDLAB_NO_AVX")) {
                2
            } else if std::arch::is_x86_feature_detected!("avx512f") && allowed("CDLAB_NO_AVX512") {
                8
            } else {
                4
            }
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    1
}

/// Whether the colored sweeps run (at least) four rows at a time ([`width`]).
pub(super) fn avx() -> bool {
    width() >= 4
}

/// Whether the packed quads are swept two at a time, eight rows in 512-bit registers
/// ([`width`]).
pub(super) fn avx512() -> bool {
    width() == 8
}

/// How the colored sweeps of this process update a color: "AVX-512, 8 contacts at a
/// time", "AVX, 4 contacts at a time", "SSE2, 2 contacts at a time" or "1 contact at a
/// time", or in single precision when asked (`CDLAB_SWEEPS_F32=1`,
/// `src/solver/single.rs`; its results differ from the others'). Named in the CPU
/// backend's description, which the runs record, so that timings from different
/// processors can be read side by side and a run says how it swept.
pub fn colored_lanes() -> &'static str {
    if super::single::enabled() {
        return "AVX-512 in f32 (CDLAB_SWEEPS_F32=1), 16 contacts at a time";
    }
    match width() {
        8 => "AVX-512, 8 contacts at a time",
        4 => "AVX, 4 contacts at a time",
        2 => "SSE2, 2 contacts at a time",
        _ => "1 contact at a time",
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

/// [`super::update::sweep_chunk`] for a chunk of one color (rows that share no movable
/// body and hold no [`FULL`](super::rows::FULL) row), with the same operations in the same
/// order as [`super::update::update`], so bit for bit the same result: when the rows are
/// packed ([`Ctx::quads`]), four at a time, then two, then the last row alone: the sweeps
/// are most of a step, and wider updates are what made them cheaper (docs/benchmarks.md,
/// "Vector sweeps").
///
/// # Safety
/// As [`super::update::update`], for every row of the chunk; no two rows share a movable
/// body; with `ctx.quads`, the chunk starts a packed quad (it is a chunk of
/// [`super::quads::pack_quads`]'s layout) and the processor has AVX.
pub(super) unsafe fn sweep_color_chunk(chunk: &mut [Row], ctx: Ctx) -> (f64, f64) {
    // SAFETY: forwarded from the caller.
    #[cfg(not(target_arch = "x86_64"))]
    return unsafe { sweep_chunk(chunk, ctx) };
    #[cfg(target_arch = "x86_64")]
    unsafe {
        sweep_lanes(chunk, ctx, avx512())
    }
}

/// [`sweep_color_chunk`], eight rows at a time first when `octs` (the caller checked
/// AVX-512F), then the packed quads, then pairs, then the last row.
///
/// # Safety
/// As [`sweep_color_chunk`]; with `octs`, the processor has AVX-512F.
#[cfg(target_arch = "x86_64")]
unsafe fn sweep_lanes(chunk: &mut [Row], ctx: Ctx, octs: bool) -> (f64, f64) {
    // SAFETY: forwarded from the caller.
    unsafe {
        if ctx.relax == 1.0 {
            sweep_widths::<false>(chunk, ctx, octs)
        } else {
            sweep_widths::<true>(chunk, ctx, octs)
        }
    }
}

/// [`sweep_lanes`] for one kind of update.
///
/// # Safety
/// As [`sweep_lanes`].
#[cfg(target_arch = "x86_64")]
unsafe fn sweep_widths<const RELAXED: bool>(chunk: &mut [Row], ctx: Ctx, octs: bool) -> (f64, f64) {
    let mut acc = (0.0, 0.0);
    let n4 = if ctx.quads { chunk.len() / 4 * 4 } else { 0 };
    let n8 = if octs { n4 / 8 * 8 } else { 0 };
    let (head, tail) = chunk.split_at_mut(n4);
    let (eights, fours) = head.split_at_mut(n8);
    // SAFETY: forwarded from the caller, who packed the rows and checked AVX for quads
    // and AVX-512F for eight at a time; a chunk starts a quad, so its first n8 rows are
    // whole quads.
    unsafe {
        if n8 > 0 {
            if ctx.frictionless {
                simd::sweep_octs::<RELAXED, false>(eights, ctx, &mut acc);
            } else {
                simd::sweep_octs::<RELAXED, true>(eights, ctx, &mut acc);
            }
        }
        if n4 > n8 {
            if ctx.frictionless {
                simd::sweep_quads::<RELAXED, false>(fours, ctx, &mut acc);
            } else {
                simd::sweep_quads::<RELAXED, true>(fours, ctx, &mut acc);
            }
        }
        simd::sweep_pairs::<RELAXED>(tail, ctx, &mut acc);
    }
    acc
}

#[cfg(test)]
pub(super) mod tests {
    use glam::DVec3;

    use super::*;
    use crate::solver::ctx::Line;
    use crate::solver::quads::{
        for_each_impulse, gather_packed, pack_quads, row_at, set_impulses, unpack_quads,
    };
    use crate::solver::rows::BodyProps;
    use crate::solver::update::{CHUNK, sweep_chunk};

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

    /// One color of `n` rows on `2n` movable disks (some that only spin) and 3 fixed walls
    /// shared by some rows, with impulses that are zero, inside the Coulomb interval or on
    /// its edge, and relative velocities that open, close or slide the contacts;
    /// `frictionless`, with `mu` and `R_t` +0 in every row (a frictionless compaction).
    pub(in crate::solver) fn color_of(
        n: usize,
        seed: u64,
        frictionless: bool,
    ) -> (Vec<Row>, Vec<Line>, Vec<BodyProps>) {
        let mut rng = Rng(seed);
        let bodies = 2 * n + 3;
        let gv: Vec<Line> = (0..bodies)
            .map(|_| Line::of(DVec3::new(rng.signed(), rng.signed(), 3.0 * rng.signed())))
            .collect();
        let props: Vec<BodyProps> = (0..bodies)
            .map(|b| {
                let (inv_mass, k, lever) = (0.5 + rng.next(), 2.0 * rng.next(), 0.1 + rng.next());
                // The walls cannot move; their lever still enters the relative velocity.
                // Some disks only spin: no inverse mass, but written all the same.
                if b < 2 * n && b % 13 == 5 {
                    BodyProps::of(0.0, k, lever)
                } else if b < 2 * n {
                    BodyProps::of(inv_mass, k, lever)
                } else {
                    BodyProps::of(0.0, 0.0, lever)
                }
            })
            .collect();
        let rows = (0..n)
            .map(|m| {
                let a = rng.next() * std::f64::consts::TAU;
                let mu = if frictionless {
                    0.0
                } else {
                    [0.0, 0.01, 0.3, 12.0][m % 4]
                };
                let rn = if m % 3 == 0 { 0.0 } else { rng.next() };
                let rt = match m % 5 {
                    // +0, as the frictionless sweeps require (`-mu * rn` would be -0).
                    _ if frictionless => 0.0,
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
        Octs,
    }

    /// The sums, velocities and impulses after three sweeps over the color, chunk by chunk
    /// as the Gauss-Seidel sweep goes.
    fn three_sweeps(n: usize, seed: u64, relax: f64, width: Width, frictionless: bool) -> Vec<u64> {
        let (mut rows, mut gv, props) = color_of(n, seed, frictionless);
        let ranges = [0, n as u32];
        let quads = matches!(width, Width::Quads | Width::Octs);
        if quads {
            pack_quads(&mut rows, &ranges, 1);
        }
        let ctx = Ctx {
            gv: gv.as_mut_ptr(),
            props: props.as_ptr(),
            contacts: std::ptr::null_mut(),
            relax,
            quads,
            frictionless: quads && frictionless,
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
                        Width::Pairs | Width::Quads => sweep_lanes(chunk, ctx, false),
                        Width::Octs => sweep_lanes(chunk, ctx, true),
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
        bits.extend(gv.iter().flat_map(|l| l.v.to_array()).map(f64::to_bits));
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
        for (has, width, note) in [
            (
                avx512(),
                Width::Octs,
                "no AVX-512F here (or CDLAB_NO_AVX512=1): eight rows at a time not compared",
            ),
            (
                avx(),
                Width::Quads,
                "no AVX here (or CDLAB_NO_AVX=1): packed quads not compared",
            ),
        ] {
            if has {
                widths.push(width);
            } else {
                // Past the test harness's capture (eprintln! shows only on failure), so
                // that a plain `cargo test` says which comparison did not run.
                let _ =
                    std::io::Write::write_all(&mut std::io::stderr(), format!("NOTE: {note}\n").as_bytes());
            }
        }
        for n in [1, 2, 3, 4, 5, 6, 7, 8, 9, 12, 15, 16, 17, 64, 67, 130] {
            // Without friction the packed sweeps take their normal-only form.
            for (relax, frictionless) in [(1.0, false), (0.5, false), (1.0, true), (0.5, true)] {
                let seed = 7 + n as u64;
                let reference = three_sweeps(n, seed, relax, Width::Rows, frictionless);
                assert!(reference.iter().any(|&b| b != 0), "{n} rows did nothing");
                for &w in &widths {
                    let other = three_sweeps(n, seed, relax, w, frictionless);
                    let first = reference.iter().zip(&other).position(|(a, b)| a != b);
                    assert_eq!(
                        first, None,
                        "{w:?}, {n} rows, relax {relax}, frictionless {frictionless}: first differing value"
                    );
                }
            }
        }
        let (rows, _, _) = color_of(67, 1, false);
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

    /// Packed rows read and written in place (as the solve keeps them for the deep updates
    /// and the store) equal the plain rows: every row read back, every row's body j and
    /// impulses in order, and impulses set on some rows change those rows only. Over colors
    /// with remainders, an empty color and a last range left plain (the serial group).
    #[test]
    fn packed_rows_read_and_written_in_place_equal_the_plain_rows() {
        let (rows, _, _) = color_of(67, 3, false);
        let (ranges, colors) = ([0, 13, 13, 40, 67], 3);
        let mut packed = rows.clone();
        pack_quads(&mut packed, &ranges, colors);
        // Gathered in an order and packed in one pass, as the solve copies its rows: the
        // bytes of a copy in that order packed afterwards.
        let order: Vec<u32> = (0..67).map(|m| (m * 29 % 67) as u32).collect();
        let mut copy: Vec<Row> = order.iter().map(|&k| rows[k as usize]).collect();
        pack_quads(&mut copy, &ranges, colors);
        let mut gathered = Vec::new();
        gather_packed(&rows, &order, &ranges, colors, &mut gathered);
        let bits = |rows: &[Row]| -> Vec<u64> {
            rows.iter()
                .flat_map(|r| {
                    let f = [
                        r.nx, r.ny, r.inv_wnn, r.inv_wtt, r.mu, r.bias_n, r.bias_t, r.rn, r.rt,
                    ];
                    std::iter::once(((r.i as u64) << 32) | r.j as u64).chain(f.map(f64::to_bits))
                })
                .collect()
        };
        assert_eq!(bits(&gathered), bits(&copy));
        for (m, r) in rows.iter().enumerate() {
            let got = row_at(&packed, &ranges, colors, m);
            assert_eq!(format!("{got:?}"), format!("{r:?}"), "row {m}");
        }
        let mut seen = Vec::new();
        for_each_impulse(&packed, &ranges, colors, |m, j, rn, rt| {
            seen.push((m, j, rn.to_bits(), rt.to_bits()))
        });
        let want: Vec<_> = (rows.iter().enumerate())
            .map(|(m, r)| (m, r.j, r.rn.to_bits(), r.rt.to_bits()))
            .collect();
        assert_eq!(seen, want);
        let set = [0, 5, 12, 13, 38, 39, 40, 66];
        for &m in &set {
            set_impulses(&mut packed, &ranges, colors, m, 1.5 + m as f64, -2.5);
        }
        unpack_quads(&mut packed, &ranges, colors);
        for (m, r) in rows.iter().enumerate() {
            let mut r = *r;
            if set.contains(&m) {
                (r.rn, r.rt) = (1.5 + m as f64, -2.5);
            }
            assert_eq!(format!("{:?}", packed[m]), format!("{r:?}"), "row {m}");
        }
    }
}
