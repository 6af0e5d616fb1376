//! The text `cdlab fabric` prints: every number of a snapshot's analysis with its unit.

use crate::measure::micro::{Analysis, PDF_BINS, PDF_MAX, ROSE_BINS};
use crate::record::SeriesRow;

/// The printed report: every number with its unit.
pub fn report(a: &Analysis, strain: f64, time_s: f64, row: &SeriesRow) -> String {
    let mut s = String::new();
    let mut line = |k: &str, v: String| s.push_str(&format!("  {k:<44} {v}\n"));
    line("snapshot", format!("axial strain {strain:.4}, t = {time_s:.3} s"));
    line(
        "force-carrying disk-disk contacts",
        format!("{} (mean normal force {:.4e} N/m)", a.sums.n_force, a.mean_f_n),
    );
    line(
        "fabric anisotropy a_c",
        format!(
            "{:.4} (principal direction {:.1} deg from x)",
            a.a_c, a.theta_c_deg
        ),
    );
    line("normal force anisotropy a_n", format!("{:.4}", a.a_n));
    line("tangential force anisotropy a_t", format!("{:.4}", a.a_t));
    line(
        "q/p: Love-Weber / (a_c + a_n + a_t)/2",
        format!("{:.4} / {:.4}", a.q_over_p, a.sff_q_over_p),
    );
    line(
        "Love-Weber sigma1 / sigma3",
        format!(
            "{:.3} MPa / {:.3} MPa over {:.1} m^2",
            a.sigma1_pa / 1e6,
            a.sigma3_pa / 1e6,
            a.area_m2
        ),
    );
    line(
        "boundary sigma1 (top wall) / sigma3 (strips)",
        format!("{:.3} MPa / {:.3} MPa", row.sigma1_pa / 1e6, row.sigma3_pa / 1e6),
    );
    line(
        "strong network (f_n > <f_n>)",
        format!(
            "{} contacts, {:.1}% of them, carrying {:.1}% of q",
            a.sums.n_strong,
            100.0 * a.strong_fraction,
            100.0 * a.strong_q_share
        ),
    );
    line(
        "weak network",
        format!(
            "{} contacts, carrying {:.1}% of q",
            a.sums.n_force - a.sums.n_strong,
            100.0 * (1.0 - a.strong_q_share)
        ),
    );
    line(
        "force-branch angle alpha, strong / weak",
        format!(
            "{:.2} deg / {:.2} deg (mean)",
            a.alpha_strong_mean_deg, a.alpha_weak_mean_deg
        ),
    );
    line(
        "disks in strong chains (>= 2 strong contacts)",
        format!(
            "{}, mean radius {:.4} m against {:.4} m for all disks ({:+.1}%)",
            a.chain_disks,
            a.chain_radius_mean_m,
            a.radius_mean_m,
            100.0 * (a.chain_radius_mean_m / a.radius_mean_m - 1.0)
        ),
    );
    line(
        "orientation homogeneity",
        format!(
            "largest deviation from the mean {:.1}% ({ROSE_BINS} bins of {:.0} deg)",
            100.0 * a.rose_max_deviation,
            180.0 / ROSE_BINS as f64
        ),
    );
    line(
        "force PDF",
        format!("{PDF_BINS} bins over f_n/<f_n> in [0, {PDF_MAX}) (-)"),
    );
    s
}
