//! Macroscopic measurements of a biaxial test, computed from a backend's reductions, and
//! the derived results (peak and residual strength, Mohr-Coulomb angle).

pub mod derived;

use crate::backend::Reductions;

/// One row of the time series (SI units, named in the field).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SeriesRow {
    /// Simulated time (s).
    pub time_s: f64,
    /// Step index.
    pub step: u64,
    /// Phase name: compaction, confinement, compression.
    pub phase: String,
    /// Axial strain `(h0 - h) / h0`, h0 the height at the start of compression (0 before).
    pub strain_axial: f64,
    /// Axial stress: normal force on the top wall (glued disks included) over the width (Pa).
    pub sigma1_pa: f64,
    /// Confining stress applied by the strips (Pa).
    pub sigma3_pa: f64,
    /// Volumetric strain `V / V0 - 1`, positive in dilation (V0 at the start of compression).
    pub volumetric_strain: f64,
    /// Candidate contacts (within the alert distance).
    pub n_contacts: u32,
    /// Force-carrying disk-disk contacts.
    pub n_force: u32,
    /// Force-carrying contacts below the Coulomb limit.
    pub n_rolling: u32,
    /// Force-carrying contacts at the Coulomb limit.
    pub n_sliding: u32,
    /// Geometric disk-disk contacts without force.
    pub n_zero_force: u32,
    /// Coordination number `2 N_c / N'`.
    pub coordination: f64,
    /// Fraction of free disks with fewer than two force-carrying contacts.
    pub isolated_fraction: f64,
    /// Mean overlap over overlapping contacts, relative to the smallest radius.
    pub overlap_mean_rel: f64,
    /// Largest overlap relative to the smallest radius.
    pub overlap_max_rel: f64,
    /// Mean solver iterations per step over the interval.
    pub iterations: f64,
    /// Largest iteration count of a step in the interval.
    pub iterations_max: u32,
    /// Kinetic energy of the free disks (J/m).
    pub kinetic_energy_j: f64,
    /// Inertial number `I = gamma_dot sqrt(m / p)` with the bulk shear rate
    /// `gamma_dot = v_axial / h`, m the mean disk mass and p = (sigma1 + sigma3) / 2.
    pub inertial_number: f64,
    /// Sample height between the walls (m).
    pub height_m: f64,
    /// Sample width from the strip estimator (m).
    pub width_m: f64,
}

/// Geometry needed to turn reductions into stresses and strains.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Gauge {
    /// Index of the top and bottom walls.
    pub top: usize,
    /// See `top`.
    pub bottom: usize,
    /// Width estimate at the reference state (outer edges of the strips, m).
    pub w_ref: f64,
    /// Distance between the strips' mean centres at the reference state (m).
    pub strips_ref: f64,
    /// Height at the start of compression (m; 0 before).
    pub h0: f64,
    /// Width at the start of compression (m; 0 before).
    pub w0: f64,
    /// Smallest radius (m).
    pub r_min: f64,
    /// Mean disk mass (kg/m).
    pub mean_mass: f64,
}

impl Gauge {
    /// Sample height: distance between the top and bottom walls (m).
    pub fn height(&self, red: &Reductions) -> f64 {
        red.wall_point[self.top].y - red.wall_point[self.bottom].y
    }

    /// Sample width (m): the outer width measured when the strips were formed, plus the
    /// change of the distance between the two strips' mean centres since then. The strip
    /// centroids average over a strip's ~7.5 m of disks, so this follows the deformable
    /// walls without the noise of the single outermost disk.
    pub fn width(&self, red: &Reductions) -> f64 {
        let d = red.strip_mean_x[1] - red.strip_mean_x[0];
        if d.is_finite() {
            self.w_ref + d - self.strips_ref
        } else {
            self.w_ref
        }
    }

    /// Builds a series row.
    pub fn row(&self, red: &Reductions, phase: &str, sigma3: f64, v_axial: f64) -> SeriesRow {
        let h = self.height(red);
        let w = self.width(red);
        let sigma1 = red.wall_force[self.top].y / w;
        let (strain, vol) = if self.h0 > 0.0 {
            ((self.h0 - h) / self.h0, (w * h) / (self.w0 * self.h0) - 1.0)
        } else {
            (0.0, 0.0)
        };
        let p = 0.5 * (sigma1 + sigma3);
        let inertial = if p > 0.0 && v_axial > 0.0 {
            v_axial / h * (self.mean_mass / p).sqrt()
        } else {
            0.0
        };
        SeriesRow {
            time_s: red.time,
            step: red.step,
            phase: phase.to_string(),
            strain_axial: strain,
            sigma1_pa: sigma1,
            sigma3_pa: sigma3,
            volumetric_strain: vol,
            n_contacts: red.candidates,
            n_force: red.force_carrying,
            n_rolling: red.rolling,
            n_sliding: red.sliding,
            n_zero_force: red.zero_force,
            coordination: red.coordination,
            isolated_fraction: red.isolated_fraction,
            overlap_mean_rel: red.overlap_mean / self.r_min,
            overlap_max_rel: red.overlap_max / self.r_min,
            iterations: red.iterations_sum as f64 / red.steps.max(1) as f64,
            iterations_max: red.iterations_max,
            kinetic_energy_j: red.kinetic_energy,
            inertial_number: inertial,
            height_m: h,
            width_m: w,
        }
    }
}
