//! Rows: the compact copy of the contacts that the Gauss-Seidel sweeps work on, the table
//! of body properties they refer to, and the parking of open candidates.
//!
//! The full [`Contact`] is 192 bytes, three cache lines, and 10,000 of them do not fit in
//! a core's L2 cache. A row keeps only what an update reads and writes (80 bytes), and the
//! inverse masses and lever arms live once per body in a small table: the update is most
//! of a step's time (docs/benchmarks.md, "Compact rows").

use glam::DVec3;

use super::quads::push_quad;
use crate::contact::Contact;

/// Marks a row whose contact needs the full 2x2 law (body j translates along an axis
/// oblique to the contact frame: a force-driven wall); `i` then holds the contact's index.
pub(super) const FULL: u32 = u32::MAX;

/// The part of a contact that a Gauss-Seidel update touches.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C)]
pub(super) struct Row {
    pub(super) i: u32,
    pub(super) j: u32,
    pub(super) nx: f64,
    pub(super) ny: f64,
    /// `1 / W_nn` and `1 / W_tt` (0 for a direction in which neither body can move).
    pub(super) inv_wnn: f64,
    pub(super) inv_wtt: f64,
    pub(super) mu: f64,
    pub(super) bias_n: f64,
    pub(super) bias_t: f64,
    pub(super) rn: f64,
    pub(super) rt: f64,
}

/// What a body contributes to an update: inverse mass (twice: the factors of an impulse's
/// x and y components), `r / I` (spin change per unit tangential impulse) and lever arm,
/// in the order of a velocity's [`Line`](super::ctx::Line), so that one vector multiply of
/// an impulse's `(p_x, p_y, dR_t, 0)` gives a body's whole velocity change
/// ([`super::simd`]).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(32))]
pub(super) struct BodyProps {
    pub(super) inv_mass: f64,
    inv_mass_y: f64,
    pub(super) k: f64,
    pub(super) lever: f64,
}

impl BodyProps {
    /// The entry of a disk with inverse mass `inv_mass`, `r / I` `k` and radius `lever`,
    /// as a contact's side gives it ([`Contact::moves_i`]); a wall's entry is the default.
    pub(super) fn of(inv_mass: f64, k: f64, lever: f64) -> Self {
        BodyProps {
            inv_mass,
            inv_mass_y: inv_mass,
            k,
            lever,
        }
    }

    /// Whether an impulse may change the body's velocity (as [`Contact::moves_i`] says of
    /// a contact's side); the updates never write a body that cannot move.
    #[inline(always)]
    pub(super) fn movable(&self) -> bool {
        self.inv_mass != 0.0 || self.k != 0.0
    }
}

fn inverse(w: f64) -> f64 {
    if w > 0.0 { 1.0 / w } else { 0.0 }
}

/// Where [`build`] leaves out the open rows that
/// [`SolverParams::open_skip`](super::SolverParams::open_skip) keeps out of the sweeps: a
/// candidate without impulse whose `U_n + bias_n` at the velocities `gv` exceeds
/// `open_skip` goes to `parked`, and `active` lists the contact index of every row kept.
pub(super) struct Parking<'a> {
    pub(super) gv: &'a [DVec3],
    pub(super) open_skip: f64,
    pub(super) active: &'a mut Vec<u32>,
    pub(super) parked: &'a mut Vec<Row>,
}

/// The rows of the contacts, in their order (less the parked ones with `parking`), and the
/// table of body properties they refer to; `deep` lists the contacts with a diagonal block
/// that overlap by more than `deep_gap` (m), in order. With `colors`, the rows' color
/// ranges are written beside the contacts' ([`ColorRows`]) and the rows of its first
/// colors packed four at a time as they are built. One pass over the contacts: at 50,000
/// disks each pass over the rows or the contacts leaves the cache. Returns whether every
/// row kept (less the [`FULL`] ones) has `mu` and `R_t` +0 ([`super::ctx::Ctx::frictionless`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn build(
    contacts: &[Contact],
    n_bodies: usize,
    deep_gap: f64,
    rows: &mut Vec<Row>,
    mut props: Option<&mut Vec<BodyProps>>,
    deep: &mut Vec<u32>,
    mut parking: Option<Parking>,
    colors: Option<ColorRows>,
) -> bool {
    deep.clear();
    // Without a table to fill, the one given for the step ([`BodyProps::of`]) serves.
    if let Some(p) = props.as_mut() {
        p.clear();
        p.resize(n_bodies, BodyProps::default());
    }
    rows.clear();
    if let Some(p) = parking.as_mut() {
        p.active.clear();
        p.parked.clear();
    }
    let whole = [0, contacts.len() as u32];
    let (ranges, packed, mut row_ranges, mut figures) = match colors {
        Some(c) => (c.ranges, c.packed, Some(c.out), c.figures),
        None => (&whole[..], 0, None, None),
    };
    if let Some(f) = figures.as_mut() {
        f.clear();
    }
    // Both bodies' figures of each row kept, from the record at hand: read from the body
    // table instead, they would cost a scattered read per row and body.
    let mut figure = |c: &Contact| {
        if let Some(f) = figures.as_mut() {
            f.push([c.mi, c.ki, c.ri, c.mj, c.kj, c.rj].map(|x| x as f32));
        }
    };
    let mut quad = Quad4::default();
    // Bit patterns, so that -0 (and NaN) count as friction: the sweeps' shortcut rests on
    // the +0 of both.
    let mut frictionless = true;
    let mut keep = |r: &Row| frictionless &= r.j == FULL || (r.mu.to_bits() | r.rt.to_bits()) == 0;
    assert!(
        ranges.last().is_some_and(|&e| e as usize == contacts.len()),
        "color ranges that do not cover the contacts"
    );
    if let Some(out) = row_ranges.as_mut() {
        out.clear();
        out.push(0);
    }
    for (color, w) in ranges.windows(2).enumerate() {
        let (a, b) = (w[0] as usize, w[1] as usize);
        let pack = color < packed;
        for (k, c) in (a..b).zip(&contacts[a..b]) {
            let r = row(
                k,
                c,
                n_bodies,
                deep_gap,
                props.as_deref_mut().map(|p| &mut p[..]),
                deep,
            );
            match parking.as_mut() {
                Some(p) if r.j != FULL && r.rn == 0.0 && r.rt == 0.0 && opening(&r, p.gv) > p.open_skip => {
                    p.parked.push(r)
                }
                Some(p) => {
                    p.active.push(k as u32);
                    keep(&r);
                    figure(c);
                    quad.push(rows, r, pack);
                }
                None => {
                    keep(&r);
                    figure(c);
                    quad.push(rows, r, pack)
                }
            }
        }
        // A color's last rows that make no four stay plain, as `quads::pack_quads` leaves them.
        quad.flush(rows);
        if let Some(out) = row_ranges.as_mut() {
            out.push(rows.len() as u32);
        }
    }
    frictionless
}

/// What [`build`] does with colored contacts: `ranges` are the contacts' color ranges, the
/// rows' go to `out` (empty colors included), and the rows of the first `packed` colors are
/// packed four at a time from each color's first row ([`super::quads::Quad`]). With
/// `figures`, each row kept gets its bodies' inverse mass, `r / I` and lever (body i's, then
/// body j's) in `f32` there, in row order, for the `f32` sweeps ([`super::single`]).
pub(super) struct ColorRows<'a> {
    pub(super) ranges: &'a [u32],
    pub(super) packed: usize,
    pub(super) out: &'a mut Vec<u32>,
    pub(super) figures: Option<&'a mut Vec<[f32; 6]>>,
}

/// Up to three rows waiting for a fourth, to be packed with it.
#[derive(Default)]
struct Quad4 {
    pending: [Row; 4],
    n: usize,
}

impl Quad4 {
    #[inline]
    fn push(&mut self, rows: &mut Vec<Row>, r: Row, pack: bool) {
        if !pack {
            rows.push(r);
            return;
        }
        self.pending[self.n] = r;
        self.n += 1;
        if self.n == 4 {
            push_quad(rows, &self.pending);
            self.n = 0;
        }
    }

    fn flush(&mut self, rows: &mut Vec<Row>) {
        rows.extend_from_slice(&self.pending[..self.n]);
        self.n = 0;
    }
}

/// The row of contact `k` (and its bodies' properties, and `k` in `deep` when deeper than
/// `deep_gap`).
#[inline]
fn row(
    k: usize,
    c: &Contact,
    n_bodies: usize,
    deep_gap: f64,
    props: Option<&mut [BodyProps]>,
    deep: &mut Vec<u32>,
) -> Row {
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
    if c.gap < -deep_gap {
        deep.push(k as u32);
    }
    // Every contact of a body sees the same inverse mass, r / I and lever (detection
    // takes them from the body), so later contacts only rewrite the same values.
    if let Some(props) = props {
        props[c.i as usize] = BodyProps::of(c.mi, c.ki, c.ri);
        props[c.j as usize] = BodyProps::of(c.mj, c.kj, c.rj);
    }
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
}

/// The contact of swept row `m`: row `m` is row `order[m]` (or `m` without an order) of the
/// swept rows, which belongs to contact `active[..]` of that (or to the contact of the same
/// index when every contact was swept).
pub(super) fn contact_of(m: usize, order: Option<&[u32]>, active: Option<&[u32]>) -> usize {
    let k = order.map_or(m, |o| o[m] as usize);
    active.map_or(k, |a| a[k] as usize)
}

/// `U_n + bias_n` of a row at the velocities `gv`: the local law gives the row a normal
/// impulse from zero only when this is negative.
pub(super) fn opening(r: &Row, gv: &[DVec3]) -> f64 {
    let (vi, vj) = (gv[r.i as usize], gv[r.j as usize]);
    (vi.x - vj.x) * r.nx + (vi.y - vj.y) * r.ny + r.bias_n
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three contacts among four disks, without friction or impulse.
    fn contacts() -> Vec<Contact> {
        (0..3)
            .map(|k| Contact {
                i: k,
                j: k + 1,
                disk_j: k + 1,
                n: glam::DVec2::X,
                wnn: 2.0,
                wtt: 3.0,
                mi: 1.0,
                mj: 1.0,
                ..Default::default()
            })
            .collect()
    }

    fn frictionless(contacts: &[Contact]) -> bool {
        let (mut rows, mut deep) = (Vec::new(), Vec::new());
        build(contacts, 4, f64::INFINITY, &mut rows, None, &mut deep, None, None)
    }

    /// The figures kept beside the rows are, row by row, those of the body table the same
    /// build fills (what the `f32` sweeps read instead of the table), parked rows left out of
    /// both.
    #[test]
    fn the_rows_figures_are_the_body_table_s() {
        let mut contacts = contacts();
        // Each body's own figures, as detection gives every contact of the body.
        let of = |b: u32| (1.0 + b as f64, 0.5 + b as f64, 0.25 * (b + 1) as f64);
        for c in contacts.iter_mut() {
            (c.mi, c.ki, c.ri) = of(c.i);
            (c.mj, c.kj, c.rj) = of(c.j);
        }
        // Contact 1 opens fast: parked.
        contacts[1].bias_n = 1.0;
        let gv = vec![DVec3::ZERO; 4];
        let (mut rows, mut deep, mut props) = (Vec::new(), Vec::new(), Vec::new());
        let (mut active, mut parked, mut out, mut figures) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        build(
            &contacts,
            4,
            f64::INFINITY,
            &mut rows,
            Some(&mut props),
            &mut deep,
            Some(Parking {
                gv: &gv,
                open_skip: 0.5,
                active: &mut active,
                parked: &mut parked,
            }),
            Some(ColorRows {
                ranges: &[0, 3],
                packed: 0,
                out: &mut out,
                figures: Some(&mut figures),
            }),
        );
        assert_eq!((rows.len(), parked.len()), (2, 1), "rows kept and parked");
        assert_eq!(figures.len(), rows.len());
        for (r, f) in rows.iter().zip(&figures) {
            let (bi, bj) = (props[r.i as usize], props[r.j as usize]);
            let want = [bi.inv_mass, bi.k, bi.lever, bj.inv_mass, bj.k, bj.lever].map(|x| x as f32);
            assert_eq!(*f, want, "row on bodies {} and {}", r.i, r.j);
        }
    }

    /// The packed sweeps' normal-only form rests on `mu` and `R_t` being +0 in every row
    /// swept: a -0, a friction or an impulse anywhere turns it off; a full-block row,
    /// which the serial group sweeps with the full law, does not.
    #[test]
    fn frictionless_only_when_every_swept_row_has_zero_friction_and_tangential_impulse() {
        let plain = contacts();
        assert!(frictionless(&plain));
        type Edit = fn(&mut Contact);
        let edits: [(&str, Edit); 4] = [
            ("R_t -0", |c| c.rt = -0.0),
            ("R_t", |c| c.rt = 1e-9),
            ("mu", |c| c.mu = 0.3),
            ("mu -0", |c| c.mu = -0.0),
        ];
        for (what, edit) in edits {
            let mut c = plain.clone();
            edit(&mut c[2]);
            assert!(!frictionless(&c), "{what} in the last row went unseen");
        }
        let mut full = plain.clone();
        full[1].ma = 1.0;
        full[1].mu = 0.3;
        assert!(frictionless(&full), "a full-block row counted");
    }
}
