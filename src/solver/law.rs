//! The local Signorini-Coulomb solution for one contact, given the free relative velocity
//! (all other impulses included, this contact's own removed).

/// Exact local solution for a contact with a diagonal Delassus block (`W_nt = 0`, the case
/// of every disk-disk and disk-plane contact): returns `(R_n, R_t)`.
///
/// `ufn`, `uft` are the free formal velocities (`U_free + bias`). With `W_nt = 0` the normal
/// and tangential problems decouple: `R_n = max(0, -ufn / W_nn)`, then
/// `R_t = clamp(-uft / W_tt, -mu R_n, mu R_n)` (docs/method.md, "The local law and its
/// exact solution").
#[inline]
pub fn solve_diagonal(wnn: f64, wtt: f64, ufn: f64, uft: f64, mu: f64) -> (f64, f64) {
    let rn = if ufn < 0.0 { -ufn / wnn } else { 0.0 };
    let lim = mu * rn;
    let rt = if wtt > 0.0 {
        (-uft / wtt).clamp(-lim, lim)
    } else {
        0.0
    };
    (rn, rt)
}

/// Exact local solution for a full symmetric 2x2 block `[[wnn, wnt], [wnt, wtt]]`, by
/// cases: no contact, stick, slide in either direction. Returns `(R_n, R_t)`.
///
/// Used for contacts with a body that translates along an axis oblique to the contact
/// frame (a disk glued to a force-driven wall), where normal and tangent couple.
pub fn solve_block(wnn: f64, wtt: f64, wnt: f64, ufn: f64, uft: f64, mu: f64) -> (f64, f64) {
    if ufn >= 0.0 {
        return (0.0, 0.0);
    }
    // Stick: W r = -u.
    let det = wnn * wtt - wnt * wnt;
    if det > 0.0 {
        let rn = (-ufn * wtt + uft * wnt) / det;
        let rt = (-uft * wnn + ufn * wnt) / det;
        if rn >= 0.0 && rt.abs() <= mu * rn {
            return (rn, rt);
        }
    }
    // Slide with R_t = -s mu R_n and u_n = 0: (wnn - s mu wnt) R_n = -ufn, and the sliding
    // velocity u_t = uft + (wnt - s mu wtt) R_n must have the sign s.
    let mut best = (0.0, 0.0);
    for s in [1.0, -1.0] {
        let denom = wnn - s * mu * wnt;
        if denom <= 0.0 {
            continue;
        }
        let rn = -ufn / denom;
        let ut = uft + (wnt - s * mu * wtt) * rn;
        if rn >= 0.0 && ut * s >= 0.0 {
            return (rn, -s * mu * rn);
        }
        best = (rn, -s * mu * rn);
    }
    // Only reached through round-off at a case boundary: take the last admissible slide.
    best
}

/// Solves the local problem choosing the diagonal fast path when the block is diagonal.
#[inline]
pub fn solve(wnn: f64, wtt: f64, wnt: f64, ufn: f64, uft: f64, mu: f64) -> (f64, f64) {
    if wnt == 0.0 {
        solve_diagonal(wnn, wtt, ufn, uft, mu)
    } else {
        solve_block(wnn, wtt, wnt, ufn, uft, mu)
    }
}

/// Euclidean projection of `(zn, zt)` onto the Coulomb cone `|z_t| <= mu z_n`: the point
/// itself inside, the apex when it lies in the polar cone, else the nearest point of the
/// cone's edge on its side.
#[inline]
pub fn project_cone(zn: f64, zt: f64, mu: f64) -> (f64, f64) {
    if zt.abs() <= mu * zn {
        (zn, zt)
    } else if mu * zt.abs() <= -zn {
        (0.0, 0.0)
    } else {
        let pn = (zn + mu * zt.abs()) / (1.0 + mu * mu);
        (pn, (mu * pn).copysign(zt))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn projection_lands_on_the_cone_and_keeps_points_inside() {
        // Inside: unchanged.
        assert_eq!(project_cone(2.0, 0.5, 0.5), (2.0, 0.5));
        // Polar cone (mu |t| <= -n): the apex.
        assert_eq!(project_cone(-1.0, 0.1, 0.5), (0.0, 0.0));
        // Outside, beyond the boundary t = mu n: (n + mu |t|) / (1 + mu^2) = (1 + 0.5 * 2)
        // / 1.25 = 1.6, t = 0.8.
        let (pn, pt) = project_cone(1.0, -2.0, 0.5);
        assert!((pn - 1.6).abs() < 1e-15 && (pt + 0.8).abs() < 1e-15, "{pn} {pt}");
    }
}
