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

impl Quad {
    /// Row `l` (0 to 3) of the four.
    fn lane(&self, l: usize) -> Row {
        Row {
            i: self.i[l],
            j: self.j[l],
            nx: self.nx[l],
            ny: self.ny[l],
            inv_wnn: self.inv_wnn[l],
            inv_wtt: self.inv_wtt[l],
            mu: self.mu[l],
            bias_n: self.bias_n[l],
            bias_t: self.bias_t[l],
            rn: self.rn[l],
            rt: self.rt[l],
        }
    }
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
/// sweeps; [`unpack_quads`] undoes it. A solve that colors packs as it copies into color
/// order ([`gather_packed`]); one given contacts in color order packs as it builds the rows
/// ([`push_quad`]).
#[cfg(test)]
pub(super) fn pack_quads(rows: &mut [Row], ranges: &[u32], colors: usize) {
    for k in quads_of(ranges, colors) {
        let r: [Row; 4] = rows[k..k + 4].try_into().expect("four rows");
        let q = packed(&r);
        // SAFETY: a Quad fills the bytes of four rows exactly and needs no more alignment
        // (asserted above); the four rows are in bounds.
        unsafe { rows.as_mut_ptr().add(k).cast::<Quad>().write(q) };
    }
}

/// Appends four rows packed field by field ([`Quad`]).
#[inline]
pub(super) fn push_quad(rows: &mut Vec<Row>, r: &[Row; 4]) {
    let k = rows.len();
    rows.reserve(4);
    // SAFETY: the capacity holds rows k..k + 4; a Quad fills the bytes of four rows exactly
    // and needs no more alignment (asserted above), and any bytes are valid rows.
    unsafe {
        rows.as_mut_ptr().add(k).cast::<Quad>().write(packed(r));
        rows.set_len(k + 4);
    }
}

/// Copies `rows[order[m]]` into `out[m]` for every `m`, the whole quads of the first
/// `colors` ranges packed field by field ([`Quad`]): one pass for what was a copy and then
/// a packing pass.
pub(super) fn gather_packed(rows: &[Row], order: &[u32], ranges: &[u32], colors: usize, out: &mut Vec<Row>) {
    let n = order.len();
    assert!(
        ranges.last().is_none_or(|&e| e as usize <= n),
        "ranges beyond the rows"
    );
    out.clear();
    out.reserve(n);
    let slots = &mut out.spare_capacity_mut()[..n];
    let row = |m: usize| rows[order[m] as usize];
    let mut m = 0;
    for k in quads_of(ranges, colors) {
        for (s, a) in slots[m..k].iter_mut().zip(m..k) {
            s.write(row(a));
        }
        let q = packed(&[row(k), row(k + 1), row(k + 2), row(k + 3)]);
        // SAFETY: a Quad fills the bytes of four rows exactly and needs no more alignment
        // (asserted above); slots k..k + 4 lie within the n reserved (the ranges end by n).
        unsafe { slots[k..k + 4].as_mut_ptr().cast::<Quad>().write(q) };
        m = k + 4;
    }
    for (s, a) in slots[m..].iter_mut().zip(m..n) {
        s.write(row(a));
    }
    // SAFETY: every slot below n was written: the quads' slots and those before, between and
    // after them.
    unsafe { out.set_len(n) };
}

/// Four rows field by field.
fn packed(r: &[Row; 4]) -> Quad {
    Quad {
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
    }
}

/// Where row `m` of rows packed by [`gather_packed`] with these ranges lies: the first row of
/// its quad and its lane, or `None` when it is stored as a plain [`Row`].
fn lane_of(ranges: &[u32], colors: usize, m: usize) -> Option<(usize, usize)> {
    let c = ranges.partition_point(|&x| x as usize <= m).checked_sub(1)?;
    if c >= colors || c + 1 >= ranges.len() {
        return None;
    }
    let (a, b) = (ranges[c] as usize, ranges[c + 1] as usize);
    (m < a + (b - a) / 4 * 4).then(|| (a + (m - a) / 4 * 4, (m - a) % 4))
}

/// Row `m` of rows packed by [`gather_packed`] with these ranges, as a plain [`Row`].
pub(super) fn row_at(rows: &[Row], ranges: &[u32], colors: usize, m: usize) -> Row {
    let Some((k, l)) = lane_of(ranges, colors, m) else {
        return rows[m];
    };
    assert!(k + 4 <= rows.len(), "a quad beyond the rows");
    // SAFETY: rows k..k + 4 hold a packed quad (in bounds, asserted).
    let q = unsafe { rows.as_ptr().add(k).cast::<Quad>().read() };
    q.lane(l)
}

/// Sets the impulses of row `m` of rows packed by [`gather_packed`] with these ranges.
pub(super) fn set_impulses(rows: &mut [Row], ranges: &[u32], colors: usize, m: usize, rn: f64, rt: f64) {
    let Some((k, l)) = lane_of(ranges, colors, m) else {
        rows[m].rn = rn;
        rows[m].rt = rt;
        return;
    };
    assert!(k + 4 <= rows.len(), "a quad beyond the rows");
    // SAFETY: rows k..k + 4 hold a packed quad (in bounds, asserted).
    let q = unsafe { &mut *rows.as_mut_ptr().add(k).cast::<Quad>() };
    q.rn[l] = rn;
    q.rt[l] = rt;
}

/// Calls `f(m, j, rn, rt)` for every row `m` of rows packed by [`gather_packed`] with these
/// ranges, in order, reading the packed quads where they lie: what the solve keeps of its
/// rows, without unpacking them (a pass that rewrote every row, 0.6 ms a step at 50,000
/// disks).
pub(super) fn for_each_impulse(
    rows: &[Row],
    ranges: &[u32],
    colors: usize,
    mut f: impl FnMut(usize, u32, f64, f64),
) {
    let mut m = 0;
    for k in quads_of(ranges, colors) {
        for r in &rows[m..k] {
            f(m, r.j, r.rn, r.rt);
            m += 1;
        }
        assert!(k + 4 <= rows.len(), "a quad beyond the rows");
        // SAFETY: rows k..k + 4 hold a packed quad (in bounds, asserted).
        let q = unsafe { rows.as_ptr().add(k).cast::<Quad>().read() };
        for l in 0..4 {
            f(k + l, q.j[l], q.rn[l], q.rt[l]);
        }
        m = k + 4;
    }
    for r in &rows[m..] {
        f(m, r.j, r.rn, r.rt);
        m += 1;
    }
}

/// Undoes [`pack_quads`] with the same ranges (the tests compare packed and plain rows).
#[cfg(test)]
pub(super) fn unpack_quads(rows: &mut [Row], ranges: &[u32], colors: usize) {
    for k in quads_of(ranges, colors) {
        // SAFETY: as in `pack_quads`; these rows hold a packed quad.
        let q = unsafe { rows.as_ptr().add(k).cast::<Quad>().read() };
        for (l, r) in rows[k..k + 4].iter_mut().enumerate() {
            *r = q.lane(l);
        }
    }
}
