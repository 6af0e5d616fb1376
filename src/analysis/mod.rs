//! Analysis of finished tests: Mohr-Coulomb envelopes and the macroscopic friction against
//! the contact friction from their summaries; shear bands and the deepest overlaps from a
//! run's snapshots.

pub mod bands;
pub mod fit;
pub mod overlaps;
pub mod report;
