//! The raw-pointer context of the Gauss-Seidel sweeps, and why sharing it is sound.
//!
//! The sweeps are most of a step's time, so they index the velocities and the body table
//! without bounds checks and let the threads of a team write the velocities at the same
//! time. Every `unsafe fn` of the sweeps asks its caller for the same thing: that `ctx` is
//! valid for the bodies of its rows, and that no other thread writes those bodies (or,
//! for a [`FULL`](super::rows::FULL) row, its contact) while it runs. That holds because:
//!
//! - every body index of a row is checked against the number of bodies when the rows are
//!   built ([`super::rows::build`]), and the pointers cover every body and every contact
//!   of the step for as long as the sweeps run;
//! - the rows swept at the same time by different threads belong to one color, and rows
//!   of one color share no movable body (docs/method.md, "Nonlinear Gauss-Seidel"); a body that cannot
//!   move may be shared by rows of a color, and the updates never write it;
//! - rows that need the full 2x2 law write their contact too; they share their
//!   force-driven wall, so they form the serial group, which one thread sweeps alone;
//! - between two colors the team meets at a barrier, which orders every write of one
//!   color before any read of the next ([`super::team`]).

use glam::DVec3;

use super::rows::BodyProps;
use crate::contact::Contact;

/// Raw pointers to what the sweeps read and write, shared by the threads of a team, and
/// the settings of the current iteration. See the module documentation for why it may be
/// shared.
#[derive(Clone, Copy)]
pub(super) struct Ctx {
    pub(super) gv: *mut Line,
    pub(super) props: *const BodyProps,
    pub(super) contacts: *mut Contact,
    /// Gauss-Seidel relaxation of the current iteration.
    pub(super) relax: f64,
    /// Whether the rows of the proper colors are packed four at a time
    /// ([`super::quads::gather_packed`]), to be swept in AVX registers.
    pub(super) quads: bool,
    /// Whether every packed row has no friction and no tangential impulse (`mu` and `R_t`
    /// +0, as in the frictionless compaction): their `R_t` then stays +0, and the packed
    /// sweeps compute the normal part only, with the same result bit for bit
    /// ([`super::simd`]).
    pub(super) frictionless: bool,
}

/// A body's velocity `(v_x, v_y, omega)` as the sweeps keep it: padded to 32 bytes and
/// aligned on them, so that one AVX load or store moves a whole body and four bodies
/// become the lanes of three registers in eight shuffles ([`super::simd`]). The padding
/// stays zero: the updates add zero to it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(32))]
pub(super) struct Line {
    pub(super) v: DVec3,
    pad: f64,
}

impl Line {
    /// The line of velocity `v`.
    pub(super) fn of(v: DVec3) -> Self {
        Line { v, pad: 0.0 }
    }
}

const _: () = assert!(std::mem::size_of::<Line>() == 32);

// SAFETY: see the module documentation: members of a team write disjoint bodies and
// contacts between two barriers.
unsafe impl Send for Ctx {}
unsafe impl Sync for Ctx {}
