//! Contact detection on a uniform cell grid (count, prefix sum, scatter; the same three
//! passes the GPU kernels run), and the construction of the contact records.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::DVec2;

use super::Contact;
use crate::error::{Error, Result};
use crate::model::{BodyKind, NOT_GLUED, Scene, WallDrive};

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
            lever: d.radius[k],
            inv_mass: d.inv_mass[k],
            axial: 0.0,
            axis: DVec2::ZERO,
            k: d.radius[k] * d.inv_inertia[k],
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

/// Adds `(q, gap, n)` to `partners` when disks p and q are within `alert` and at least one
/// of them is free.
#[inline]
fn push_if_near(scene: &Scene, p: usize, q: usize, alert: f64, partners: &mut Vec<(u32, f64, DVec2)>) {
    let d = &scene.disks;
    if d.kind[p] != BodyKind::Free && d.kind[q] != BodyKind::Free {
        return;
    }
    let delta = d.pos[p] - d.pos[q];
    let reach = d.radius[p] + d.radius[q] + alert;
    let dist2 = delta.length_squared();
    if dist2 < reach * reach && dist2 > 0.0 {
        let dist = dist2.sqrt();
        partners.push((q as u32, dist - d.radius[p] - d.radius[q], delta / dist));
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
            let q = q as usize;
            if free_p {
                out.push(make_contact(scene, p, q, n, gap, mu_disk));
            } else {
                let c = make_contact(scene, q, p, -n, gap, mu_disk);
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
                let si = disk_side(scene, p);
                let mut c = Contact {
                    i: si.body,
                    j: (nd + w) as u32,
                    disk_j: (nd + w) as u32,
                    n: wall.normal,
                    gap,
                    ri: si.lever,
                    mi: si.inv_mass,
                    ki: si.k,
                    ma: if matches!(wall.drive, WallDrive::Force { .. }) {
                        wall.inv_mass()
                    } else {
                        0.0
                    },
                    a: wall.normal,
                    mu: scene.material.mu_wall,
                    ..Default::default()
                };
                c.compute_delassus();
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

/// A list of nearby disk pairs (a Verlet list) kept across steps: every pair closer than
/// the alert distance plus a skin when the list was built. It stays exact until some disk
/// has moved half the skin from where it was then, so the grid search runs every few
/// hundred steps instead of every step; in between, a step only measures the listed pairs.
/// The records are the same, bit for bit and in the same order, as [`detect`]'s.
#[derive(Clone, Debug, Default)]
pub struct Neighbours {
    grid: CellGrid,
    /// `pairs[start[p]..start[p + 1]]`: the disks q > p near p, by increasing index.
    start: Vec<u32>,
    pairs: Vec<u32>,
    built_at: Vec<DVec2>,
    radius: Vec<f64>,
    alert: f64,
    skin: f64,
    /// Grid searches made so far (the tests check that the list is both rebuilt and reused).
    pub rebuilds: u64,
}

impl Neighbours {
    /// Same contract as [`detect`]; `skin` (m) is the margin of the kept list.
    pub fn detect(&mut self, scene: &Scene, alert: f64, skin: f64, out: &mut Vec<Contact>) -> Result<()> {
        if self.stale(scene, alert, skin) {
            self.rebuild(scene, alert, skin)?;
        }
        let (start, pairs) = (&self.start, &self.pairs);
        emit_all(scene, alert, out, |p, partners| {
            for &q in &pairs[start[p] as usize..start[p + 1] as usize] {
                push_if_near(scene, p, q as usize, alert, partners);
            }
        });
        Ok(())
    }

    fn stale(&self, scene: &Scene, alert: f64, skin: f64) -> bool {
        let d = &scene.disks;
        if self.built_at.len() != d.len()
            || self.alert != alert
            || self.skin != skin
            || self.radius != d.radius
        {
            return true;
        }
        let limit2 = 0.25 * skin * skin;
        // Written so that a NaN position also counts as moved (the rebuild then reports it).
        d.pos.iter().zip(&self.built_at).any(|(x, x0)| {
            let moved2 = (*x - *x0).length_squared();
            moved2.is_nan() || moved2 > limit2
        })
    }

    fn rebuild(&mut self, scene: &Scene, alert: f64, skin: f64) -> Result<()> {
        let d = &scene.disks;
        let r_max = d.radius.iter().cloned().fold(0.0, f64::max);
        let margin = alert + skin;
        self.grid.build(&d.pos, 2.0 * r_max + margin)?;
        self.start.clear();
        self.pairs.clear();
        self.start.push(0);
        for p in 0..d.len() {
            let first = self.pairs.len();
            let (xp, rp) = (d.pos[p], d.radius[p]);
            let pairs = &mut self.pairs;
            self.grid.for_neighbours(p, |q| {
                let reach = rp + d.radius[q] + margin;
                if q > p && (xp - d.pos[q]).length_squared() < reach * reach {
                    pairs.push(q as u32);
                }
            });
            self.pairs[first..].sort_unstable();
            self.start.push(self.pairs.len() as u32);
        }
        self.built_at.clone_from(&d.pos);
        self.radius.clone_from(&d.radius);
        self.alert = alert;
        self.skin = skin;
        self.rebuilds += 1;
        Ok(())
    }
}

fn make_contact(scene: &Scene, a: usize, b: usize, n: DVec2, gap: f64, mu: f64) -> Contact {
    let si = disk_side(scene, a);
    let sj = disk_side(scene, b);
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
