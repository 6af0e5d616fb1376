//! Relaxed Jacobi (docs/method.md, "Jacobi").

use glam::DVec3;
use rayon::prelude::*;

use super::law;
use super::{SolveStats, SolverParams};
use crate::contact::Contact;

/// Relaxed Jacobi: every contact is solved from the velocities of the previous iteration,
/// the impulses are relaxed, and the velocities are rebuilt from the free velocities by a
/// sequential gather (deterministic, no float atomics).
pub(super) fn solve(
    params: &SolverParams,
    contacts: &mut [Contact],
    gv0: &[DVec3],
    gv: &mut [DVec3],
) -> SolveStats {
    let omega = params.jacobi.relax;
    let mut stats = SolveStats::default();
    let mut fresh = vec![(0.0, 0.0); contacts.len()];
    for it in 1..=params.max_iter {
        let solve_one = |(c, out): (&Contact, &mut (f64, f64))| {
            let (rn, rt) = local_solution(c, gv);
            *out = (c.rn + omega * (rn - c.rn), c.rt + omega * (rt - c.rt));
        };
        if params.parallel && contacts.len() >= params.parallel_min {
            contacts.par_iter().zip(fresh.par_iter_mut()).for_each(solve_one);
        } else {
            contacts.iter().zip(fresh.iter_mut()).for_each(solve_one);
        }
        let (mut d2, mut r2) = (0.0, 0.0);
        gv.copy_from_slice(gv0);
        for (c, &(rn, rt)) in contacts.iter_mut().zip(&fresh) {
            d2 += (rn - c.rn).powi(2) + (rt - c.rt).powi(2);
            r2 += rn * rn + rt * rt;
            c.rn = rn;
            c.rt = rt;
            c.apply(gv, rn, rt);
        }
        // The change is divided by the relaxation, as Gauss-Seidel's is: the unrelaxed
        // change, which is the distance to the local solutions (docs/method.md,
        // "Comparing solvers"), so that `tol` means the same for every method.
        let converged = stats.record_change(it, d2 / (omega * omega), r2, params.tol);
        // Between two tests (solver.check_every) the step goes on.
        stats.converged = converged && params.checks_at(it);
        if stats.converged {
            break;
        }
    }
    if params.deep_updates() {
        stats.deep = deep_updates(params, contacts, gv);
    }
    stats
}

/// The exact local solution of contact `c` from the velocities `gv`, its own impulse taken
/// out of them.
fn local_solution(c: &Contact, gv: &[DVec3]) -> (f64, f64) {
    let (un, ut) = c.relative_velocity(gv);
    let ufn = un - c.wnn * c.rn - c.wnt * c.rt + c.bias_n;
    let uft = ut - c.wnt * c.rn - c.wtt * c.rt + c.bias_t;
    law::solve(c.wnn, c.wtt, c.wnt, ufn, uft, c.mu)
}

/// Local updates of deep contacts after the iterations (docs/method.md, "Deep contacts"):
/// the loaded contacts overlapping by more than `deep_gap` (those with a full 2x2 block,
/// the glued walls, left out as in Gauss-Seidel), each solved exactly again from the
/// current velocities and its change applied at once, in contact order, `deep_sweeps`
/// times. Returns how many there were. The velocities stay the free ones plus every
/// impulse, so the next step's warm start is consistent.
fn deep_updates(params: &SolverParams, contacts: &mut [Contact], gv: &mut [DVec3]) -> u32 {
    let deep: Vec<usize> = (0..contacts.len())
        .filter(|&k| {
            let c = &contacts[k];
            c.ma == 0.0 && c.wnt == 0.0 && c.rn > 0.0 && c.gap < -params.deep_gap
        })
        .collect();
    for _ in 0..params.deep_sweeps {
        for &k in &deep {
            let c = &mut contacts[k];
            let (rn, rt) = local_solution(c, gv);
            c.apply(gv, rn - c.rn, rt - c.rt);
            c.rn = rn;
            c.rt = rt;
        }
    }
    deep.len() as u32
}
