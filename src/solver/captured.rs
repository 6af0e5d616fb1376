//! A copy of one step's contact problem, kept to be solved again with other settings
//! (solver studies: `benches/solvers.rs`).

use glam::DVec3;

use super::space::BodySpace;
use crate::contact::Contact;

/// A copy of one step's contact problem, taken just before the solve
/// ([`crate::engine::CpuEngine::capture`]): the contacts with their warm-start impulses,
/// the free velocities and the velocities with those impulses applied. Solving it again
/// with other settings replays the step's solve exactly (bit for bit with the same
/// settings), which is how solvers are compared on the same states.
#[derive(Clone, Debug, Default)]
pub struct Captured {
    /// The contacts, as the solver receives them.
    pub contacts: Vec<Contact>,
    /// Free velocities of every body (disks, then walls).
    pub gv0: Vec<DVec3>,
    /// Velocities with the warm-start impulses applied.
    pub gv: Vec<DVec3>,
}

impl Captured {
    /// Solves a copy of the problem with `params`; returns the solved copy and what the
    /// solver did.
    pub fn solve(&self, params: &super::SolverParams) -> (Captured, super::SolveStats) {
        let mut out = self.clone();
        let mut work = super::sweep::Workspace::default();
        let stats = super::sweep::solve(params, &mut out.contacts, &self.gv0, &mut out.gv, &mut work, None);
        (out, stats)
    }

    /// The problem as a [`ContactSpace`](super::space::ContactSpace).
    pub fn space(&mut self) -> BodySpace<'_> {
        BodySpace {
            contacts: &mut self.contacts,
            gv0: &self.gv0,
            gv: &mut self.gv,
        }
    }
}
