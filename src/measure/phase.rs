//! The phases of a biaxial test and how each ended: the labels of the measurements (a
//! row's `phase`, the summary's `phases`), driven by `crate::protocol`.

/// The phases, in order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// Frictionless uniaxial compaction by the right wall.
    Compaction,
    /// Strips and bumpy walls set up, sample brought to sigma3.
    Confinement,
    /// Top wall moving down at constant velocity.
    Compression,
    /// Finished.
    Done,
}

impl Phase {
    /// Lower-case name used in records.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Compaction => "compaction",
            Phase::Confinement => "confinement",
            Phase::Compression => "compression",
            Phase::Done => "done",
        }
    }
}

/// How a phase ended (recorded).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PhaseEnd {
    /// The phase.
    pub phase: Phase,
    /// Simulated time at its end (s).
    pub time_s: f64,
    /// Step at its end.
    pub step: u64,
    /// True when the equilibrium criteria were met (false: stopped at `max_time`).
    pub settled: bool,
    /// Kinetic ratio `K / (sigma A)` at the end (dimensionless).
    pub kinetic_ratio: f64,
    /// Force imbalance at the end (dimensionless).
    pub force_imbalance: f64,
    /// The sample's creep at the end (1/s; docs/protocol.md, "Equilibrium"), when measured:
    /// a phase settles on it, or on its kinetic ratio.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub creep_rate: Option<f64>,
}
