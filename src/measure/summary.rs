//! The end-of-run summary (`summary.json`): every key carries its unit in its name.

use super::SeriesRow;
use super::derived::{Strength, strength};
use crate::protocol::PhaseEnd;

/// What a finished biaxial test reports.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Summary {
    /// cdlab version.
    pub version: String,
    /// Backend that ran the test.
    pub backend: String,
    /// Number of disks.
    pub disks: usize,
    /// Disk-disk friction coefficient.
    pub mu: f64,
    /// Confining stress (MPa).
    pub sigma3_mpa: f64,
    /// Time step (s); null in summaries written before it was recorded, and in summaries
    /// built without a configuration.
    #[serde(default)]
    pub dt_s: Option<f64>,
    /// Local updates of deep contacts (`solver.deep_overlap`), when the run used them:
    /// absent otherwise, and in summaries written before them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub deep_contacts: Option<DeepContacts>,
    /// Peak of sigma_1 averaged over a 0.002 strain window (MPa).
    pub sigma1_peak_mpa: f64,
    /// Axial strain at the peak.
    pub strain_peak: f64,
    /// Mean sigma_1 over axial strain 0.05-0.10 (MPa); null if the test ended before strain
    /// 0.098 (`measure::derived::residual`).
    pub sigma1_residual_mpa: Option<f64>,
    /// Mohr-Coulomb friction angle at the peak (degrees).
    pub phi_peak_deg: f64,
    /// Mohr-Coulomb friction angle at the residual (degrees); null without a residual.
    pub phi_residual_deg: Option<f64>,
    /// Volumetric strain at the end (positive = dilation).
    pub volumetric_strain_final: f64,
    /// Axial strain at the end.
    pub strain_final: f64,
    /// Force-carrying, rolling, sliding and zero-force disk-disk contacts at the end.
    pub contacts_force_final: u64,
    /// See `contacts_force_final`.
    pub contacts_rolling_final: u64,
    /// See `contacts_force_final`.
    pub contacts_sliding_final: u64,
    /// See `contacts_force_final`.
    pub contacts_zero_force_final: u64,
    /// Coordination number at the end.
    pub coordination_final: f64,
    /// Fraction of isolated disks at the end.
    pub isolated_fraction_final: f64,
    /// Mean overlap over the compression, relative to r_min (mean of the rows' means).
    pub overlap_mean_rel: f64,
    /// Largest overlap of the whole run, relative to r_min.
    pub overlap_max_rel: f64,
    /// Mean solver iterations per step during compression.
    pub iterations_mean: f64,
    /// Largest iteration count of a step during the run.
    pub iterations_max: u64,
    /// Largest kinetic energy of the compression over sigma3 times the sample's area
    /// (height x width between the strips), over the rows (dimensionless). Quasi-static
    /// tests stay below [`QUASI_STATIC_KINETIC_RATIO`]; a larger value marks a test that
    /// was leaving the quasi-static regime. 0 before the compression.
    #[serde(default)]
    pub kinetic_ratio_max: f64,
    /// Steps of the whole run.
    pub steps: u64,
    /// Simulated time of the whole run (s).
    pub time_s: f64,
    /// Wall-clock time of the run (s), summed over the parts of a resumed run (the time
    /// between a part's last checkpoint and its interruption is lost with the steps it
    /// computed). In records whose rows hold no `wall_s` (written before it) a resumed run
    /// counts its last part only.
    pub wall_time_s: f64,
    /// Steps per wall-clock second (over all the run's steps and parts).
    pub steps_per_second: f64,
    /// How each phase ended.
    pub phases: Vec<PhaseEnd>,
    /// Stress-drop events: falls of sigma_1 of at least 5% of sigma3 with concurrent
    /// contraction, over the rows averaged per `stress_drop_bin_strain` of axial strain.
    pub stress_drops: Vec<super::derived::StressDrop>,
    /// The increment of axial strain the rows were averaged over before the stress drops
    /// were looked for; absent in summaries written before it existed, whose events are
    /// falls from row to row (their number follows the time step).
    #[serde(default)]
    pub stress_drop_bin_strain: Option<f64>,
    /// Shear bands over the last snapshot interval (`crate::analysis::bands`); null when
    /// the run recorded fewer than two snapshots or the analysis could not run.
    #[serde(default)]
    pub shear_bands: Option<crate::analysis::bands::ShearBands>,
    /// The `run_id` of the record (`run.mcap`) this summary was computed from: a summary
    /// whose record was since replaced is recognised as stale. Absent in summaries written
    /// before it, and in summaries built without a record.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub record_id: Option<String>,
}

/// How a run used local updates of deep contacts (`solver.deep_overlap`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DeepContacts {
    /// The overlap beyond which a loaded contact was updated, relative to r_min.
    pub overlap_rel: f64,
    /// Local updates per such contact and step.
    pub sweeps: u32,
    /// Contacts updated per step, mean over the compression.
    pub per_step_compression: f64,
}

impl DeepContacts {
    /// The record of a run with threshold `overlap_rel` (0: none) and `sweeps` updates.
    pub fn of_run(overlap_rel: f64, sweeps: u32, rows: &[SeriesRow]) -> Option<Self> {
        if overlap_rel <= 0.0 || sweeps == 0 {
            return None;
        }
        let comp: Vec<f64> = rows
            .iter()
            .filter(|r| r.phase == "compression")
            .map(|r| r.deep_contacts)
            .collect();
        Some(DeepContacts {
            overlap_rel,
            sweeps,
            per_step_compression: comp.iter().sum::<f64>() / comp.len().max(1) as f64,
        })
    }
}

/// The kinetic ratio below which a compression counts as quasi-static in the summary:
/// measured, healthy tests stay below it (9e-5 for the 5000-disk DWL test, 6e-4 at friction
/// 0.1 and 1 MPa), while tests that were losing their confinement at low friction reached
/// 5e-3 and more before the end.
pub const QUASI_STATIC_KINETIC_RATIO: f64 = 1e-3;

impl Summary {
    /// Builds the summary from the recorded rows.
    pub fn new(
        rows: &[SeriesRow],
        ends: &[PhaseEnd],
        sigma3: f64,
        mu: f64,
        disks: usize,
        backend: String,
        wall_time_s: f64,
    ) -> Self {
        let st: Strength = strength(rows, sigma3);
        let comp: Vec<&SeriesRow> = rows.iter().filter(|r| r.phase == "compression").collect();
        let last = rows.last().cloned().unwrap_or_default();
        let finite = |x: f64| x.is_finite().then_some(x);
        let steps = last.step;
        Summary {
            version: env!("CARGO_PKG_VERSION").to_string(),
            backend,
            disks,
            mu,
            sigma3_mpa: sigma3 / 1e6,
            dt_s: None,
            deep_contacts: None,
            sigma1_peak_mpa: st.sigma1_peak_pa / 1e6,
            strain_peak: st.strain_peak,
            sigma1_residual_mpa: finite(st.sigma1_residual_pa / 1e6),
            phi_peak_deg: st.phi_peak_deg,
            phi_residual_deg: finite(st.phi_residual_deg),
            volumetric_strain_final: st.volumetric_strain_final,
            strain_final: last.strain_axial,
            contacts_force_final: last.n_force,
            contacts_rolling_final: last.n_rolling,
            contacts_sliding_final: last.n_sliding,
            contacts_zero_force_final: last.n_zero_force,
            coordination_final: last.coordination,
            isolated_fraction_final: last.isolated_fraction,
            overlap_mean_rel: comp.iter().map(|r| r.overlap_mean_rel).sum::<f64>() / comp.len().max(1) as f64,
            overlap_max_rel: rows.iter().map(|r| r.overlap_max_rel).fold(0.0, f64::max),
            iterations_mean: comp.iter().map(|r| r.iterations).sum::<f64>() / comp.len().max(1) as f64,
            iterations_max: rows.iter().map(|r| r.iterations_max).max().unwrap_or(0),
            kinetic_ratio_max: comp.iter().map(|r| r.kinetic_ratio()).fold(0.0, f64::max),
            steps,
            time_s: last.time_s,
            wall_time_s,
            steps_per_second: steps as f64 / wall_time_s.max(1e-9),
            phases: ends.to_vec(),
            stress_drops: super::derived::stress_drops(rows, 0.05 * sigma3, super::derived::STRESS_DROP_BIN),
            stress_drop_bin_strain: Some(super::derived::STRESS_DROP_BIN),
            shear_bands: None,
            record_id: None,
        }
    }

    /// A human-readable table (every number with its unit).
    pub fn table(&self) -> String {
        let opt = |x: Option<f64>, unit: &str| {
            x.map_or(
                format!(
                    "n/a (test ended before strain {:.3})",
                    super::derived::RESIDUAL_MIN_END
                ),
                |v| format!("{v:.3} {unit}"),
            )
        };
        let mut s = String::new();
        let mut line = |k: &str, v: String| s.push_str(&format!("  {k:<34} {v}\n"));
        line("disks", format!("{}", self.disks));
        line("backend", self.backend.clone());
        line("contact friction mu", format!("{}", self.mu));
        line("confining stress sigma3", format!("{:.3} MPa", self.sigma3_mpa));
        if let Some(dt) = self.dt_s {
            line("time step", format!("{} ms", dt * 1e3));
        }
        if let Some(d) = &self.deep_contacts {
            line(
                "local updates of deep contacts",
                format!(
                    "beyond {:.3}% of r_min, {} per step; {:.2} contacts per step (compression)",
                    100.0 * d.overlap_rel,
                    d.sweeps,
                    d.per_step_compression
                ),
            );
        }
        line(
            "peak sigma1 (0.002 window)",
            format!(
                "{:.3} MPa at axial strain {:.4}",
                self.sigma1_peak_mpa, self.strain_peak
            ),
        );
        line(
            "residual sigma1 (strain 0.05-0.10)",
            opt(self.sigma1_residual_mpa, "MPa"),
        );
        line("friction angle, peak", format!("{:.2} deg", self.phi_peak_deg));
        line("friction angle, residual", opt(self.phi_residual_deg, "deg"));
        line("final axial strain", format!("{:.4}", self.strain_final));
        line(
            "final volumetric strain",
            format!("{:+.4} (positive = dilation)", self.volumetric_strain_final),
        );
        line(
            "final contacts: force/roll/slide/zero",
            format!(
                "{} / {} / {} / {}",
                self.contacts_force_final,
                self.contacts_rolling_final,
                self.contacts_sliding_final,
                self.contacts_zero_force_final
            ),
        );
        line(
            "final coordination number",
            format!("{:.3}", self.coordination_final),
        );
        line(
            "final isolated fraction",
            format!("{:.3}", self.isolated_fraction_final),
        );
        line(
            "overlap mean / max",
            format!(
                "{:.2e} / {:.2e} of r_min",
                self.overlap_mean_rel, self.overlap_max_rel
            ),
        );
        line(
            "solver iterations per step",
            format!(
                "{:.1} mean (compression), {} max",
                self.iterations_mean, self.iterations_max
            ),
        );
        line(
            "largest kinetic ratio (compression)",
            if self.kinetic_ratio_max > QUASI_STATIC_KINETIC_RATIO {
                format!(
                    "{:.2e} (above {QUASI_STATIC_KINETIC_RATIO:e}: not quasi-static, treat the results as suspect)",
                    self.kinetic_ratio_max
                )
            } else {
                format!("{:.2e} (K / (sigma3 h w))", self.kinetic_ratio_max)
            },
        );
        line(
            "steps",
            format!("{} ({:.2} s simulated)", self.steps, self.time_s),
        );
        line(
            "wall time",
            format!("{:.1} s ({:.0} steps/s)", self.wall_time_s, self.steps_per_second),
        );
        match &self.shear_bands {
            Some(b) => s.push_str(&format!("  shear bands\n{}", b.table())),
            None => s.push_str("  shear bands                        n/a (fewer than two snapshots)\n"),
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(kinetic_energy_j: f64) -> SeriesRow {
        SeriesRow {
            phase: "compression".into(),
            sigma1_pa: 2e6,
            sigma3_pa: 1e6,
            height_m: 100.0,
            width_m: 50.0,
            kinetic_energy_j,
            ..Default::default()
        }
    }

    /// K / (sigma3 h w): 5e6 J/m over 1 MPa x 100 m x 50 m is 1e-3 exactly; 2.5e7 J/m is
    /// 5e-3, above the quasi-static bound, and the table must say so.
    #[test]
    fn largest_kinetic_ratio_is_reported_and_flagged() {
        let calm = Summary::new(&[row(1e6), row(5e6)], &[], 1e6, 0.3, 10, "cpu".into(), 1.0);
        assert!(
            (calm.kinetic_ratio_max - 1e-3).abs() < 1e-15,
            "{}",
            calm.kinetic_ratio_max
        );
        assert!(!calm.table().contains("not quasi-static"));
        let wild = Summary::new(&[row(1e6), row(2.5e7)], &[], 1e6, 0.3, 10, "cpu".into(), 1.0);
        assert!((wild.kinetic_ratio_max - 5e-3).abs() < 1e-15);
        assert!(wild.table().contains("not quasi-static"), "{}", wild.table());
    }

    /// The record of local updates: absent without them (threshold or sweeps 0), so that
    /// the summaries of runs without them keep their keys; the mean per step is over the
    /// compression rows only (3 and 5 contacts: 4), not the confinement's 100.
    #[test]
    fn deep_contacts_are_recorded_only_when_used() {
        let mut rows = vec![row(1e6), row(1e6), row(1e6)];
        rows[0].phase = "confinement".into();
        for (r, d) in rows.iter_mut().zip([100.0, 3.0, 5.0]) {
            r.deep_contacts = d;
        }
        assert_eq!(DeepContacts::of_run(0.0, 5, &rows), None);
        assert_eq!(DeepContacts::of_run(0.005, 0, &rows), None);
        let d = DeepContacts::of_run(0.005, 5, &rows).expect("used");
        assert_eq!((d.overlap_rel, d.sweeps, d.per_step_compression), (0.005, 5, 4.0));
        let mut s = Summary::new(&rows, &[], 1e6, 0.3, 10, "cpu".into(), 1.0);
        let json = serde_json::to_string(&s).unwrap();
        assert!(!json.contains("deep_contacts"), "{json}");
        s.deep_contacts = Some(d);
        let json = serde_json::to_string(&s).unwrap();
        assert!(
            json.contains("\"deep_contacts\":{\"overlap_rel\":0.005"),
            "{json}"
        );
        assert!(
            s.table()
                .contains("beyond 0.500% of r_min, 5 per step; 4.00 contacts per step"),
            "{}",
            s.table()
        );
        let back: Summary = serde_json::from_str(&json).unwrap();
        assert_eq!(back, s);
    }
}
