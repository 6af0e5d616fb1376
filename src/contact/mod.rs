//! Contacts: the local frame, the Delassus diagonal and the record the solver iterates on.
//!
//! Conventions (docs/method.md, "Contact frame and units"): for a contact between body `i` (always a disk) and body `j`
//! (a disk or a wall), `n` points from `j` to `i`, `t = (n_y, -n_x)`, and the impulse
//! exerted by `j` on `i` over the step is `P = R_n n + R_t t` with `R_n >= 0`.
//! The relative velocity of the contact points is
//! `U_n = (v_i - v_j).n`, `U_t = (v_i - v_j).t + w_i r_i + w_j r_j`.

pub mod detect;

use glam::{DVec2, DVec3};

/// The tangent of a contact frame, `t = (n_y, -n_x)`.
#[inline]
pub fn tangent(n: DVec2) -> DVec2 {
    DVec2::new(n.y, -n.x)
}

/// One candidate or active contact, in the form the solver sweeps over.
///
/// `i` and `j` are generalized body indices: disks `0..n_disks`, then walls. A disk glued
/// to a wall is represented dynamically by that wall (it moves with it and does not spin),
/// so `j` may be a wall while the geometry (`n`, `gap`) comes from the glued disk; `disk_j`
/// keeps the geometric partner for reporting.
///
/// The layout is fixed and cache-line aligned: the fields that the per-step passes over
/// every contact read (keys, frame, impulses, gap, friction: warm start, overlap check,
/// wall forces) fill the first 64-byte line, so those passes read a third of the record
/// (with the default layout and alignment a record straddled four lines).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(64))]
pub struct Contact {
    /// Dynamic body i (a disk).
    pub i: u32,
    /// Dynamic body j (a disk, or `n_disks + wall`).
    pub j: u32,
    /// Geometric partner of `i`: a disk index, or `n_disks + wall` for a plane wall.
    pub disk_j: u32,
    /// Color assigned by the GPU coloring (contacts of one color share no body that can
    /// move under an impulse); the CPU path keeps its coloring in the solver's workspace.
    pub color: u32,
    /// Unit normal, from j to i.
    pub n: DVec2,
    /// Normal impulse (N s/m).
    pub rn: f64,
    /// Tangential impulse (N s/m).
    pub rt: f64,
    /// Gap at the start of the step (m); negative is an overlap.
    pub gap: f64,
    /// Coulomb coefficient of this contact.
    pub mu: f64,
    /// Offset added to `U_n^+` in the normal law (restitution or open-gap shift), m/s.
    pub bias_n: f64,
    /// Offset added to `U_t^+` in the friction law (tangential restitution), m/s.
    pub bias_t: f64,
    /// Delassus block: `W_nn`, `W_tt`, `W_nt` (the latter non-zero only when j translates
    /// along an axis that is neither the normal nor the tangent).
    pub wnn: f64,
    /// See `wnn`.
    pub wtt: f64,
    /// See `wnn`.
    pub wnt: f64,
    /// Lever arm of i (its radius) and of j (its radius; 0 for walls and glued disks).
    pub ri: f64,
    /// See `ri`.
    pub rj: f64,
    /// Isotropic inverse mass of i.
    pub mi: f64,
    /// Isotropic inverse mass of j (0 for walls).
    pub mj: f64,
    /// Inverse mass of j along the axis `a` only (force-driven walls); 0 otherwise.
    pub ma: f64,
    /// Axis along which j can translate when `ma > 0` (the wall normal).
    pub a: DVec2,
    /// `r_i / I_i`: spin change of i per unit tangential impulse.
    pub ki: f64,
    /// `r_j / I_j`.
    pub kj: f64,
    /// Relative normal velocity at the start of the step, `U_n^-`.
    pub un0: f64,
    /// Relative tangential velocity at the start of the step, `U_t^-`.
    pub ut0: f64,
}

const _: () = assert!(std::mem::size_of::<Contact>() == 192);

impl Contact {
    /// The sort and warm-start key: (i, geometric j).
    #[inline]
    pub fn key(&self) -> u64 {
        ((self.i as u64) << 32) | self.disk_j as u64
    }

    /// Relative velocity `(U_n, U_t)` of the contact points for generalized velocities `gv`
    /// (vx, vy, spin per body).
    #[inline]
    pub fn relative_velocity(&self, gv: &[DVec3]) -> (f64, f64) {
        self.relative_velocity_of(gv[self.i as usize], gv[self.j as usize])
    }

    /// Relative velocity `(U_n, U_t)` from the generalized velocities of bodies i and j.
    #[inline]
    pub fn relative_velocity_of(&self, vi: DVec3, vj: DVec3) -> (f64, f64) {
        let dx = vi.x - vj.x;
        let dy = vi.y - vj.y;
        let un = dx * self.n.x + dy * self.n.y;
        let ut = dx * self.n.y - dy * self.n.x + vi.z * self.ri + vj.z * self.rj;
        (un, ut)
    }

    /// Fills the Delassus block from the inverse masses and the frame.
    pub fn compute_delassus(&mut self) {
        let t = tangent(self.n);
        let an = self.a.dot(self.n);
        let at = self.a.dot(t);
        self.wnn = self.mi + self.mj + self.ma * an * an;
        self.wtt = self.mi + self.mj + self.ma * at * at + self.ri * self.ki + self.rj * self.kj;
        self.wnt = self.ma * an * at;
    }

    /// True when neither body can be moved by an impulse (nothing to solve).
    pub fn is_inert(&self) -> bool {
        self.wnn == 0.0 && self.wtt == 0.0
    }

    /// Adds the velocity change due to impulse increments `(drn, drt)` to both bodies.
    #[inline]
    pub fn apply(&self, gv: &mut [DVec3], drn: f64, drt: f64) {
        let (dvi, dvj) = self.velocity_changes(drn, drt);
        gv[self.i as usize] += dvi;
        if self.moves_j() {
            gv[self.j as usize] += dvj;
        }
    }

    /// Generalized velocity changes of bodies i and j for impulse increments `(drn, drt)`.
    #[inline]
    pub fn velocity_changes(&self, drn: f64, drt: f64) -> (DVec3, DVec3) {
        let px = drn * self.n.x + drt * self.n.y;
        let py = drn * self.n.y - drt * self.n.x;
        let pa = self.ma * (px * self.a.x + py * self.a.y);
        (
            DVec3::new(self.mi * px, self.mi * py, self.ki * drt),
            DVec3::new(
                -(self.mj * px + pa * self.a.x),
                -(self.mj * py + pa * self.a.y),
                self.kj * drt,
            ),
        )
    }

    /// True when an impulse can change body j's velocity. Kinematic and fixed bodies are
    /// never written, which lets contacts of one color share them safely in parallel.
    #[inline]
    pub fn moves_j(&self) -> bool {
        self.mj != 0.0 || self.ma != 0.0 || self.kj != 0.0
    }

    /// True when an impulse can change body i's velocity.
    #[inline]
    pub fn moves_i(&self) -> bool {
        self.mi != 0.0 || self.ki != 0.0
    }
}
