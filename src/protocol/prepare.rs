//! Sample preparation: geometric deposition (phase 1) and the scene for frictionless
//! uniaxial compaction (phase 2).

use glam::DVec2;

use super::{ProtocolParams, walls};
use crate::error::Result;
use crate::model::{Material, Scene, Wall, WallDrive};
use crate::sample;

/// Figures of a deposited sample.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DepositionReport {
    /// Packing fraction of the deposit (area fraction in its core band).
    pub packing_fraction: f64,
    /// Mean number of touching neighbours (geometric coordination).
    pub coordination: f64,
    /// D10 and D60 by area (m).
    pub d10_m: f64,
    /// See `d10_m`.
    pub d60_m: f64,
    /// Height / width of the deposit.
    pub aspect: f64,
    /// Wall time of the deposition (s).
    pub seconds: f64,
}

/// Deposits `params.disks` disks and builds the compaction scene: four walls around the
/// deposit (the top one at the highest disk), the right one force-driven with mass equal to
/// the sample's, coordinates centred on the deposit, no gravity, no friction.
pub fn deposit_scene(params: &ProtocolParams) -> Result<(Scene, DepositionReport)> {
    let t0 = std::time::Instant::now();
    let radii = sample::sample_radii(params.disks, params.r_min, params.r_max, params.seed)?;
    let width = sample::box_width_for(params.disks, params.r_min, params.r_max, params.aspect);
    let pk = sample::deposit(&radii, width)?;
    let seconds = t0.elapsed().as_secs_f64();
    let (d10, d60) = sample::d10_d60(&radii);
    let report = DepositionReport {
        packing_fraction: sample::packing_fraction(&pk, 0.1 * pk.height, 0.8 * pk.height),
        coordination: sample::geometric_coordination(&pk, 1e-6),
        d10_m: d10,
        d60_m: d60,
        aspect: pk.height / pk.width,
        seconds,
    };
    let centre = DVec2::new(0.5 * pk.width, 0.5 * pk.height);
    let mut scene = Scene {
        material: Material::default(),
        ..Default::default()
    };
    for (c, &r) in pk.centers.iter().zip(&pk.radii) {
        scene.disks.push(*c - centre, r, params.density)?;
    }
    let total_mass: f64 = scene.disks.mass.iter().sum();
    let half = 0.5 * DVec2::new(pk.width, pk.height);
    let mut w = [
        Wall::fixed(DVec2::new(0.0, -half.y), DVec2::Y),
        Wall::fixed(DVec2::new(0.0, half.y), -DVec2::Y),
        Wall::fixed(DVec2::new(-half.x, 0.0), DVec2::X),
        Wall::fixed(DVec2::new(half.x, 0.0), -DVec2::X),
    ];
    w[walls::RIGHT].drive = WallDrive::Force {
        mass: total_mass,
        force: params.sigma_c * pk.height,
    };
    scene.walls = w.to_vec();
    Ok((scene, report))
}
