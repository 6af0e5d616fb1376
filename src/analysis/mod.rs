//! Analysis of finished tests: Mohr-Coulomb envelopes and the macroscopic friction against
//! the contact friction from their summaries; shear bands from a run's snapshots.

pub mod bands;
pub mod fit;
pub mod report;
