//! Geometric deposition (docs/protocol.md, "Deposition"): disks placed one at a time, each at the
//! lowest position where it rests on two supports (two disks, a disk and a side wall, a disk
//! and the floor, or the floor and a wall) without overlap, reachable from above: its centre
//! lies on the upper envelope of the pile's top chain dilated by its radius. No dynamics.
//!
//! The top chain is kept as the list of disks exposed from above (sorted by x); candidate
//! positions are the pairwise tangent points of nearby chain members, so each placement
//! costs O(chain length) and a deposit of n disks O(n sqrt(n)).

use glam::DVec2;

use crate::error::{Error, Result, check_positive};

/// A deposited packing in the box `[0, width] x [0, inf)`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Packing {
    /// Disk centres (m).
    pub centers: Vec<DVec2>,
    /// Disk radii (m).
    pub radii: Vec<f64>,
    /// Box width (m).
    pub width: f64,
    /// Height of the highest disk top (m).
    pub height: f64,
}

/// Relative tolerance of contact: supports may touch within `TOUCH * r` but never overlap
/// by more.
const TOUCH: f64 = 1e-9;

/// Places the disks of `radii`, in order, into a box of the given width.
pub fn deposit(radii: &[f64], width: f64) -> Result<Packing> {
    check_positive("deposition width", width)?;
    let r_max = radii.iter().cloned().fold(0.0, f64::max);
    let r_min = radii.iter().cloned().fold(f64::INFINITY, f64::min);
    if radii.is_empty() || r_min.is_nan() || r_min <= 0.0 {
        return Err(Error::invalid(
            "radii",
            r_min,
            "need at least one disk, all radii > 0",
        ));
    }
    if width <= 2.0 * r_max {
        return Err(Error::invalid(
            "deposition width",
            width,
            &format!("must exceed the largest diameter {}", 2.0 * r_max),
        ));
    }
    let mut pk = Packing {
        width,
        ..Default::default()
    };
    // Chain: indices of exposed disks, sorted by centre x.
    let mut chain: Vec<usize> = Vec::new();
    let mut grid = Columns::new(width, 2.0 * r_max);
    let mut profile = Profile::new(width, 0.5 * r_min);
    for &r in radii {
        let c = best_position(&pk, &chain, &grid, r, r_max);
        let k = pk.centers.len();
        grid.insert(c, k);
        pk.centers.push(c);
        pk.radii.push(r);
        pk.height = pk.height.max(c.y + r);
        let at = chain.partition_point(|&j| pk.centers[j].x < c.x);
        chain.insert(at, k);
        profile.add(c, r);
        prune(&pk, &mut chain, &profile, k, 3.0 * r_max, r_max);
    }
    Ok(pk)
}

/// Height of the centre of a disk of radius `r` resting on disk `k` at abscissa `x`, or
/// -inf when `x` is out of its reach.
#[inline]
fn arc(pk: &Packing, k: usize, r: f64, x: f64) -> f64 {
    let d = pk.radii[k] + r;
    let dx = x - pk.centers[k].x;
    let s = d * d - dx * dx;
    if s <= 0.0 {
        f64::NEG_INFINITY
    } else {
        pk.centers[k].y + s.sqrt()
    }
}

/// Chain members whose dilated arc can reach abscissa `x` (|dx| < r_k + r): a window of the
/// sorted chain.
fn window<'a>(pk: &Packing, chain: &'a [usize], x: f64, reach: f64) -> &'a [usize] {
    let lo = chain.partition_point(|&j| pk.centers[j].x < x - reach);
    let hi = chain.partition_point(|&j| pk.centers[j].x <= x + reach);
    &chain[lo..hi]
}

/// True when a disk of radius `r` at `c` overlaps no chain disk (beyond the touch
/// tolerance). Positions beside a larger disk, below its equator, are allowed: a falling
/// disk slides along its support into them.
fn free_at(pk: &Packing, chain: &[usize], c: DVec2, r: f64, r_max: f64) -> bool {
    window(pk, chain, c.x, r + r_max).iter().all(|&k| {
        let d = pk.radii[k] + r;
        (pk.centers[k] - c).length_squared() >= d * d * (1.0 - 2.0 * TOUCH)
    })
}

/// The lowest admissible centre for a disk of radius `r` (ties broken by smaller x).
fn best_position(pk: &Packing, chain: &[usize], grid: &Columns, r: f64, r_max: f64) -> DVec2 {
    let (x_lo, x_hi) = (r, pk.width - r);
    let mut best = DVec2::new(f64::INFINITY, f64::INFINITY);
    let mut consider = |c: DVec2| {
        if c.y < r - TOUCH * r || c.x < x_lo - TOUCH * r || c.x > x_hi + TOUCH * r || !c.is_finite() {
            return;
        }
        if (c.y, c.x) < (best.y, best.x) && free_at(pk, chain, c, r, r_max) && !grid.overlaps(pk, c, r) {
            best = c;
        }
    };
    // Floor and a wall.
    consider(DVec2::new(x_lo, r));
    consider(DVec2::new(x_hi, r));
    for (ia, &a) in chain.iter().enumerate() {
        let (ca, ra) = (pk.centers[a], pk.radii[a] + r);
        // A disk and a side wall.
        for x in [x_lo, x_hi] {
            let y = arc(pk, a, r, x);
            consider(DVec2::new(x, y));
        }
        // A disk and the floor.
        let dy = ca.y - r;
        if ra * ra > dy * dy {
            let dx = (ra * ra - dy * dy).sqrt();
            consider(DVec2::new(ca.x - dx, r));
            consider(DVec2::new(ca.x + dx, r));
        }
        // Two disks: the upper intersection of the dilated circles.
        for &b in &chain[ia + 1..] {
            let (cb, rb) = (pk.centers[b], pk.radii[b] + r);
            let d = cb - ca;
            if d.x > ra + rb {
                break;
            }
            let l2 = d.length_squared();
            if l2 >= (ra + rb) * (ra + rb) || l2 <= (ra - rb) * (ra - rb) {
                continue;
            }
            let l = l2.sqrt();
            let along = (ra * ra - rb * rb + l2) / (2.0 * l);
            let h = (ra * ra - along * along).max(0.0).sqrt();
            let u = d / l;
            let perp = DVec2::new(-u.y, u.x);
            let p = ca + along * u;
            let c = if perp.y >= 0.0 { p + h * perp } else { p - h * perp };
            consider(c);
        }
    }
    debug_assert!(best.is_finite(), "the floor always offers a position");
    best
}

/// Surface height profile: the highest disk top over each bin of width `bin` (m).
struct Profile {
    bin: f64,
    top: Vec<f64>,
}

impl Profile {
    fn new(width: f64, bin: f64) -> Self {
        Profile {
            bin,
            top: vec![0.0; (width / bin) as usize + 1],
        }
    }

    fn bins(&self, x0: f64, x1: f64) -> std::ops::Range<usize> {
        let lo = ((x0 / self.bin).max(0.0) as usize).min(self.top.len() - 1);
        let hi = ((x1 / self.bin).max(0.0) as usize).min(self.top.len() - 1);
        lo..hi + 1
    }

    fn add(&mut self, c: DVec2, r: f64) {
        for b in self.bins(c.x - r, c.x + r) {
            let dx = ((b as f64 + 0.5) * self.bin - c.x).clamp(-r, r);
            let h = c.y + (r * r - dx * dx).sqrt();
            self.top[b] = self.top[b].max(h);
        }
    }

    /// Lowest surface height over `[x0, x1]`.
    fn lowest(&self, x0: f64, x1: f64) -> f64 {
        self.bins(x0, x1)
            .map(|b| self.top[b])
            .fold(f64::INFINITY, f64::min)
    }
}

/// Removes from the chain the disks near the new disk `k` that lie deeper than `depth`
/// below the surface everywhere over their span. Every placement fills the lowest
/// reachable point, so the surface never holds pockets that deep and such disks can no
/// longer support anything; shallower disks stay (a member too many only costs time).
fn prune(pk: &Packing, chain: &mut Vec<usize>, profile: &Profile, k: usize, depth: f64, r_max: f64) {
    let xk = pk.centers[k].x;
    let reach = pk.radii[k] + 2.0 * r_max;
    let lo = chain.partition_point(|&j| pk.centers[j].x < xk - reach);
    let hi = chain.partition_point(|&j| pk.centers[j].x <= xk + reach);
    let mut keep = Vec::with_capacity(hi - lo);
    for &j in &chain[lo..hi] {
        let (c, r) = (pk.centers[j], pk.radii[j]);
        if j == k || c.y + r >= profile.lowest(c.x - r, c.x + r) - depth {
            keep.push(j);
        }
    }
    chain.splice(lo..hi, keep);
}

/// A uniform grid of all placed disks (square cells of one largest diameter), for the exact
/// overlap test of a candidate: the chain is pruned by a sampled test, so a disk that left
/// it may still border a pocket.
struct Columns {
    cell: f64,
    nx: usize,
    rows: Vec<Vec<Vec<usize>>>,
}

impl Columns {
    fn new(width: f64, cell: f64) -> Self {
        Columns {
            cell,
            nx: (width / cell) as usize + 1,
            rows: Vec::new(),
        }
    }

    fn coords(&self, c: DVec2) -> (usize, usize) {
        (
            ((c.x / self.cell).max(0.0) as usize).min(self.nx - 1),
            (c.y / self.cell).max(0.0) as usize,
        )
    }

    fn insert(&mut self, c: DVec2, k: usize) {
        let (x, y) = self.coords(c);
        while self.rows.len() <= y {
            self.rows.push(vec![Vec::new(); self.nx]);
        }
        self.rows[y][x].push(k);
    }

    fn overlaps(&self, pk: &Packing, c: DVec2, r: f64) -> bool {
        let (x, y) = self.coords(c);
        for row in self.rows.iter().take(y + 2).skip(y.saturating_sub(1)) {
            for cell in &row[x.saturating_sub(1)..(x + 2).min(self.nx)] {
                for &k in cell {
                    let d = pk.radii[k] + r;
                    if (pk.centers[k] - c).length_squared() < d * d * (1.0 - 2.0 * TOUCH) {
                        return true;
                    }
                }
            }
        }
        false
    }
}
