//! The end-of-run summary (`summary.json`): every key carries its unit in its name.

use super::SeriesRow;
use super::derived::{Strength, strength};
use super::phase::PhaseEnd;

/// What a finished biaxial test reports.
///
/// `summary.json` ([`Summary::to_json`]) also carries [`CHECKSUM_KEY`], the CRC-32 of the
/// rest of its content, and reading one ([`serde::Deserialize`], [`verify_checksum`])
/// refuses a summary whose content no longer matches it: a flipped digit changes the
/// campaign's figures without any other sign. A summary without the key (written before
/// summaries had one) is read unchecked.
// `remote = "Self"` makes the derives generate the field-by-field code as inherent
// functions, so that the trait impls below can check the checksum before using it.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(remote = "Self")]
pub struct Summary {
    /// cdlab version.
    pub version: String,
    /// Backend that ran the test (its last part, for a resumed run).
    pub backend: String,
    /// Every backend that ran a part of the test, in order, when they were not all one
    /// (a GPU run resumed on the CPU); absent otherwise, and in summaries written before it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub backends: Vec<String>,
    /// Number of disks.
    pub disks: usize,
    /// Seed of the sample (`sample.seed`); absent in summaries written before it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// Axial strain at which the test ends (`test.strain_end`); absent in summaries written
    /// before it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub strain_end: Option<f64>,
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
    /// What the peak, the residual, the stress drops and `kinetic_ratio_max` were derived
    /// from; absent in summaries written before it (derived from the series rows).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub derived_from: Option<DerivedFrom>,
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
    pub shear_bands: Option<super::bands::ShearBands>,
    /// Fabric and force anisotropies at the ends of the preparation phases, at the peak and
    /// at the end ([`crate::measure::micro`]); absent when the rows hold no
    /// micromechanical columns (records written before them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fabric: Option<FabricSummary>,
    /// The `run_id` of the record (`run.mcap`) this summary was computed from: a summary
    /// whose record was since replaced is recognised as stale. Absent in summaries written
    /// before it, and in summaries built without a record.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub record_id: Option<String>,
}

impl serde::Serialize for Summary {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        Summary::serialize(self, s)
    }
}

impl<'de> serde::Deserialize<'de> for Summary {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        use serde::de::Error;
        let value = serde_json::Value::deserialize(d)?;
        verify_checksum(&value).map_err(D::Error::custom)?;
        Summary::deserialize(value).map_err(D::Error::custom)
    }
}

/// The key of `summary.json` that holds the CRC-32 of the rest of the summary.
pub const CHECKSUM_KEY: &str = "checksum";

/// The checksum of a summary's JSON `value`: `crc32:` and the CRC-32 (IEEE), in 8 hex
/// digits, of its canonical text (compact, keys sorted) without [`CHECKSUM_KEY`]. Computed on the
/// values, not the bytes, so that it does not depend on the spacing or the order of keys.
pub fn checksum(value: &serde_json::Value) -> String {
    let mut text = String::new();
    match value.as_object() {
        Some(map) => {
            let mut rest = map.clone();
            rest.remove(CHECKSUM_KEY);
            canonical(&serde_json::Value::Object(rest), &mut text);
        }
        None => canonical(value, &mut text),
    }
    format!("crc32:{:08x}", crc32fast::hash(text.as_bytes()))
}

/// Writes `value` as compact JSON with the keys of every object sorted: one text per value,
/// whatever the map type keeps (the numbers as serde_json writes them, shortest round trip).
fn canonical(value: &serde_json::Value, out: &mut String) {
    use serde_json::Value;
    match value {
        Value::Object(map) => {
            let mut keys: Vec<&String> = map.keys().collect();
            keys.sort();
            out.push('{');
            for (k, key) in keys.into_iter().enumerate() {
                if k > 0 {
                    out.push(',');
                }
                out.push_str(&Value::from(key.as_str()).to_string());
                out.push(':');
                canonical(&map[key], out);
            }
            out.push('}');
        }
        Value::Array(items) => {
            out.push('[');
            for (k, item) in items.iter().enumerate() {
                if k > 0 {
                    out.push(',');
                }
                canonical(item, out);
            }
            out.push(']');
        }
        other => out.push_str(&other.to_string()),
    }
}

/// Checks the checksum of a summary's JSON `value`: `Err` says why it does not match its
/// content. A summary without [`CHECKSUM_KEY`] (written before summaries had one) passes.
pub fn verify_checksum(value: &serde_json::Value) -> std::result::Result<(), String> {
    let Some(saved) = value.get(CHECKSUM_KEY) else {
        return Ok(());
    };
    let calculated = checksum(value);
    match saved.as_str() {
        Some(s) if s == calculated => Ok(()),
        Some(s) => Err(format!(
            "its content does not match its checksum (saved {s}, calculated {calculated}): it \
             was changed or damaged after it was written"
        )),
        None => Err(format!("its {CHECKSUM_KEY} is not a string: {saved}")),
    }
}

impl Summary {
    /// The text of `summary.json`: the summary as pretty JSON, [`CHECKSUM_KEY`] last.
    pub fn to_json(&self) -> serde_json::Result<String> {
        #[derive(serde::Serialize)]
        struct Sealed<'a> {
            #[serde(flatten)]
            summary: &'a Summary,
            checksum: String,
        }
        // From the text itself, as a reader will parse it.
        let plain: serde_json::Value = serde_json::from_str(&serde_json::to_string(self)?)?;
        serde_json::to_string_pretty(&Sealed {
            summary: self,
            checksum: checksum(&plain),
        })
    }
}

/// What a summary's derived results (peak, residual, stress drops, largest kinetic ratio)
/// were computed from.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DerivedFrom {
    /// `"steps"`: the compression's every step, averaged by the protocol over blocks of
    /// `every_steps` steps as it ran ([`super::derived::DerivedCurve`]), whatever
    /// `output.series_every` is; `"rows"`: the series rows, written every `every_steps`
    /// steps (a record whose checkpoints do not keep the blocks): the peak and the stress
    /// drops then move with the row interval.
    pub source: String,
    /// Steps a point averages (see `source`).
    pub every_steps: u64,
}

impl DerivedFrom {
    fn line(&self) -> String {
        match self.source.as_str() {
            "steps" => format!(
                "every step of the compression, averaged over blocks of {} steps",
                self.every_steps
            ),
            _ => format!(
                "the series rows, one every {} steps (the peak and the stress drops depend on that interval)",
                self.every_steps
            ),
        }
    }
}

/// The micromechanical state at four points of a test, from the series rows.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FabricSummary {
    /// Last row of the compaction (the state the confinement starts from).
    pub after_compaction: FabricState,
    /// Last row of the confinement (the state the compression starts from).
    pub after_confinement: FabricState,
    /// The compression row nearest the peak's strain.
    pub peak: FabricState,
    /// Last row.
    pub end: FabricState,
    /// The paper's homogeneity of the contact orientations after compaction: the largest
    /// deviation of the orientation histogram from its mean, in % of the mean, over
    /// `homogeneity_bins` bins of equal width over 180 degrees.
    pub homogeneity_after_compaction_pct: f64,
    /// Bins of that histogram.
    pub homogeneity_bins: usize,
    /// The counting noise of one bin at that row, `100 / sqrt(N_c / bins)` % for `N_c`
    /// force-carrying contacts: an isotropic fabric's largest deviation over 18 bins is
    /// typically about twice this, so a homogeneity near it says the fabric is isotropic
    /// within what the sample's size can show.
    pub homogeneity_bin_noise_pct: f64,
}

/// The Love-Weber `q / p` below which the summary's table gives no strong network's share
/// of `q`: the share divides by the network's `q`, which a nearly isotropic state (after
/// compaction or confinement) has close to 0, so that any value, -69% or 300%, can come
/// out of the noise (docs/micromechanics.md, "Strong and weak networks"). The sheared
/// states of the paper's tests have `q / p` of 0.2 to 0.6.
pub const STRONG_SHARE_MIN_Q_OVER_P: f64 = 0.05;

/// The micromechanical columns of one row.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FabricState {
    /// Axial strain of the row (0 before the compression).
    pub strain: f64,
    /// Fabric anisotropy.
    pub a_c: f64,
    /// Principal direction of the fabric (degrees from x).
    pub theta_c_deg: f64,
    /// Normal force anisotropy.
    pub a_n: f64,
    /// Tangential force anisotropy.
    pub a_t: f64,
    /// Strong-network fraction of the force-carrying contacts.
    pub strong_fraction: f64,
    /// Strong network's share of the deviatoric stress.
    pub strong_q_share: f64,
    /// Love-Weber principal stresses (MPa).
    pub lw_sigma1_mpa: f64,
    /// See `lw_sigma1_mpa`.
    pub lw_sigma3_mpa: f64,
}

impl FabricState {
    /// The state of a row; `None` when the row holds no micromechanical columns (NaN).
    pub fn of(r: &SeriesRow) -> Option<FabricState> {
        let s = FabricState {
            strain: r.strain_axial,
            a_c: r.a_c,
            theta_c_deg: r.theta_c_deg,
            a_n: r.a_n,
            a_t: r.a_t,
            strong_fraction: r.strong_fraction,
            strong_q_share: r.strong_q_share,
            lw_sigma1_mpa: r.lw_sigma1_pa / 1e6,
            lw_sigma3_mpa: r.lw_sigma3_pa / 1e6,
        };
        [
            s.a_c,
            s.theta_c_deg,
            s.a_n,
            s.a_t,
            s.strong_fraction,
            s.strong_q_share,
        ]
        .iter()
        .chain(&[s.lw_sigma1_mpa, s.lw_sigma3_mpa])
        .all(|x| x.is_finite())
        .then_some(s)
    }

    /// The Love-Weber `q / p`, `(sigma1 - sigma3) / (sigma1 + sigma3)` (NaN without a
    /// positive mean stress).
    pub fn q_over_p(&self) -> f64 {
        let p = self.lw_sigma1_mpa + self.lw_sigma3_mpa;
        if p > 0.0 {
            (self.lw_sigma1_mpa - self.lw_sigma3_mpa) / p
        } else {
            f64::NAN
        }
    }

    fn line(&self) -> String {
        let q_over_p = self.q_over_p();
        let share = if q_over_p.abs() >= STRONG_SHARE_MIN_Q_OVER_P {
            format!("carrying {:.0}% of q", 100.0 * self.strong_q_share)
        } else {
            format!("(share of q n/a: q/p {q_over_p:.3}, nearly isotropic)")
        };
        format!(
            "a_c {:.3} at {:.0} deg, a_n {:.3}, a_t {:.3}; strong {:.1}% {share}; \
             Love-Weber sigma1 {:.3} MPa, sigma3 {:.3} MPa",
            self.a_c,
            self.theta_c_deg,
            self.a_n,
            self.a_t,
            100.0 * self.strong_fraction,
            self.lw_sigma1_mpa,
            self.lw_sigma3_mpa
        )
    }
}

impl FabricSummary {
    /// The summary of a test's rows at the peak strain `strain_peak`; `None` without a
    /// compaction, a confinement and a compression row holding the micromechanical columns.
    pub fn of_run(rows: &[SeriesRow], strain_peak: f64) -> Option<FabricSummary> {
        let last_of = |phase: &str| rows.iter().rev().find(|r| r.phase == phase);
        let compaction = last_of("compaction")?;
        let confinement = last_of("confinement")?;
        let peak = rows.iter().filter(|r| r.phase == "compression").min_by(|a, b| {
            (a.strain_axial - strain_peak)
                .abs()
                .total_cmp(&(b.strain_axial - strain_peak).abs())
        })?;
        Some(FabricSummary {
            after_compaction: FabricState::of(compaction)?,
            after_confinement: FabricState::of(confinement)?,
            peak: FabricState::of(peak)?,
            end: FabricState::of(rows.last()?)?,
            homogeneity_after_compaction_pct: 100.0 * compaction.rose_max_dev,
            homogeneity_bins: super::micro::ROSE_BINS,
            homogeneity_bin_noise_pct: 100.0
                / (compaction.n_force as f64 / super::micro::ROSE_BINS as f64)
                    .sqrt()
                    .max(1.0),
        })
        .filter(|f| f.homogeneity_after_compaction_pct.is_finite())
    }

    /// Lines of the summary's table.
    pub fn table(&self) -> String {
        let mut s = String::new();
        for (k, st) in [
            ("after compaction", &self.after_compaction),
            ("after confinement", &self.after_confinement),
            ("at the peak", &self.peak),
            ("at the end", &self.end),
        ] {
            s.push_str(&format!("    {k:<18} (strain {:.4}) {}\n", st.strain, st.line()));
        }
        s.push_str(&format!(
            "    strong: the contacts with f_n above the mean; its share of q is the deviator of \
             its stress along the network's principal direction over the network's q, the weak \
             network carrying the rest (a share below 0% or above 100%: the weak network's \
             deviator points the other way); n/a where q/p < {STRONG_SHARE_MIN_Q_OVER_P} \
             (q near 0, the share is noise)\n"
        ));
        s.push_str(&format!(
            "    orientation homogeneity after compaction: largest deviation {:.1}% of the mean \
             ({} bins of {:.0} deg; counting noise {:.1}% a bin)\n",
            self.homogeneity_after_compaction_pct,
            self.homogeneity_bins,
            180.0 / self.homogeneity_bins as f64,
            self.homogeneity_bin_noise_pct
        ));
        s
    }
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
/// healthy tests stay well below it, while tests losing their confinement pass it long
/// before the end (docs/results.md, "Low contact friction: the strips").
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
            backends: Vec::new(),
            disks,
            seed: None,
            strain_end: None,
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
            derived_from: None,
            stress_drops: super::derived::stress_drops(
                rows,
                super::derived::STRESS_DROP_MIN_REL * sigma3,
                super::derived::STRESS_DROP_BIN,
            ),
            stress_drop_bin_strain: Some(super::derived::STRESS_DROP_BIN),
            shear_bands: None,
            fabric: FabricSummary::of_run(rows, st.strain_peak),
            record_id: None,
        }
    }

    /// The summary with its derived results (peak, residual, friction angles, stress drops,
    /// largest kinetic ratio, the fabric at the peak) from `curve`, the compression's every
    /// step in blocks of `block_steps`, instead of from the series rows `rows` it was
    /// built from.
    pub fn with_derived(
        mut self,
        curve: &super::derived::DerivedCurve,
        block_steps: u64,
        rows: &[SeriesRow],
    ) -> Self {
        use super::derived::friction_angle_deg;
        let sigma3 = self.sigma3_mpa * 1e6;
        let (peak, at) = curve.peak();
        let residual = curve.residual();
        let finite = |x: f64| x.is_finite().then_some(x);
        self.sigma1_peak_mpa = peak / 1e6;
        self.strain_peak = at;
        self.phi_peak_deg = friction_angle_deg(peak, sigma3);
        self.sigma1_residual_mpa = finite(residual / 1e6);
        self.phi_residual_deg = finite(friction_angle_deg(residual, sigma3));
        self.stress_drops = curve.stress_drops();
        self.kinetic_ratio_max = curve.kinetic_ratio_max();
        self.fabric = FabricSummary::of_run(rows, at);
        self.derived_from = Some(DerivedFrom {
            source: "steps".into(),
            every_steps: block_steps,
        });
        self
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
        if let Some(seed) = self.seed {
            line("sample seed", format!("{seed}"));
        }
        if self.backends.len() > 1 {
            line("backends (resumed run)", self.backends.join(", then "));
        } else {
            line("backend", self.backend.clone());
        }
        line("contact friction mu", format!("{}", self.mu));
        line("confining stress sigma3", format!("{:.3} MPa", self.sigma3_mpa));
        if let Some(end) = self.strain_end {
            line("end axial strain", format!("{end}"));
        }
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
        if let Some(d) = &self.derived_from {
            line("peak, residual, drops derived from", d.line());
        }
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
        match &self.fabric {
            Some(f) => s.push_str(&format!("  fabric and forces\n{}", f.table())),
            None => s.push_str("  fabric and forces                  n/a (not in the series)\n"),
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

    /// The strong network's share of q is given with its meaning, and not at all for a
    /// nearly isotropic state, whose q is near 0 and share noise (issue 36, item 18:
    /// "strong 42.3% carrying -69% of q" after compaction).
    #[test]
    fn the_strong_share_of_q_is_left_out_where_q_is_near_zero() {
        let state = |s1: f64, s3: f64, share: f64| FabricState {
            strain: 0.0,
            a_c: 0.01,
            theta_c_deg: 90.0,
            a_n: 0.0,
            a_t: 0.0,
            strong_fraction: 0.423,
            strong_q_share: share,
            lw_sigma1_mpa: s1,
            lw_sigma3_mpa: s3,
        };
        let iso = state(8.05, 7.95, -0.69).line();
        assert!(
            !iso.contains("-69%") && iso.contains("share of q n/a: q/p 0.006"),
            "{iso}"
        );
        let sheared = state(17.0, 8.0, 0.87).line();
        assert!(sheared.contains("strong 42.3% carrying 87% of q"), "{sheared}");
    }

    /// The fabric summary takes the last compaction and confinement rows, the compression
    /// row nearest the peak strain and the last row; a record without the columns (NaN, as
    /// read from files written before them) gives none. 1800 contacts in 18 bins: 100 a
    /// bin, counting noise 10%.
    #[test]
    fn fabric_summary_picks_its_rows() {
        let mk = |phase: &str, strain: f64, a_c: f64| SeriesRow {
            phase: phase.into(),
            strain_axial: strain,
            a_c,
            n_force: 1800,
            rose_max_dev: a_c / 10.0,
            lw_sigma1_pa: 2e6 * a_c,
            ..Default::default()
        };
        let rows = vec![
            mk("compaction", 0.0, 0.1),
            mk("compaction", 0.0, 0.2),
            mk("confinement", 0.0, 0.3),
            mk("compression", 0.001, 0.4),
            mk("compression", 0.004, 0.5),
            mk("compression", 0.009, 0.6),
        ];
        let f = FabricSummary::of_run(&rows, 0.0035).expect("columns present");
        let got = [
            f.after_compaction.a_c,
            f.after_confinement.a_c,
            f.peak.a_c,
            f.end.a_c,
        ];
        assert_eq!(got, [0.2, 0.3, 0.5, 0.6]);
        assert_eq!(f.peak.strain, 0.004);
        assert!((f.end.lw_sigma1_mpa - 1.2).abs() < 1e-12);
        assert!((f.homogeneity_after_compaction_pct - 2.0).abs() < 1e-12);
        assert!((f.homogeneity_bin_noise_pct - 10.0).abs() < 1e-12);
        assert!(f.table().contains("counting noise 10.0% a bin"), "{}", f.table());
        assert!(
            f.table().contains("its share of q is the deviator"),
            "{}",
            f.table()
        );
        let mut old = rows.clone();
        old[1].a_c = f64::NAN;
        assert_eq!(FabricSummary::of_run(&old, 0.0035), None);
        assert_eq!(
            FabricSummary::of_run(&rows[3..], 0.0035),
            None,
            "no preparation rows"
        );
    }
}
