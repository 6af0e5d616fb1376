//! The contact problem of one step as any iterative solver sees it, whoever stores it: the
//! engine's bodies and contacts ([`BodySpace`]) or an explicit Delassus matrix
//! ([`crate::fc2d::Space`]). A solver written against [`ContactSpace`] runs on both, so
//! the Siconos fc2d problems test the same code the engine runs.
//!
//! It also holds the measures every solver is judged by, whatever its own stopping test
//! (docs/method.md, "Comparing solvers"): the distance of the impulses to their local
//! solutions ([`local_residual`]) and the closing velocity left at loaded contacts
//! ([`closing`]), which is how far they sink per unit time. A step's problem kept for
//! solving again is a [`super::captured::Captured`].

use glam::DVec3;

use super::law;
use crate::contact::Contact;

/// A frictional contact problem `u = W R + q` (normal component first, then tangent) and
/// its current impulses, with the velocities kept consistent with them.
pub trait ContactSpace {
    /// Number of contacts.
    fn len(&self) -> usize;
    /// True when there is no contact.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Delassus block of contact `c`: `(W_nn, W_tt, W_nt)` (s/kg for disks).
    fn block(&self, c: usize) -> (f64, f64, f64);
    /// Friction coefficient of contact `c`.
    fn mu(&self, c: usize) -> f64;
    /// Impulse `(R_n, R_t)` of contact `c` (N s).
    fn impulse(&self, c: usize) -> (f64, f64);
    /// Formal relative velocity `(W R + q)_c` of contact `c` at the current impulses
    /// (m/s; the law's offsets included).
    fn velocity(&self, c: usize) -> (f64, f64);
    /// Sets the impulse of contact `c` and carries the change into the velocities, as a
    /// Gauss-Seidel update does.
    fn set(&mut self, c: usize, rn: f64, rt: f64);
    /// Sets every impulse and rebuilds the velocities from the free ones, `u = q + W R`,
    /// summed in contact order so that the result does not depend on the history.
    fn set_all(&mut self, r: &[(f64, f64)]);
}

/// The exact local solution of contact `c` with every other impulse held: its own
/// contribution is taken out of the velocity (`u - W_cc R_c`) and the local law solved
/// (`law::solve`).
pub fn local_solution<S: ContactSpace + ?Sized>(s: &S, c: usize) -> (f64, f64) {
    let (wnn, wtt, wnt) = s.block(c);
    let (rn, rt) = s.impulse(c);
    let (un, ut) = s.velocity(c);
    if wnn <= 0.0 {
        return (0.0, 0.0);
    }
    law::solve(
        wnn,
        wtt,
        wnt,
        un - wnn * rn - wnt * rt,
        ut - wnt * rn - wtt * rt,
        s.mu(c),
    )
}

/// The relative distance of the impulses to their local solutions,
/// `sqrt(sum |L_c(R) - R_c|^2) / sqrt(sum |L_c(R)|^2)`: 0 exactly at a solution of the
/// whole problem, and the change one Jacobi iteration would make. The common measure
/// across solvers, whatever test each stops on (0 when nothing carries or asks for an
/// impulse).
pub fn local_residual<S: ContactSpace + ?Sized>(s: &S) -> f64 {
    let (mut d2, mut l2) = (0.0, 0.0);
    for c in 0..s.len() {
        let (ln, lt) = local_solution(s, c);
        let (rn, rt) = s.impulse(c);
        d2 += (ln - rn).powi(2) + (lt - rt).powi(2);
        l2 += ln * ln + lt * lt;
    }
    super::convergence::relative_change(d2, l2)
}

/// Closing velocities left at contacts that carry a normal impulse (m/s): the largest and
/// the mean of `max(0, -(u_n))` over them, and how many there are. At an exact solution
/// a loaded contact has `u_n = 0` (Signorini), so what is left is the rate at which it
/// sinks (times `theta dt` per step).
pub fn closing<S: ContactSpace + ?Sized>(s: &S) -> Closing {
    let mut out = Closing::default();
    let mut sum = 0.0;
    for c in 0..s.len() {
        if s.impulse(c).0 > 0.0 {
            let v = (-s.velocity(c).0).max(0.0);
            out.max = out.max.max(v);
            sum += v;
            out.loaded += 1;
        }
    }
    if out.loaded > 0 {
        out.mean = sum / out.loaded as f64;
    }
    out
}

/// See [`closing`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Closing {
    /// Largest closing velocity of a loaded contact (m/s).
    pub max: f64,
    /// Mean closing velocity over the loaded contacts (m/s).
    pub mean: f64,
    /// Contacts with `R_n > 0`.
    pub loaded: usize,
}

/// The engine's form of the problem: contacts between bodies whose generalized velocities
/// (vx, vy, spin) are `gv`, with free velocities `gv0`.
pub struct BodySpace<'a> {
    /// The contacts, their impulses and Delassus blocks.
    pub contacts: &'a mut [Contact],
    /// Free velocities: what the bodies would do without any impulse.
    pub gv0: &'a [DVec3],
    /// Velocities with every impulse of `contacts` applied.
    pub gv: &'a mut [DVec3],
}

impl ContactSpace for BodySpace<'_> {
    fn len(&self) -> usize {
        self.contacts.len()
    }
    fn block(&self, c: usize) -> (f64, f64, f64) {
        let k = &self.contacts[c];
        (k.wnn, k.wtt, k.wnt)
    }
    fn mu(&self, c: usize) -> f64 {
        self.contacts[c].mu
    }
    fn impulse(&self, c: usize) -> (f64, f64) {
        let k = &self.contacts[c];
        (k.rn, k.rt)
    }
    fn velocity(&self, c: usize) -> (f64, f64) {
        let k = &self.contacts[c];
        let (un, ut) = k.relative_velocity(self.gv);
        (un + k.bias_n, ut + k.bias_t)
    }
    fn set(&mut self, c: usize, rn: f64, rt: f64) {
        let k = &mut self.contacts[c];
        let (drn, drt) = (rn - k.rn, rt - k.rt);
        k.rn = rn;
        k.rt = rt;
        if drn != 0.0 || drt != 0.0 {
            k.apply(self.gv, drn, drt);
        }
    }
    fn set_all(&mut self, r: &[(f64, f64)]) {
        self.gv.copy_from_slice(self.gv0);
        for (k, &(rn, rt)) in self.contacts.iter_mut().zip(r) {
            k.rn = rn;
            k.rt = rt;
            if rn != 0.0 || rt != 0.0 {
                k.apply(self.gv, rn, rt);
            }
        }
    }
}
