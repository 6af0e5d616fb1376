//! Contact detection on a uniform cell grid (count, prefix sum, scatter; the same three
//! passes the GPU kernels run), and the construction of the contact records.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::{DVec2, DVec3};

use super::Contact;
use crate::error::{Error, Result};
use crate::model::{BodyKind, NOT_GLUED, Scene, WallDrive};
use crate::solver::color::{Coloring, Node, color};

/// A uniform grid of square cells holding disk indices, built by counting sort so that the
/// order of disks inside a cell is their index order (deterministic).
#[derive(Clone, Debug, Default)]
pub struct CellGrid {
    /// Lower-left corner of the grid (m).
    pub origin: DVec2,
    /// Cell side (m), at least the largest diameter plus the alert distance.
    pub cell: f64,
    /// Cells along x and y.
    pub dims: (usize, usize),
    /// `start[c]..start[c+1]` indexes `items` for cell `c`.
    pub start: Vec<u32>,
    /// Disk indices sorted by cell.
    pub items: Vec<u32>,
    /// Cell of each disk.
    pub cell_of: Vec<u32>,
}

impl CellGrid {
    /// Builds the grid for the given centres. `min_cell` must be at least the largest
    /// diameter plus the alert distance so that every candidate pair lies in adjacent cells.
    /// The cell is enlarged when needed to keep the number of cells proportional to the
    /// number of disks (a stray disk far away must not allocate a huge grid).
    pub fn build(&mut self, pos: &[DVec2], min_cell: f64) -> Result<()> {
        let n = pos.len();
        let mut lo = DVec2::splat(f64::INFINITY);
        let mut hi = DVec2::splat(f64::NEG_INFINITY);
        for (k, p) in pos.iter().enumerate() {
            if !p.is_finite() {
                return Err(Error::Numerical {
                    step: 0,
                    message: format!("disk {k} has a non-finite position {p}"),
                });
            }
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        if n == 0 {
            lo = DVec2::ZERO;
            hi = DVec2::ZERO;
        }
        let ext = hi - lo;
        let max_cells = 4.0 * n as f64 + 1024.0;
        let mut cell = min_cell;
        if (ext.x / cell + 1.0) * (ext.y / cell + 1.0) > max_cells {
            cell = ((ext.x * ext.y) / max_cells).sqrt().max(min_cell) * 1.5;
        }
        let nx = (ext.x / cell) as usize + 1;
        let ny = (ext.y / cell) as usize + 1;
        self.origin = lo;
        self.cell = cell;
        self.dims = (nx, ny);
        let nc = nx * ny;
        self.start.clear();
        self.start.resize(nc + 1, 0);
        self.cell_of.clear();
        for p in pos {
            let cx = (((p.x - lo.x) / cell) as usize).min(nx - 1);
            let cy = (((p.y - lo.y) / cell) as usize).min(ny - 1);
            let c = cy * nx + cx;
            self.cell_of.push(c as u32);
            self.start[c + 1] += 1;
        }
        for c in 0..nc {
            self.start[c + 1] += self.start[c];
        }
        self.items.clear();
        self.items.resize(n, 0);
        let mut fill = self.start.clone();
        for (k, &c) in self.cell_of.iter().enumerate() {
            let slot = &mut fill[c as usize];
            self.items[*slot as usize] = k as u32;
            *slot += 1;
        }
        Ok(())
    }

    /// Calls `f(q)` for every disk `q` in the 3x3 block of cells around disk `p`'s cell.
    #[inline]
    pub fn for_neighbours(&self, p: usize, mut f: impl FnMut(usize)) {
        let (nx, ny) = self.dims;
        let c = self.cell_of[p] as usize;
        let (cx, cy) = (c % nx, c / nx);
        for y in cy.saturating_sub(1)..(cy + 2).min(ny) {
            let row = y * nx;
            for x in cx.saturating_sub(1)..(cx + 2).min(nx) {
                let cc = row + x;
                for &q in &self.items[self.start[cc] as usize..self.start[cc + 1] as usize] {
                    f(q as usize);
                }
            }
        }
    }
}

/// The dynamic side of a disk in a contact: which generalized body carries its motion and
/// how an impulse moves it.
struct Side {
    body: u32,
    lever: f64,
    inv_mass: f64,
    axial: f64,
    axis: DVec2,
    k: f64,
}

fn disk_side(scene: &Scene, k: usize) -> Side {
    let d = &scene.disks;
    side(
        scene,
        k,
        d.radius[k],
        d.inv_mass[k],
        d.radius[k] * d.inv_inertia[k],
    )
}

/// [`disk_side`] from disk k's radius, inverse mass and `r / I` as given.
#[inline]
fn side(scene: &Scene, k: usize, radius: f64, inv_mass: f64, r_over_i: f64) -> Side {
    let d = &scene.disks;
    let g = d.glued_to[k];
    if g != NOT_GLUED {
        let w = &scene.walls[g as usize];
        // A glued disk moves rigidly with its wall and does not spin: its contacts act on
        // the wall's single degree of freedom (along the wall normal) when the wall is
        // force-driven.
        Side {
            body: (d.len() + g as usize) as u32,
            lever: 0.0,
            inv_mass: 0.0,
            axial: w.inv_mass(),
            axis: w.normal,
            k: 0.0,
        }
    } else {
        Side {
            body: k as u32,
            lever: radius,
            inv_mass,
            axial: 0.0,
            axis: DVec2::ZERO,
            k: r_over_i,
        }
    }
}

/// Finds every disk-disk and disk-wall pair whose gap is below `alert` (m) and returns the
/// contact records sorted by key, with frames, inverse masses, Delassus blocks and friction
/// filled in and impulses at zero. Pairs in which neither disk is free are skipped: no
/// impulse can change their motion.
///
/// This is the reference search over the whole grid; [`Neighbours::detect`] gives the same
/// records from a list of nearby pairs kept across steps.
pub fn detect(scene: &Scene, alert: f64, grid: &mut CellGrid, out: &mut Vec<Contact>) -> Result<()> {
    let d = &scene.disks;
    let r_max = d.radius.iter().cloned().fold(0.0, f64::max);
    grid.build(&d.pos, 2.0 * r_max + alert)?;
    emit_all(scene, alert, out, |p, partners| {
        grid.for_neighbours(p, |q| {
            if q > p {
                push_if_near(scene, p, q, alert, partners);
            }
        });
    });
    Ok(())
}

/// The gap and normal (from q to p) of disks p and q when they are within `alert` and at
/// least one of them is free.
#[inline]
fn near(scene: &Scene, p: usize, q: usize, alert: f64) -> Option<(f64, DVec2)> {
    let d = &scene.disks;
    near_at(&d.kind, p, q, alert, |k| (d.pos[k], d.radius[k]))
}

/// [`near`] with each disk's position and radius from `at`.
#[inline]
fn near_at(
    kind: &[BodyKind],
    p: usize,
    q: usize,
    alert: f64,
    at: impl Fn(usize) -> (DVec2, f64),
) -> Option<(f64, DVec2)> {
    if kind[p] != BodyKind::Free && kind[q] != BodyKind::Free {
        return None;
    }
    let ((xp, rp), (xq, rq)) = (at(p), at(q));
    let delta = xp - xq;
    let reach = rp + rq + alert;
    let dist2 = delta.length_squared();
    if dist2 < reach * reach && dist2 > 0.0 {
        let dist = dist2.sqrt();
        Some((dist - rp - rq, delta / dist))
    } else {
        None
    }
}

/// Adds `(q, gap, n)` to `partners` when disks p and q are within `alert` and at least one
/// of them is free.
#[inline]
fn push_if_near(scene: &Scene, p: usize, q: usize, alert: f64, partners: &mut Vec<(u32, f64, DVec2)>) {
    if let Some((gap, n)) = near(scene, p, q, alert) {
        partners.push((q as u32, gap, n));
    }
}

/// Builds the contact records disk by disk: `near(p, partners)` fills the disks q > p
/// within the alert distance of p; their contacts and then p's wall contacts are emitted.
fn emit_all(
    scene: &Scene,
    alert: f64,
    out: &mut Vec<Contact>,
    mut near: impl FnMut(usize, &mut Vec<(u32, f64, DVec2)>),
) {
    let d = &scene.disks;
    let nd = d.len();
    out.clear();
    let mu_disk = scene.material.mu_disk;
    let active: Vec<(usize, &crate::model::Wall)> =
        scene.walls.iter().enumerate().filter(|(_, w)| w.active).collect();
    // Contacts come out sorted by key without sorting or moving the (large) records: for
    // each disk p in order, its partners q > p sorted by index, then its walls (keys
    // n_disks + w are larger than any disk index). A pair whose disk p cannot move is keyed
    // (q, p) by its free disk q > p: it waits in a heap and is emitted when the loop
    // reaches q, before q's own pairs, whose partners are all larger than p. (Merging them
    // in at the end would move every record once per step.)
    let mut partners: Vec<(u32, f64, DVec2)> = Vec::with_capacity(32);
    let mut swapped: Vec<Contact> = Vec::new();
    let mut waiting: BinaryHeap<Reverse<(u64, u32)>> = BinaryHeap::new();
    for p in 0..nd {
        let free_p = d.kind[p] == BodyKind::Free;
        let (xp, rp) = (d.pos[p], d.radius[p]);
        while let Some(&Reverse((key, k))) = waiting.peek()
            && key >> 32 == p as u64
        {
            out.push(swapped[k as usize]);
            waiting.pop();
        }
        partners.clear();
        near(p, &mut partners);
        // The kept list gives them sorted already (1.4% of a 50,000-disk step went to
        // sorting them again); the grid search does not.
        if !partners.is_sorted_by_key(|e| e.0) {
            partners.sort_unstable_by_key(|e| e.0);
        }
        for &(q, gap, n) in &partners {
            let c = pair_contact(scene, p, q as usize, n, gap, mu_disk);
            if free_p {
                out.push(c);
            } else {
                waiting.push(Reverse((c.key(), swapped.len() as u32)));
                swapped.push(c);
            }
        }
        if !free_p {
            continue;
        }
        for &(w, wall) in &active {
            let gap = wall.distance(xp) - rp;
            if gap < alert {
                let c = wall_contact(scene, p, w, gap);
                out.push(c);
            }
        }
    }
    debug_assert!(
        waiting.is_empty(),
        "a swapped pair's free disk comes after its other disk"
    );
    debug_assert!(out.windows(2).all(|w| w[0].key() < w[1].key()));
}

/// A list of nearby pairs (a Verlet list) kept across steps: every disk pair, and every
/// free disk and active wall, closer than the alert distance plus a skin when the list was
/// built. It stays exact until some disk has moved half the skin from where it was then, or
/// a wall half the skin along its normal, so the grid search runs every few hundred steps
/// instead of every step; in between, a step only measures the listed pairs. Bodies glued,
/// freed or resized, and walls switched on, off or to another drive, rebuild it too.
///
/// The list also keeps what a pair's contact carries from one step to the next, so that
/// the step need not find it again: the impulses it had at the end of the last step (the
/// warm start, [`Neighbours::keep_impulses`]) and, for colored Gauss-Seidel, a coloring of
/// the whole list. Pairs that share no movable body share none in any subset either, so
/// a step's contacts come out of [`Neighbours::detect_kept`] already sorted by color, and
/// the solver neither colors nor reorders them (docs/benchmarks.md, "The kept list").
#[derive(Clone, Debug, Default)]
pub struct Neighbours {
    grid: CellGrid,
    /// The listed pairs: by key, or by color and then key.
    slots: Vec<Slot>,
    /// `slots[ranges[c]..ranges[c + 1]]` is color `c`; a single range when not colored.
    ranges: Vec<u32>,
    /// The last range holds the contacts with a force-driven wall ([`crate::solver::color::color`]).
    serial_last: bool,
    colored: bool,
    built: Built,
    coloring: Coloring,
    /// The slot of each contact of the last detection.
    emitted: Vec<u32>,
    /// Color ranges of the contacts of the last detection.
    contact_ranges: Vec<u32>,
    /// Where the next detection builds the list ([`Self::start_from`]).
    origin: Option<ListOrigin>,
    /// What emission reads of each disk, one cache line per disk ([`Line`]).
    lines: Vec<Line>,
    /// Grid searches made so far (the tests check that the list is both rebuilt and reused).
    pub rebuilds: u64,
}

/// The positions of the disks and the walls' points at which a kept pair list was built
/// ([`Neighbours::origin`]): with the scene, all it takes to build the same list again.
#[derive(Clone, Debug, PartialEq)]
pub struct ListOrigin {
    /// Disk positions (m).
    pub pos: Vec<DVec2>,
    /// Wall points (m), in the scene's wall order.
    pub wall_points: Vec<DVec2>,
}

/// What the kept list's emission reads of a disk, gathered in one 64-byte line per step:
/// read from the scene's arrays (position, radius, inverse mass, inverse inertia) and the
/// start-of-step velocities, a disk met in color order cost a cache miss in each
/// (docs/benchmarks.md, "One line per disk"); only its kind and glue, small arrays, are
/// still read where they lie. The values are copies, so the records are the same bit for
/// bit.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
struct Line {
    pos: DVec2,
    radius: f64,
    inv_mass: f64,
    /// `r / I`, as [`disk_side`] computes it.
    k: f64,
    /// Start-of-step velocity (vx, vy, spin).
    v: DVec3,
}

const _: () = assert!(std::mem::size_of::<Line>() == 64);

/// How many slots ahead the emission asks for its disks' lines: in color order each pair
/// meets two disks far from the last pair's, and the loads of one pair wait on memory
/// without this (docs/benchmarks.md, "One line per disk").
const AHEAD: usize = 12;

/// Asks the processor to bring `lines[k]` into the cache, if there is such a line.
#[inline(always)]
fn prefetch(lines: &[Line], k: usize) {
    #[cfg(target_arch = "x86_64")]
    if let Some(l) = lines.get(k) {
        // SAFETY: a prefetch only hints the cache; the address is that of a live line.
        unsafe {
            std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(
                (l as *const Line).cast::<i8>(),
            )
        };
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (lines, k);
}

/// What the list depends on, as it was when the list was built.
#[derive(Clone, Debug, Default)]
struct Built {
    pos: Vec<DVec2>,
    radius: Vec<f64>,
    kind: Vec<BodyKind>,
    glued_to: Vec<u32>,
    /// Point, normal, active, force-driven.
    walls: Vec<(DVec2, DVec2, bool, bool)>,
    alert: f64,
    skin: f64,
}

/// A listed pair and the impulses of its contact at the end of the last step (zero when
/// the pair was no contact then).
#[derive(Clone, Copy, Debug, Default)]
struct Slot {
    /// Disk p.
    p: u32,
    /// Disk q > p, or `n_disks + w` for wall w.
    q: u32,
    rn: f64,
    rt: f64,
}

impl Slot {
    /// The key of the pair's contact ([`Contact::key`]): keyed by its free disk.
    fn key(&self, kind: &[BodyKind]) -> u64 {
        let (p, q) = (self.p as u64, self.q as u64);
        let swapped = (q as usize) < kind.len() && kind[p as usize] != BodyKind::Free;
        if swapped { (q << 32) | p } else { (p << 32) | q }
    }
}

impl Neighbours {
    /// Same contract as [`detect`] (records by key, impulses at zero until
    /// [`Self::keep_impulses`] keeps some); `skin` (m) is the margin of the kept list.
    pub fn detect(&mut self, scene: &Scene, alert: f64, skin: f64, out: &mut Vec<Contact>) -> Result<()> {
        self.detect_kept(scene, alert, skin, false, None, out, &[], |_, _, _, _| {})
    }

    /// The contact records of the listed pairs closer than `alert`, in the list's order:
    /// by key, or with `colored` by color and then key ([`Self::contact_ranges`]). Each
    /// carries the impulses its pair kept from the last step, or, with `warm`, those of
    /// its key there (`(key, R_n, R_t)` sorted by key, e.g. from a checkpoint; zero for a
    /// key not listed). Impulses are those kept, not clamped to the friction cone.
    /// `each(k, contact, v_i, v_j)` sees contact `k` before it is stored, while it is in the
    /// cache (at 50,000 disks a pass over the 21 MB of records cost about a millisecond),
    /// with the start-of-step velocities of its bodies i and j taken from `velocities`
    /// (every body's, disks then walls; zero when `velocities` is empty).
    #[allow(clippy::too_many_arguments)]
    pub fn detect_kept(
        &mut self,
        scene: &Scene,
        alert: f64,
        skin: f64,
        colored: bool,
        warm: Option<&[(u64, f64, f64)]>,
        out: &mut Vec<Contact>,
        velocities: &[DVec3],
        each: impl FnMut(usize, &mut Contact, DVec3, DVec3),
    ) -> Result<()> {
        if let Some(o) = self.origin.take()
            && o.pos.len() == scene.disks.len()
            && o.wall_points.len() == scene.walls.len()
        {
            self.rebuild(scene, (&o.pos, &o.wall_points), (alert, skin), colored)?;
        }
        if self.stale(scene, alert, skin, colored) {
            let points: Vec<DVec2> = scene.walls.iter().map(|w| w.point).collect();
            self.rebuild(scene, (&scene.disks.pos, &points), (alert, skin), colored)?;
        }
        if let Some(w) = warm {
            self.load(&scene.disks.kind, w);
        }
        self.emit(scene, alert, out, velocities, each);
        Ok(())
    }

    /// Where the list was built, if it still serves `scene` with these settings: with the
    /// scene (and the same settings) this gives back the same list
    /// ([`Self::start_from`]), so that a checkpoint can hold it and a resumed run go on as
    /// this one. `None` when the next detection would build the list anyway.
    pub fn origin(&self, scene: &Scene, alert: f64, skin: f64, colored: bool) -> Option<ListOrigin> {
        // Not built yet since a start from an origin: that origin is still where it starts.
        if let Some(o) = &self.origin {
            return Some(o.clone());
        }
        (self.rebuilds > 0 && !self.stale(scene, alert, skin, colored)).then(|| ListOrigin {
            pos: self.built.pos.clone(),
            wall_points: self.built.walls.iter().map(|w| w.0).collect(),
        })
    }

    /// Makes the next detection start from the list built at `origin` (from
    /// [`Self::origin`]) with the scene it is then given, instead of from the scene's
    /// positions. It is ignored if its sizes are not the scene's.
    pub fn start_from(&mut self, origin: ListOrigin) {
        self.origin = Some(origin);
    }

    /// Each disk's inverse mass, `r / I` and radius as the last detection read them (the
    /// figures its records' sides carry), for the solver's body table
    /// (`crate::solver::sweep::Workspace::give_bodies`).
    pub fn disk_figures(&self) -> impl Iterator<Item = (f64, f64, f64)> + '_ {
        self.lines.iter().map(|l| (l.inv_mass, l.k, l.radius))
    }

    /// Color ranges of the last detection's contacts (`ranges[c]..ranges[c + 1]`), a
    /// single range when not colored; some may be empty.
    pub fn contact_ranges(&self) -> &[u32] {
        &self.contact_ranges
    }

    /// True when the last of [`Self::contact_ranges`] is the serial group: the contacts
    /// with a force-driven wall, which one thread sweeps in order.
    pub fn serial_last(&self) -> bool {
        self.serial_last
    }

    /// Keeps the impulses of `contacts` (the last detection's records, in its order) for
    /// the next step's warm start; `each` sees every contact in the same pass.
    pub fn keep_impulses(&mut self, contacts: &[Contact], mut each: impl FnMut(&Contact)) {
        assert_eq!(
            contacts.len(),
            self.emitted.len(),
            "not the last detection's contacts"
        );
        for (c, &s) in contacts.iter().zip(&self.emitted) {
            let slot = &mut self.slots[s as usize];
            slot.rn = c.rn;
            slot.rt = c.rt;
            each(c);
        }
    }

    /// The impulses kept, as `(key, R_n, R_t)` for the pairs with a normal impulse, by key.
    fn kept(&self) -> Vec<(u64, f64, f64)> {
        let mut k: Vec<(u64, f64, f64)> = self
            .slots
            .iter()
            .filter(|s| s.rn > 0.0)
            .map(|s| (s.key(&self.built.kind), s.rn, s.rt))
            .collect();
        k.sort_unstable_by_key(|e| e.0);
        k
    }

    /// Gives each slot the impulses of its key in `warm` (sorted by key), zero if absent.
    fn load(&mut self, kind: &[BodyKind], warm: &[(u64, f64, f64)]) {
        for s in &mut self.slots {
            let key = s.key(kind);
            (s.rn, s.rt) = match warm.binary_search_by_key(&key, |e| e.0) {
                Ok(m) => (warm[m].1, warm[m].2),
                Err(_) => (0.0, 0.0),
            };
        }
    }

    fn emit(
        &mut self,
        scene: &Scene,
        alert: f64,
        out: &mut Vec<Contact>,
        velocities: &[DVec3],
        mut each: impl FnMut(usize, &mut Contact, DVec3, DVec3),
    ) {
        let d = &scene.disks;
        let nd = d.len();
        let mu_disk = scene.material.mu_disk;
        let moving = velocities.len() == nd + scene.walls.len();
        self.lines.clear();
        self.lines.extend((0..nd).map(|k| Line {
            pos: d.pos[k],
            radius: d.radius[k],
            inv_mass: d.inv_mass[k],
            k: d.radius[k] * d.inv_inertia[k],
            v: if moving { velocities[k] } else { DVec3::ZERO },
        }));
        let lines = &self.lines[..];
        let at = |k: usize| (lines[k].pos, lines[k].radius);
        let side = |k: usize| {
            let l = &lines[k];
            side(scene, k, l.radius, l.inv_mass, l.k)
        };
        let velocity = |b: u32| match lines.get(b as usize) {
            Some(l) => l.v,
            None if moving => velocities[b as usize],
            None => DVec3::ZERO,
        };
        out.clear();
        self.emitted.clear();
        self.contact_ranges.clear();
        self.contact_ranges.push(0);
        for w in self.ranges.windows(2) {
            for s in w[0]..w[1] {
                if let Some(ahead) = self.slots.get(s as usize + AHEAD) {
                    prefetch(lines, ahead.p as usize);
                    prefetch(lines, ahead.q as usize);
                }
                let slot = &mut self.slots[s as usize];
                let (p, q) = (slot.p as usize, slot.q as usize);
                let found = if q >= nd {
                    let (x, r) = at(p);
                    let gap = scene.walls[q - nd].distance(x) - r;
                    (gap < alert).then(|| wall_contact_of(scene, side(p), q - nd, gap))
                } else {
                    near_at(&d.kind, p, q, alert, at)
                        .map(|(gap, n)| pair_contact_of(&d.kind, p, q, n, gap, mu_disk, side))
                };
                match found {
                    Some(mut c) => {
                        if slot.rn > 0.0 {
                            c.rn = slot.rn;
                            c.rt = slot.rt;
                        }
                        let (vi, vj) = (velocity(c.i), velocity(c.j));
                        each(out.len(), &mut c, vi, vj);
                        out.push(c);
                        self.emitted.push(s);
                    }
                    None => {
                        // A pair that parts loses its impulses: it starts from zero if it
                        // closes again, as a new contact would.
                        slot.rn = 0.0;
                        slot.rt = 0.0;
                    }
                }
            }
            self.contact_ranges.push(out.len() as u32);
        }
    }

    fn stale(&self, scene: &Scene, alert: f64, skin: f64, colored: bool) -> bool {
        let d = &scene.disks;
        let b = &self.built;
        if b.pos.len() != d.len()
            || b.alert != alert
            || b.skin != skin
            || self.colored != colored
            || b.radius != d.radius
            || b.kind != d.kind
            || b.glued_to != d.glued_to
            || b.walls.len() != scene.walls.len()
        {
            return true;
        }
        let half = 0.5 * skin;
        let wall_moved = scene
            .walls
            .iter()
            .zip(&b.walls)
            .any(|(w, &(point, normal, active, force))| {
                let moved = (w.point - point).dot(normal).abs();
                // A NaN position counts as moved.
                w.active != active
                    || w.normal != normal
                    || is_force(w) != force
                    || moved.is_nan()
                    || moved > half
            });
        if wall_moved {
            return true;
        }
        let limit2 = half * half;
        // Written so that a NaN position also counts as moved (the rebuild then reports it).
        d.pos.iter().zip(&b.pos).any(|(x, x0)| {
            let moved2 = (*x - *x0).length_squared();
            moved2.is_nan() || moved2 > limit2
        })
    }

    /// Builds the list for `scene` as if its disks and walls were at `at` (positions, wall
    /// points).
    fn rebuild(
        &mut self,
        scene: &Scene,
        at: (&[DVec2], &[DVec2]),
        (alert, skin): (f64, f64),
        colored: bool,
    ) -> Result<()> {
        let d = &scene.disks;
        let nd = d.len();
        let (pos, points) = at;
        // The impulses kept move to the new list by key (lost if the disks changed).
        let carried = if self.built.pos.len() == nd {
            self.kept()
        } else {
            Vec::new()
        };
        let r_max = d.radius.iter().cloned().fold(0.0, f64::max);
        let margin = alert + skin;
        self.grid.build(pos, 2.0 * r_max + margin)?;
        let mut slots = std::mem::take(&mut self.slots);
        slots.clear();
        let active: Vec<(usize, &crate::model::Wall)> =
            scene.walls.iter().enumerate().filter(|(_, w)| w.active).collect();
        for p in 0..nd {
            let (xp, rp) = (pos[p], d.radius[p]);
            self.grid.for_neighbours(p, |q| {
                let reach = rp + d.radius[q] + margin;
                if q > p && (xp - pos[q]).length_squared() < reach * reach {
                    slots.push(Slot {
                        p: p as u32,
                        q: q as u32,
                        ..Default::default()
                    });
                }
            });
            if d.kind[p] == BodyKind::Free {
                for &(w, wall) in &active {
                    if (xp - points[w]).dot(wall.normal) - rp < margin {
                        slots.push(Slot {
                            p: p as u32,
                            q: (nd + w) as u32,
                            ..Default::default()
                        });
                    }
                }
            }
        }
        slots.sort_unstable_by_key(|s| s.key(&d.kind));
        self.ranges.clear();
        self.ranges.push(0);
        self.serial_last = false;
        if colored {
            let nodes = slots.iter().map(|s| node(scene, s));
            color(nodes, nd + scene.walls.len(), &mut self.coloring);
            self.slots.clear();
            self.slots
                .extend(self.coloring.order.iter().map(|&k| slots[k as usize]));
            self.ranges.extend_from_slice(&self.coloring.ranges[1..]);
            self.serial_last = self.coloring.serial_last;
        } else {
            self.slots = slots;
            self.ranges.push(self.slots.len() as u32);
        }
        self.load(&d.kind, &carried);
        let b = &mut self.built;
        b.pos.clear();
        b.pos.extend_from_slice(pos);
        b.radius.clone_from(&d.radius);
        b.kind.clone_from(&d.kind);
        b.glued_to.clone_from(&d.glued_to);
        b.walls.clear();
        b.walls.extend(
            scene
                .walls
                .iter()
                .zip(points)
                .map(|(w, &point)| (point, w.normal, w.active, is_force(w))),
        );
        b.alert = alert;
        b.skin = skin;
        self.colored = colored;
        self.rebuilds += 1;
        Ok(())
    }
}

fn is_force(w: &crate::model::Wall) -> bool {
    matches!(w.drive, WallDrive::Force { .. })
}

/// A listed pair as the coloring sees its contact: the bodies an impulse acts on (a glued
/// disk's is its wall), which of them it can move, and whether it needs the serial group
/// (a force-driven wall moves along an axis oblique to the contact frame).
fn node(scene: &Scene, s: &Slot) -> Node {
    let d = &scene.disks;
    let nd = d.len();
    let (p, q) = (s.p as usize, s.q as usize);
    let moves = |side: &Side| side.inv_mass != 0.0 || side.k != 0.0 || side.axial != 0.0;
    if q >= nd {
        let si = disk_side(scene, p);
        let force = is_force(&scene.walls[q - nd]);
        return Node {
            i: si.body,
            j: q as u32,
            moves_i: moves(&si),
            moves_j: force,
            serial: force,
        };
    }
    let (a, b) = if d.kind[p] == BodyKind::Free {
        (p, q)
    } else {
        (q, p)
    };
    if d.kind[a] != BodyKind::Free {
        // Never a contact while the list lasts: no impulse can move either disk.
        return Node {
            i: a as u32,
            j: b as u32,
            moves_i: false,
            moves_j: false,
            serial: false,
        };
    }
    let (si, sj) = (disk_side(scene, a), disk_side(scene, b));
    Node {
        i: si.body,
        j: sj.body,
        moves_i: moves(&si),
        moves_j: moves(&sj),
        serial: sj.axial != 0.0,
    }
}

/// The record of the contact between free disk `p` and wall `w` at `gap` (m).
fn wall_contact(scene: &Scene, p: usize, w: usize, gap: f64) -> Contact {
    wall_contact_of(scene, disk_side(scene, p), w, gap)
}

/// [`wall_contact`] from the disk's side.
#[inline]
fn wall_contact_of(scene: &Scene, si: Side, w: usize, gap: f64) -> Contact {
    let wall = &scene.walls[w];
    let nd = scene.disks.len();
    let mut c = Contact {
        i: si.body,
        j: (nd + w) as u32,
        disk_j: (nd + w) as u32,
        n: wall.normal,
        gap,
        ri: si.lever,
        mi: si.inv_mass,
        ki: si.k,
        ma: if is_force(wall) { wall.inv_mass() } else { 0.0 },
        a: wall.normal,
        mu: scene.material.mu_wall,
        ..Default::default()
    };
    c.compute_delassus();
    c
}

/// The record of the contact between disks p and q (`n` from q to p, as [`near`] gives
/// it), with its free disk as body i: p when p is free, else q with the normal reversed.
#[inline]
fn pair_contact(scene: &Scene, p: usize, q: usize, n: DVec2, gap: f64, mu: f64) -> Contact {
    pair_contact_of(&scene.disks.kind, p, q, n, gap, mu, |k| disk_side(scene, k))
}

/// [`pair_contact`] with each disk's side from `side`.
#[inline]
fn pair_contact_of(
    kind: &[BodyKind],
    p: usize,
    q: usize,
    n: DVec2,
    gap: f64,
    mu: f64,
    side: impl Fn(usize) -> Side,
) -> Contact {
    if kind[p] == BodyKind::Free {
        make_contact(side(p), side(q), q, n, gap, mu)
    } else {
        make_contact(side(q), side(p), p, -n, gap, mu)
    }
}

/// The record of the contact between the disks of sides `si` and `sj` (disk `b`).
#[inline]
fn make_contact(si: Side, sj: Side, b: usize, n: DVec2, gap: f64, mu: f64) -> Contact {
    let mut c = Contact {
        i: si.body,
        j: sj.body,
        disk_j: b as u32,
        n,
        gap,
        ri: si.lever,
        rj: sj.lever,
        mi: si.inv_mass,
        mj: sj.inv_mass,
        ma: sj.axial,
        a: sj.axis,
        ki: si.k,
        kj: sj.k,
        mu,
        ..Default::default()
    };
    c.compute_delassus();
    c
}
