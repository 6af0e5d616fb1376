//! Campaign analysis: Mohr-Coulomb envelopes and the macroscopic friction against the
//! contact friction, from the summaries of finished tests.

pub mod fit;
pub mod report;
