//! The packed layout of the AVX sweeps: the rows of a color four at a time, field by
//! field, so that one instruction loads a field of four rows (docs/benchmarks.md, "Vector
//! sweeps").

use super::rows::Row;
use super::update::CHUNK;

/// Four rows laid out field by field in the bytes of four [`Row`]s.
#[derive(Clone, Copy, Default)]
#[repr(C)]
pub(super) struct Quad {
    pub(super) i: [u32; 4],
    pub(super) j: [u32; 4],
    pub(super) nx: [f64; 4],
    pub(super) ny: [f64; 4],
    pub(super) inv_wnn: [f64; 4],
    pub(super) inv_wtt: [f64; 4],
    pub(super) mu: [f64; 4],
    pub(super) bias_n: [f64; 4],
    pub(super) bias_t: [f64; 4],
    pub(super) rn: [f64; 4],
    pub(super) rt: [f64; 4],
}

const _: () = assert!(std::mem::size_of::<Quad>() == 4 * std::mem::size_of::<Row>());
const _: () = assert!(std::mem::align_of::<Quad>() <= std::mem::align_of::<Row>());
const _: () = assert!(CHUNK.is_multiple_of(4), "chunks must hold whole quads");

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
