//! The deepest disk pairs of a snapshot: where a run's largest overlap sits, how much force
//! the pair carries and whether it is still closing. Used to tell a contact that closed
//! within a step (a time step too large) from one sinking slowly under load (the solver's
//! residual; docs/results.md, "Overlaps at high friction").

use crate::record::Snapshot;

/// One overlapping disk pair of a snapshot.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PairOverlap {
    /// First disk.
    pub i: u32,
    /// Second disk.
    pub j: u32,
    /// Midpoint of the two centres (m).
    pub x_m: f64,
    /// See `x_m`.
    pub y_m: f64,
    /// Overlap `r_i + r_j - |x_i - x_j|` over the smallest radius of the snapshot.
    pub overlap_rel: f64,
    /// Normal force (N/m).
    pub f_n: f64,
    /// Normal force over the mean of the snapshot's positive normal forces (NaN when none
    /// carries force).
    pub f_n_rel: f64,
    /// Normal relative velocity `(v_i - v_j) . n` (m/s; negative: still closing).
    pub u_n: f64,
}

/// The `top` deepest overlapping disk pairs among the snapshot's contacts, deepest first.
/// Disk-wall contacts are left out: a snapshot does not hold the walls' positions.
pub fn deepest_pairs(snap: &Snapshot, top: usize) -> Vec<PairOverlap> {
    let d = &snap.disks;
    let r_min = d.iter().map(|k| k.r).fold(f64::INFINITY, f64::min);
    let loaded: Vec<f64> = snap.contacts.iter().map(|c| c.f_n).filter(|&f| f > 0.0).collect();
    let mean = loaded.iter().sum::<f64>() / loaded.len() as f64;
    let mut pairs: Vec<PairOverlap> = snap
        .contacts
        .iter()
        .filter(|c| (c.i as usize) < d.len() && (c.j as usize) < d.len())
        .filter_map(|c| {
            let (a, b) = (&d[c.i as usize], &d[c.j as usize]);
            let (dx, dy) = (a.x - b.x, a.y - b.y);
            let dist = dx.hypot(dy);
            let overlap = a.r + b.r - dist;
            (overlap > 0.0 && dist > 0.0).then(|| PairOverlap {
                i: c.i,
                j: c.j,
                x_m: 0.5 * (a.x + b.x),
                y_m: 0.5 * (a.y + b.y),
                overlap_rel: overlap / r_min,
                f_n: c.f_n,
                f_n_rel: c.f_n / mean,
                u_n: ((a.vx - b.vx) * dx + (a.vy - b.vy) * dy) / dist,
            })
        })
        .collect();
    pairs.sort_by(|p, q| q.overlap_rel.total_cmp(&p.overlap_rel));
    pairs.truncate(top);
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::{ContactRecord, DiskRecord};

    /// Three disks of radius 1 m (and one of 0.5 m, the smallest radius) on the x axis:
    /// pair 0-1 overlaps by 0.01 m (2% of r_min 0.5 m) and closes at 0.2 m/s, pair 1-2 by
    /// 0.002 m, pair 2-3 has a gap. The expected values follow from the positions.
    #[test]
    fn the_deepest_pair_comes_first_with_its_force_and_closing_speed() {
        let disk = |x: f64, vx: f64, r: f64| DiskRecord {
            x,
            vx,
            r,
            ..Default::default()
        };
        let snap = Snapshot {
            disks: vec![
                disk(0.0, 0.1, 1.0),
                disk(1.99, -0.1, 1.0),
                disk(3.988, 0.0, 1.0),
                disk(5.6, 0.0, 0.5),
            ],
            contacts: vec![
                ContactRecord {
                    i: 1,
                    j: 2,
                    nx: -1.0,
                    f_n: 1.0,
                    ..Default::default()
                },
                ContactRecord {
                    i: 0,
                    j: 1,
                    nx: -1.0,
                    f_n: 3.0,
                    ..Default::default()
                },
                ContactRecord {
                    i: 2,
                    j: 3,
                    nx: -1.0,
                    f_n: 0.0,
                    ..Default::default()
                },
                // A wall contact (j = n_disks + wall): not a pair.
                ContactRecord {
                    i: 0,
                    j: 4,
                    nx: 1.0,
                    f_n: 2.0,
                    ..Default::default()
                },
            ],
            ..Default::default()
        };
        let p = deepest_pairs(&snap, 5);
        assert_eq!(p.len(), 2, "{p:?}");
        assert_eq!((p[0].i, p[0].j), (0, 1));
        assert!((p[0].overlap_rel - 0.02).abs() < 1e-12, "{p:?}");
        // Mean positive force (1 + 3 + 2) / 3 = 2 N/m.
        assert!((p[0].f_n_rel - 1.5).abs() < 1e-12, "{p:?}");
        // v_0 - v_1 = 0.2 m/s along +x, n from 1 to 0 along -x: closing at 0.2 m/s.
        assert!((p[0].u_n + 0.2).abs() < 1e-12, "{p:?}");
        assert!((p[0].x_m - 0.995).abs() < 1e-12);
        assert_eq!((p[1].i, p[1].j), (1, 2));
        assert!((p[1].overlap_rel - 0.004).abs() < 1e-9, "{p:?}");
        assert_eq!(deepest_pairs(&snap, 1).len(), 1);
    }
}
