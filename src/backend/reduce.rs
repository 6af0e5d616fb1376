//! Reduced quantities of a run: what the protocol measures without downloading the state.
//! The GPU path computes the same sums in its reduction kernels; this is their reference.

use glam::DVec2;

use super::Loading;
use crate::contact::Contact;
use crate::engine::StepStats;
use crate::model::{BodyKind, Scene};

/// Relative threshold below which a normal force counts as zero: a contact carries force
/// when `N > FORCE_THRESHOLD * mean(N)` over the contacts with `N > 0` (dimensionless).
pub const FORCE_THRESHOLD: f64 = 1e-6;

/// Relative tolerance on `|T| = mu N` for a sliding contact: sliding when
/// `|T| >= mu N (1 - SLIDE_EPS)` (dimensionless).
pub const SLIDE_EPS: f64 = 1e-6;

/// A contact's class (method.md, "Contact classification").
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
    pub fn add_step(&mut self, stats: &StepStats, wall_impulse: Vec<DVec2>) {
        let r = &mut self.red;
        r.steps += 1;
        r.iterations_sum += stats.solve.iterations as u64;
        r.iterations_max = r.iterations_max.max(stats.solve.iterations);
        r.capped_steps += !stats.solve.converged as u32;
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

/// Outer edges of the two strips (m): the sample is cut into horizontal bands one largest
/// diameter high between the bottom and top walls; in each band the left edge is the
/// smallest `x - r` of the left-strip disks whose centre lies in it, the right edge the
/// largest `x + r` of the right-strip disks; each edge is the mean over the bands that hold
/// disks of both strips. The sample width `right - left` times the wall distance is the
/// area between the outer edges of the strips and the walls (protocol.md's V).
pub fn strip_outer_edges(scene: &Scene, loading: &Loading) -> [f64; 2] {
    if loading.strip.is_empty() {
        return [f64::NAN; 2];
    }
    let d = &scene.disks;
    let y0 = scene.walls[loading.bottom].point.y;
    let y1 = scene.walls[loading.top].point.y;
    let band = 2.0 * d.radius.iter().cloned().fold(0.0, f64::max);
    let n = (((y1 - y0) / band).ceil().max(1.0)) as usize;
    let mut left = vec![f64::INFINITY; n];
    let mut right = vec![f64::NEG_INFINITY; n];
    for (k, &s) in loading.strip.iter().enumerate() {
        if s == 0 {
            continue;
        }
        let b = (((d.pos[k].y - y0) / band).max(0.0) as usize).min(n - 1);
        if s < 0 {
            left[b] = left[b].min(d.pos[k].x - d.radius[k]);
        } else {
            right[b] = right[b].max(d.pos[k].x + d.radius[k]);
        }
    }
    let (mut sl, mut sr, mut m) = (0.0, 0.0, 0usize);
    for b in 0..n {
        if left[b].is_finite() && right[b].is_finite() {
            sl += left[b];
            sr += right[b];
            m += 1;
        }
    }
    if m == 0 {
        [f64::NAN; 2]
    } else {
        [sl / m as f64, sr / m as f64]
    }
}
