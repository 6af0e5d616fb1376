//! Reduced quantities of a run: what the protocol measures without downloading the state.
//! The GPU path computes the same sums in its reduction kernels; this is their reference.

use glam::DVec2;

use super::Loading;
use crate::contact::Contact;
use crate::engine::StepStats;
use crate::model::{BodyKind, Scene};

pub use crate::measure::micro::FORCE_THRESHOLD;

/// Relative tolerance on `|T| = mu N` for a sliding contact: sliding when
/// `|T| >= mu N (1 - SLIDE_EPS)` (dimensionless).
pub const SLIDE_EPS: f64 = 1e-6;

/// A contact's class (docs/method.md, "Contact classification").
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[repr(u8)]
pub enum ContactClass {
    /// Candidate whose gap is open (beyond the zero-gap tolerance) and carries nothing.
    Open = 0,
    /// Geometric contact (gap within tolerance of zero or overlapping) without force.
    ZeroForce = 1,
    /// Force-carrying, `|T| < mu N (1 - eps)`.
    Rolling = 2,
    /// Force-carrying, `|T| >= mu N (1 - eps)`.
    Sliding = 3,
}

impl ContactClass {
    /// The class with this code (its `u8` value), if any.
    pub fn from_u8(code: u8) -> Option<Self> {
        [Self::Open, Self::ZeroForce, Self::Rolling, Self::Sliding]
            .into_iter()
            .find(|c| *c as u8 == code)
    }
}

/// Gap below which a contact without force counts as a geometric (zero-force) contact:
/// 1e-4 of the smallest radius (m), well above the solver's positional round-off and well
/// below the alert distance.
pub fn zero_gap_tolerance(scene: &Scene) -> f64 {
    1e-4 * scene.disks.radius.iter().cloned().fold(f64::INFINITY, f64::min)
}

/// Classifies one contact (force threshold absolute here: `rn > 0`; the relative threshold
/// is applied by [`Accumulator::finish`]).
pub fn classify(c: &Contact, gap_tol: f64) -> ContactClass {
    if c.rn > 0.0 {
        if c.rt.abs() >= c.mu * c.rn * (1.0 - SLIDE_EPS) {
            ContactClass::Sliding
        } else {
            ContactClass::Rolling
        }
    } else if c.gap <= gap_tol {
        ContactClass::ZeroForce
    } else {
        ContactClass::Open
    }
}

/// What a backend reports after a run of steps.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Reductions {
    /// Simulated time at the end (s).
    pub time: f64,
    /// Step count at the end.
    pub step: u64,
    /// Steps in this run.
    pub steps: u32,
    /// Force exerted by the contacts on each wall, glued disks included, averaged over the
    /// run's steps (N/m).
    pub wall_force: Vec<DVec2>,
    /// Wall positions at the end (a point on each wall, m).
    pub wall_point: Vec<DVec2>,
    /// Candidate contacts at the last step (disk-disk and disk-wall).
    pub candidates: u32,
    /// Force-carrying disk-disk contacts.
    pub force_carrying: u32,
    /// Force-carrying disk-disk contacts that stick (rolling).
    pub rolling: u32,
    /// Force-carrying disk-disk contacts at the Coulomb limit (sliding).
    pub sliding: u32,
    /// Disk-disk geometric contacts without force.
    pub zero_force: u32,
    /// Coordination number `Z = 2 N_c / N'` (N' disks with two or more force-carrying
    /// contacts, walls included in their count).
    pub coordination: f64,
    /// Fraction of free disks with fewer than two force-carrying contacts.
    pub isolated_fraction: f64,
    /// Mean overlap over overlapping contacts (m, >= 0).
    pub overlap_mean: f64,
    /// Largest overlap (m).
    pub overlap_max: f64,
    /// Kinetic energy of the free disks at the end (J/m).
    pub kinetic_energy: f64,
    /// Translational part of the kinetic energy (J/m).
    pub translational_energy: f64,
    /// Translational kinetic energy of the free disks with two or more force-carrying
    /// contacts (J/m): the rattlers left out.
    pub connected_energy: f64,
    /// Mean centre x of the left and right strips (m); NaN without strips.
    pub strip_mean_x: [f64; 2],
    /// Outer edges of the left and right strips (m), see [`strip_outer_edges`]; NaN
    /// without strips.
    pub strip_edges: [f64; 2],
    /// Solver iterations summed over the run's steps.
    pub iterations_sum: u64,
    /// Largest iteration count of a step.
    pub iterations_max: u32,
    /// Steps whose solver hit the iteration cap.
    pub capped_steps: u32,
    /// Mean number of colors per step (0 unless colored).
    pub colors_mean: f64,
    /// Contacts given local updates after the iterations, summed over the steps.
    pub deep_sum: u64,
    /// Sums over the last step's contacts for the micromechanical measures
    /// ([`crate::measure::micro::MicroSums`]; forces in N/m).
    #[serde(default)]
    pub micro: crate::measure::micro::MicroSums,
}

/// Sums over the steps of one run.
pub struct Accumulator {
    red: Reductions,
    impulse: Vec<DVec2>,
    colors: u64,
}

impl Accumulator {
    /// Starts a run on `scene`.
    pub fn new(scene: &Scene) -> Self {
        Accumulator {
            red: Reductions::default(),
            impulse: vec![DVec2::ZERO; scene.walls.len()],
            colors: 0,
        }
    }

    /// Adds one step's solver statistics and wall impulses.
    pub fn add_step(&mut self, stats: &StepStats, wall_impulse: &[DVec2]) {
        let r = &mut self.red;
        r.steps += 1;
        r.iterations_sum += stats.solve.iterations as u64;
        r.iterations_max = r.iterations_max.max(stats.solve.iterations);
        r.capped_steps += !stats.solve.converged as u32;
        r.deep_sum += stats.solve.deep as u64;
        self.colors += stats.solve.colors as u64;
        for (a, b) in self.impulse.iter_mut().zip(wall_impulse) {
            *a += b;
        }
    }

    /// Completes the reductions from the final state and contacts.
    pub fn finish(mut self, scene: &Scene, contacts: &[Contact], dt: f64, loading: &Loading) -> Reductions {
        let r = &mut self.red;
        let d = &scene.disks;
        let nd = d.len();
        r.time = scene.time;
        r.step = scene.step;
        let steps = r.steps.max(1) as f64;
        r.wall_force = self.impulse.iter().map(|p| *p / (steps * dt)).collect();
        r.wall_point = scene.walls.iter().map(|w| w.point).collect();
        r.colors_mean = self.colors as f64 / steps;
        r.candidates = contacts.len() as u32;
        let gap_tol = zero_gap_tolerance(scene);
        let loaded: Vec<f64> = contacts.iter().filter(|c| c.rn > 0.0).map(|c| c.rn).collect();
        let mean_rn = loaded.iter().sum::<f64>() / loaded.len().max(1) as f64;
        let threshold = FORCE_THRESHOLD * mean_rn;
        let mut per_disk = vec![0u32; nd];
        let (mut n_ov, mut sum_ov) = (0u32, 0.0);
        for c in contacts {
            if c.gap < 0.0 {
                n_ov += 1;
                sum_ov += -c.gap;
                r.overlap_max = r.overlap_max.max(-c.gap);
            }
            let j = c.disk_j as usize;
            let disk_disk = j < nd;
            let carrying = c.rn > threshold;
            if carrying {
                per_disk[c.i as usize] += 1;
                if disk_disk {
                    per_disk[j] += 1;
                }
            }
            if !disk_disk {
                continue;
            }
            match classify(c, gap_tol) {
                _ if !carrying && c.gap <= gap_tol => r.zero_force += 1,
                ContactClass::Rolling if carrying => r.rolling += 1,
                ContactClass::Sliding if carrying => r.sliding += 1,
                _ => {}
            }
        }
        r.force_carrying = r.rolling + r.sliding;
        // Same force-carrying criterion as the counts above (the mean over every loaded
        // contact), so `micro.n_force` equals `force_carrying`.
        r.micro = crate::measure::micro::MicroSums::of(&crate::measure::micro::from_solver(
            contacts, &d.radius, dt,
        ));
        r.overlap_mean = if n_ov > 0 { sum_ov / n_ov as f64 } else { 0.0 };
        let free: Vec<usize> = (0..nd).filter(|&k| d.kind[k] == BodyKind::Free).collect();
        let connected = free.iter().filter(|&&k| per_disk[k] >= 2).count();
        r.coordination = if connected > 0 {
            2.0 * r.force_carrying as f64 / connected as f64
        } else {
            0.0
        };
        r.isolated_fraction = if free.is_empty() {
            0.0
        } else {
            1.0 - connected as f64 / free.len() as f64
        };
        r.kinetic_energy = d.kinetic_energy();
        r.translational_energy = d.translational_energy();
        r.connected_energy = free
            .iter()
            .filter(|&&k| per_disk[k] >= 2)
            .map(|&k| 0.5 * d.mass[k] * d.vel[k].length_squared())
            .sum();
        let mut sx = [0.0f64; 2];
        let mut cnt = [0u32; 2];
        for (k, &s) in loading.strip.iter().enumerate() {
            if s != 0 {
                let side = (s > 0) as usize;
                sx[side] += d.pos[k].x;
                cnt[side] += 1;
            }
        }
        r.strip_edges = strip_outer_edges(scene, loading);
        r.strip_mean_x = [0, 1].map(|s| {
            if cnt[s] > 0 {
                sx[s] / cnt[s] as f64
            } else {
                f64::NAN
            }
        });
        self.red
    }
}

/// Outer edges of the two strips (m): the mean over heights of the `Outline` of the
/// left-strip and of the right-strip disks, over the heights crossed by both strips. The
/// sample width `right - left` times the wall distance is the area between the outer edges
/// of the strips and the walls (docs/protocol.md, "Width and volume").
///
/// The outline moves continuously with the disks. An earlier estimator took the extreme
/// `x -+ r` of the disks in bands one largest diameter high: a disk passing from one band
/// into another, or a band emptying, made the volumetric strain of a 300-disk test jump
/// by 0.02 (about the whole dilation of the test).
pub fn strip_outer_edges(scene: &Scene, loading: &Loading) -> [f64; 2] {
    if loading.strip.is_empty() {
        return [f64::NAN; 2];
    }
    let Some(o) = Outline::of(scene, loading.bottom, loading.top, |k| loading.strip[k]) else {
        return [f64::NAN; 2];
    };
    let (mut sl, mut sr, mut m) = (0.0, 0.0, 0usize);
    for (l, r) in o.left.iter().zip(&o.right) {
        if l.is_finite() && r.is_finite() {
            sl += l;
            sr += r;
            m += 1;
        }
    }
    if m == 0 {
        [f64::NAN; 2]
    } else {
        [sl / m as f64, sr / m as f64]
    }
}

/// The left and right outlines of a set of disks at heights `y0 + (i + 1/2) h` between the
/// bottom and the top wall, `h` about `r_min / 2`: at each height the smallest
/// `x - sqrt(r^2 - (y - y_k)^2)` over the left-side disks the horizontal line crosses, and
/// the largest `x + ...` over the right-side disks (infinite where no disk is crossed).
struct Outline {
    y0: f64,
    h: f64,
    left: Vec<f64>,
    right: Vec<f64>,
}

impl Outline {
    /// The outline of the disks `side(k)` puts on a side (-1 left, +1 right, 0 neither);
    /// `None` when the walls do not bound a finite height.
    fn of(scene: &Scene, bottom: usize, top: usize, side: impl Fn(usize) -> i8) -> Option<Outline> {
        let d = &scene.disks;
        let y0 = scene.walls[bottom].point.y;
        let y1 = scene.walls[top].point.y;
        let r_min = d.radius.iter().cloned().fold(f64::INFINITY, f64::min);
        let n = ((y1 - y0) / (0.5 * r_min)).ceil().clamp(16.0, 65_536.0);
        if !n.is_finite() {
            return None;
        }
        let n = n as usize;
        let h = (y1 - y0) / n as f64;
        let mut left = vec![f64::INFINITY; n];
        let mut right = vec![f64::NEG_INFINITY; n];
        for k in 0..d.len() {
            let s = side(k);
            if s == 0 {
                continue;
            }
            let (c, r) = (d.pos[k], d.radius[k]);
            // Heights y_i = y0 + (i + 1/2) h within [c.y - r, c.y + r].
            let first = ((c.y - r - y0) / h - 0.5).ceil().max(0.0) as usize;
            let last = ((c.y + r - y0) / h - 0.5).floor().min(n as f64 - 1.0);
            if last < 0.0 {
                continue;
            }
            for i in first..=last as usize {
                let dy = y0 + (i as f64 + 0.5) * h - c.y;
                let half = (r * r - dy * dy).max(0.0).sqrt();
                if s < 0 {
                    left[i] = left[i].min(c.x - half);
                } else {
                    right[i] = right[i].max(c.x + half);
                }
            }
        }
        Some(Outline { y0, h, left, right })
    }
}

/// The deformable-wall strips of a sample: -1 for a free disk whose centre lies within
/// `thickness` of the sample's left edge at its height, +1 within `thickness` of the right
/// edge, 0 otherwise (glued and other non-free disks included). The edge at a height is
/// the outermost point of the outline of all free disks within `thickness / 2` above or
/// below it, so it follows a bulging or sheared side rather than the sample's extreme.
///
/// The strips are a place, not a set of disks: a disk that the flow carries deeper than
/// `thickness` into the sample stops carrying the confinement and one that comes near the
/// side starts. With strips fixed as sets of disks, each strip disk pushes its own share of
/// sigma3 x H inwards wherever it goes, and in a near-frictionless sample the strips sank
/// into the core while core disks rose past them (an overturn like a heavy fluid over a
/// light one); at contact friction 0.01 the released work drove the kinetic energy up by
/// four orders of magnitude and the samples came apart.
pub fn strip_members(scene: &Scene, bottom: usize, top: usize, thickness: f64) -> Vec<i8> {
    let d = &scene.disks;
    let free = |k: usize| d.kind[k] == BodyKind::Free;
    let (Some(l), Some(r)) = (
        Outline::of(scene, bottom, top, |k| -(free(k) as i8)),
        Outline::of(scene, bottom, top, |k| free(k) as i8),
    ) else {
        return vec![0; d.len()];
    };
    let n = l.left.len();
    let reach = (0.5 * thickness / l.h).ceil() as usize;
    let window = |i: usize| i.saturating_sub(reach)..(i + reach + 1).min(n);
    let edge_l: Vec<f64> = (0..n)
        .map(|i| l.left[window(i)].iter().cloned().fold(f64::INFINITY, f64::min))
        .collect();
    let edge_r: Vec<f64> = (0..n)
        .map(|i| {
            r.right[window(i)]
                .iter()
                .cloned()
                .fold(f64::NEG_INFINITY, f64::max)
        })
        .collect();
    (0..d.len())
        .map(|k| {
            if !free(k) {
                return 0;
            }
            let c = d.pos[k];
            let i = ((c.y - l.y0) / l.h).floor().clamp(0.0, n as f64 - 1.0) as usize;
            if c.x < edge_l[i] + thickness {
                -1
            } else if c.x > edge_r[i] - thickness {
                1
            } else {
                0
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Wall;
    use glam::DVec2;

    /// Two columns of touching disks of radius r at x = -a and x = +a between walls at
    /// y = 0 and y = 2 r m: the mean half-chord of a disk over heights spread uniformly
    /// across it is pi r / 4, so the edges are -a - pi r / 4 and a + pi r / 4.
    fn columns(r: f64, a: f64, m: usize) -> (Scene, Loading) {
        let mut s = Scene::default();
        let mut strip = Vec::new();
        for (x, side) in [(-a, -1i8), (a, 1)] {
            for k in 0..m {
                s.disks
                    .push(DVec2::new(x, r + 2.0 * r * k as f64), r, 2600.0)
                    .unwrap();
                strip.push(side);
            }
        }
        s.walls = vec![
            Wall::fixed(DVec2::ZERO, DVec2::Y),
            Wall::fixed(DVec2::new(0.0, 2.0 * r * m as f64), -DVec2::Y),
        ];
        let loading = Loading {
            strip,
            bottom: 0,
            top: 1,
            ..Default::default()
        };
        (s, loading)
    }

    #[test]
    fn edges_of_touching_columns_match_the_mean_half_chord() {
        let (r, a) = (0.5, 10.0);
        let (s, l) = columns(r, a, 40);
        let [left, right] = strip_outer_edges(&s, &l);
        // Heights every r_min / 2 give 4 per disk, at y / r = +-1/4 and +-3/4, whose mean
        // half-chord is 0.8147 r against pi r / 4 = 0.7854 r: the midpoint rule's error of
        // 0.03 r (a bias common to V and V0, so it cancels in dV/V0 to first order).
        let expected = a + std::f64::consts::PI * r / 4.0;
        assert!(
            (right - expected).abs() < 0.035 * r,
            "right {right} expected {expected}"
        );
        assert!(
            (left + expected).abs() < 0.035 * r,
            "left {left} expected {}",
            -expected
        );
        assert!(
            right - expected > 0.0,
            "the midpoint rule overestimates a concave chord"
        );
    }

    #[test]
    fn edges_move_continuously_with_the_disks() {
        // One disk of the right column slides outwards by 1e-4 m per step through 2 m: the
        // width may change by at most about its own share of the outline per step, never
        // jump (the banded estimator jumped by whole radii when a disk changed band).
        let (mut s, l) = columns(0.5, 10.0, 40);
        let k = 40 + 17;
        let mut last = strip_outer_edges(&s, &l)[1];
        for _ in 0..20_000 {
            s.disks.pos[k].x += 1e-4;
            s.disks.pos[k].y += 3e-5;
            let now = strip_outer_edges(&s, &l)[1];
            assert!((now - last).abs() < 1e-3, "jump from {last} to {now}");
            last = now;
        }
        assert!(
            last > 10.0 + std::f64::consts::PI * 0.5 / 4.0,
            "the edge followed the disk out"
        );
    }

    /// A square lattice of `nx` x `ny` disks of radius 0.5 m at unit spacing, between walls
    /// at y = 0 and y = ny, its left edge at x = 0; `shift(row)` moves a row sideways.
    fn lattice(nx: usize, ny: usize, shift: impl Fn(usize) -> f64) -> Scene {
        let mut s = Scene::default();
        for j in 0..ny {
            for i in 0..nx {
                let c = DVec2::new(0.5 + i as f64 + shift(j), 0.5 + j as f64);
                s.disks.push(c, 0.5, 2600.0).unwrap();
            }
        }
        s.walls = vec![
            Wall::fixed(DVec2::ZERO, DVec2::Y),
            Wall::fixed(DVec2::new(0.0, ny as f64), -DVec2::Y),
        ];
        s
    }

    #[test]
    fn strips_of_a_straight_sided_sample_are_the_outer_columns() {
        // Edges at x = 0 and x = 20: centres 0.5, 1.5, 2.5 lie within 3 m of the left
        // edge, 17.5, 18.5, 19.5 within 3 m of the right one.
        let (nx, ny) = (20, 30);
        let mut s = lattice(nx, ny, |_| 0.0);
        s.disks.glue(5, 0);
        let m = strip_members(&s, 0, 1, 3.0);
        for (k, &side) in m.iter().enumerate() {
            let col = k % nx;
            let expected = match col {
                _ if k == 5 => 0,
                0..=2 => -1,
                17..=19 => 1,
                _ => 0,
            };
            assert_eq!(side, expected, "disk {k} in column {col}");
        }
    }

    #[test]
    fn strips_follow_a_sheared_side_and_not_the_disks() {
        // The upper half is displaced 6 m to the right, as by a band: at each height the
        // strips are the three outer columns there. A 3 m window is small beside the 15 m
        // halves, so only rows within 1.5 m of the step see the other half's edge.
        let (nx, ny) = (20, 30);
        let s = lattice(nx, ny, |j| if j >= 15 { 6.0 } else { 0.0 });
        let m = strip_members(&s, 0, 1, 3.0);
        for (k, &side) in m.iter().enumerate() {
            let (col, row) = (k % nx, k / nx);
            if (13..17).contains(&row) {
                continue;
            }
            let expected = match col {
                0..=2 => -1,
                17..=19 => 1,
                _ => 0,
            };
            assert_eq!(side, expected, "disk {k}, row {row}, column {col}");
        }
        // A left-strip disk carried into the core stops carrying the confinement, and the
        // core disk that took its place starts.
        let mut s = s;
        let (a, b) = (3 * nx, 3 * nx + 10);
        s.disks.pos.swap(a, b);
        let m = strip_members(&s, 0, 1, 3.0);
        assert_eq!((m[a], m[b]), (0, -1));
    }
}
