//! Iterative sweeps over the contacts of one step: the face that the engine and the CPU
//! backend call. Gauss-Seidel (`gauss_seidel.rs`) works on compact rows (`rows.rs`) with
//! one local update (`update.rs`), several rows of a color at a time in vector lanes
//! (`lanes.rs`), on a thread team for large problems (`team.rs`); Jacobi (`jacobi.rs`)
//! works on the contacts themselves.
//!
//! `gv` holds the generalized velocities (vx, vy, spin) of every body: disks first, then
//! walls. On entry it must already include the impulses the contacts carry (warm start).

use glam::DVec3;

use super::space::BodySpace;
use super::{Method, SolveStats, SolverParams, anderson, apgd, gauss_seidel, jacobi};
use crate::contact::Contact;

pub use super::gauss_seidel::{SolveTimes, Workspace};
pub use super::lanes::colored_lanes;

/// A coloring the contacts already follow: they are sorted by color, and
/// `ranges[c]..ranges[c + 1]` is color `c` (some may be empty), the last one the serial
/// group when `serial_last` ([`super::color::color`]). The engine's kept pair list gives it
/// (`contact::detect::Neighbours`), so that a step neither colors nor reorders.
#[derive(Clone, Copy, Debug)]
pub struct Colors<'a> {
    /// Color boundaries in the contacts' order.
    pub ranges: &'a [u32],
    /// The last range is the serial group.
    pub serial_last: bool,
}

/// Solves the contact problem: plain Gauss-Seidel sweeps the contacts in their order,
/// colored Gauss-Seidel colors them first and sweeps the colors in order, on a thread team
/// when the problem is large enough; Jacobi rebuilds the velocities from the free
/// velocities `gv0` every iteration, and so does accelerated projected Jacobi (`apgd.rs`,
/// run on the contacts and bodies as a [`BodySpace`]); Anderson-accelerated Gauss-Seidel
/// sweeps in contact order and rebuilds them from `gv0` after each mixing. Colored
/// Gauss-Seidel takes the coloring `colors` when given, and colors the contacts itself
/// otherwise; the other methods ignore it.
pub fn solve(
    params: &SolverParams,
    contacts: &mut [Contact],
    gv0: &[DVec3],
    gv: &mut [DVec3],
    work: &mut Workspace,
    colors: Option<Colors>,
) -> SolveStats {
    match params.method {
        Method::Gs | Method::ColoredGs => gauss_seidel::solve(params, contacts, gv, work, colors),
        Method::Jacobi => {
            work.clear_coloring();
            jacobi::solve(params, contacts, gv0, gv)
        }
        Method::Apgd => {
            work.clear_coloring();
            apgd::solve(&mut BodySpace { contacts, gv0, gv }, params)
        }
        Method::AndersonGs => {
            work.clear_coloring();
            anderson::solve(&mut BodySpace { contacts, gv0, gv }, params)
        }
    }
}
