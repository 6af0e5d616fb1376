//! The sample's geometry as the protocol tracks it, which turns a backend's reductions
//! into a row of the measured series.

use crate::backend::Reductions;
use crate::measure::SeriesRow;

/// Geometry needed to turn reductions into stresses and strains.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Gauge {
    /// Index of the top and bottom walls.
    pub top: usize,
    /// See `top`.
    pub bottom: usize,
    /// Width at the start of confinement, used before the strips exist (m).
    pub w_ref: f64,
    /// Height at the start of compression (m; 0 before).
    pub h0: f64,
    /// Width at the start of compression (m; 0 before).
    pub w0: f64,
    /// Smallest radius (m).
    pub r_min: f64,
    /// Mean disk mass (kg/m).
    pub mean_mass: f64,
    /// Total area of the disks (m^2), the scale of the kinetic ratio.
    pub disk_area: f64,
}

impl Gauge {
    /// Sample height: distance between the top and bottom walls (m).
    pub fn height(&self, red: &Reductions) -> f64 {
        red.wall_point[self.top].y - red.wall_point[self.bottom].y
    }

    /// Sample width (m): the distance between the strips' outer edges
    /// ([`crate::backend::reduce::strip_outer_edges`]).
    pub fn width(&self, red: &Reductions) -> f64 {
        let d = red.strip_edges[1] - red.strip_edges[0];
        if d.is_finite() { d } else { self.w_ref }
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
            n_contacts: red.candidates as u64,
            n_force: red.force_carrying as u64,
            n_rolling: red.rolling as u64,
            n_sliding: red.sliding as u64,
            n_zero_force: red.zero_force as u64,
            coordination: red.coordination,
            isolated_fraction: red.isolated_fraction,
            overlap_mean_rel: red.overlap_mean / self.r_min,
            overlap_max_rel: red.overlap_max / self.r_min,
            iterations: red.iterations_sum as f64 / red.steps.max(1) as f64,
            iterations_max: red.iterations_max as u64,
            deep_contacts: red.deep_sum as f64 / red.steps.max(1) as f64,
            kinetic_energy_j: red.kinetic_energy,
            inertial_number: inertial,
            height_m: h,
            width_m: w,
            // The clock is the recording's, which sets it; 0 keeps rows of the same
            // physics equal (resume tests compare them whole).
            wall_s: 0.0,
            ..Default::default()
        }
        .with_micro(&red.micro)
    }
}
