//! Bodies of a contact dynamics scene: disks (structure of arrays) and plane walls.
//!
//! Units are SI with unit thickness (1 m): masses in kg per metre of thickness, forces in
//! N/m, stresses in Pa. Coordinates are kept relative to the sample's centre so that the
//! f32 GPU path keeps its round-off far below the overlaps it must resolve.

use glam::DVec2;

use crate::error::{Error, Result, check_non_negative, check_positive};

/// How a disk moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[repr(u32)]
pub enum BodyKind {
    /// Integrated from contact impulses and external forces.
    Free = 0,
    /// Velocity imposed (e.g. glued to a moving wall); contacts do not change it.
    Kinematic = 1,
    /// Never moves.
    Fixed = 2,
}

/// Sentinel for "not glued to any wall" in [`Disks::glued_to`].
pub const NOT_GLUED: u32 = u32::MAX;

/// All disks of a scene, as structure of arrays (the same layout the GPU buffers use).
#[derive(Clone, Debug, Default)]
pub struct Disks {
    /// Centre positions (m), relative to the sample centre.
    pub pos: Vec<DVec2>,
    /// Rotation angles (rad, counterclockwise).
    pub theta: Vec<f64>,
    /// Velocities (m/s).
    pub vel: Vec<DVec2>,
    /// Angular velocities (rad/s, counterclockwise positive).
    pub spin: Vec<f64>,
    /// Radii (m).
    pub radius: Vec<f64>,
    /// Inverse masses (1/kg per metre of thickness); 0 for kinematic and fixed disks.
    pub inv_mass: Vec<f64>,
    /// Inverse moments of inertia; 0 for kinematic and fixed disks.
    pub inv_inertia: Vec<f64>,
    /// Masses (kg per metre of thickness), kept even for kinematic disks (kinetic energy).
    pub mass: Vec<f64>,
    /// Kind of each disk.
    pub kind: Vec<BodyKind>,
    /// External force applied during the step (N/m), e.g. the deformable-wall strips.
    pub force: Vec<DVec2>,
    /// External torque applied during the step (N m/m).
    pub torque: Vec<f64>,
    /// Index of the wall a disk is glued to (its velocity follows that wall), or [`NOT_GLUED`].
    pub glued_to: Vec<u32>,
}

impl Disks {
    /// Number of disks.
    pub fn len(&self) -> usize {
        self.pos.len()
    }

    /// True when there are no disks.
    pub fn is_empty(&self) -> bool {
        self.pos.is_empty()
    }

    /// Adds a free disk of the given density (kg/m^3), at rest.
    pub fn push(&mut self, pos: DVec2, radius: f64, density: f64) -> Result<usize> {
        check_positive("radius", radius)?;
        check_positive("density", density)?;
        if !pos.is_finite() {
            return Err(Error::invalid("position", pos, "must be finite"));
        }
        let mass = density * std::f64::consts::PI * radius * radius;
        let inertia = 0.5 * mass * radius * radius;
        self.pos.push(pos);
        self.theta.push(0.0);
        self.vel.push(DVec2::ZERO);
        self.spin.push(0.0);
        self.radius.push(radius);
        self.inv_mass.push(1.0 / mass);
        self.inv_inertia.push(1.0 / inertia);
        self.mass.push(mass);
        self.kind.push(BodyKind::Free);
        self.force.push(DVec2::ZERO);
        self.torque.push(0.0);
        self.glued_to.push(NOT_GLUED);
        Ok(self.len() - 1)
    }

    /// Changes the kind of disk `k`, zeroing its inverse mass and inertia unless it is free.
    pub fn set_kind(&mut self, k: usize, kind: BodyKind) {
        self.kind[k] = kind;
        if kind == BodyKind::Free {
            let m = self.mass[k];
            let r = self.radius[k];
            self.inv_mass[k] = 1.0 / m;
            self.inv_inertia[k] = 1.0 / (0.5 * m * r * r);
        } else {
            self.inv_mass[k] = 0.0;
            self.inv_inertia[k] = 0.0;
            if kind == BodyKind::Fixed {
                self.vel[k] = DVec2::ZERO;
                self.spin[k] = 0.0;
            }
        }
    }

    /// Glues disk `k` to wall `wall`: it becomes kinematic and moves with the wall.
    pub fn glue(&mut self, k: usize, wall: usize) {
        self.set_kind(k, BodyKind::Kinematic);
        self.glued_to[k] = wall as u32;
        self.spin[k] = 0.0;
    }

    /// Translational kinetic energy of the free disks (J/m).
    pub fn translational_energy(&self) -> f64 {
        (0..self.len())
            .filter(|&k| self.kind[k] == BodyKind::Free)
            .map(|k| 0.5 * self.mass[k] * self.vel[k].length_squared())
            .sum()
    }

    /// Kinetic energy of the free disks, translation and spin (J/m).
    pub fn kinetic_energy(&self) -> f64 {
        (0..self.len())
            .filter(|&k| self.kind[k] == BodyKind::Free)
            .map(|k| {
                let m = self.mass[k];
                let r = self.radius[k];
                0.5 * m * self.vel[k].length_squared() + 0.25 * m * r * r * self.spin[k].powi(2)
            })
            .sum()
    }
}

/// How a wall moves.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub enum WallDrive {
    /// Velocity imposed (m/s); contacts do not change it.
    Kinematic,
    /// Translates along its normal under an applied force (N/m, positive along the normal)
    /// and the contact impulses, with the given mass (kg/m). Solved implicitly with the
    /// contacts, as a body with inverse mass along its normal only.
    Force {
        /// Mass (kg per metre of thickness).
        mass: f64,
        /// Applied force along the wall's normal (N/m).
        force: f64,
    },
}

/// A plane wall (a line in 2D): the half-plane `(x - point) . normal >= 0` is the inside.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Wall {
    /// Unit normal, pointing into the domain (towards the disks).
    pub normal: DVec2,
    /// A point on the wall (m).
    pub point: DVec2,
    /// Wall velocity (m/s).
    pub vel: DVec2,
    /// How the wall moves.
    pub drive: WallDrive,
    /// Whether the wall takes part in contact detection (removed walls stay for bookkeeping).
    pub active: bool,
}

impl Wall {
    /// A fixed wall through `point` with inward `normal` (normalized here).
    pub fn fixed(point: DVec2, normal: DVec2) -> Self {
        Wall {
            normal: normal.normalize(),
            point,
            vel: DVec2::ZERO,
            drive: WallDrive::Kinematic,
            active: true,
        }
    }

    /// Signed distance of `x` from the wall, positive inside.
    pub fn distance(&self, x: DVec2) -> f64 {
        (x - self.point).dot(self.normal)
    }

    /// Inverse mass along the normal (0 for a kinematic wall).
    pub fn inv_mass(&self) -> f64 {
        match self.drive {
            WallDrive::Kinematic => 0.0,
            WallDrive::Force { mass, .. } => 1.0 / mass,
        }
    }
}

/// Contact law parameters shared by all contacts of a kind.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Material {
    /// Coulomb friction between disks.
    pub mu_disk: f64,
    /// Coulomb friction between a disk and a wall (or a disk glued to a wall).
    pub mu_wall: f64,
    /// Normal restitution `e_n` (Newton, on the formal velocity).
    pub e_n: f64,
    /// Tangential restitution `e_t`.
    pub e_t: f64,
}

impl Default for Material {
    fn default() -> Self {
        Material {
            mu_disk: 0.0,
            mu_wall: 0.0,
            e_n: 0.0,
            e_t: 0.0,
        }
    }
}

impl Material {
    /// Rejects negative or non-finite friction and restitution outside [0, 1]
    /// (`e_t` may go down to -1: -1 is a perfectly rough reversal).
    pub fn validate(&self) -> Result<()> {
        check_non_negative("mu_disk", self.mu_disk)?;
        check_non_negative("mu_wall", self.mu_wall)?;
        crate::error::check_range("e_n", self.e_n, 0.0, 1.0)?;
        crate::error::check_range("e_t", self.e_t, -1.0, 1.0)
    }
}

/// A complete mechanical state: disks, walls, body force field and contact law.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// The disks.
    pub disks: Disks,
    /// The walls; in the generalized body numbering, wall `k` is body `disks.len() + k`.
    pub walls: Vec<Wall>,
    /// Gravity (m/s^2), applied to free disks.
    pub gravity: DVec2,
    /// Contact law parameters.
    pub material: Material,
    /// Simulated time (s).
    pub time: f64,
    /// Steps taken.
    pub step: u64,
}

impl Scene {
    /// Number of generalized bodies (disks then walls).
    pub fn n_bodies(&self) -> usize {
        self.disks.len() + self.walls.len()
    }

    /// Rejects non-finite state and bad material parameters.
    pub fn validate(&self) -> Result<()> {
        self.material.validate()?;
        let d = &self.disks;
        for k in 0..d.len() {
            if !(d.pos[k].is_finite() && d.vel[k].is_finite() && d.spin[k].is_finite()) {
                return Err(Error::invalid(
                    &format!("disk {k} state"),
                    format!("pos {} vel {} spin {}", d.pos[k], d.vel[k], d.spin[k]),
                    "must be finite",
                ));
            }
            check_positive(&format!("disk {k} radius"), d.radius[k])?;
        }
        for (k, w) in self.walls.iter().enumerate() {
            if !(w.point.is_finite() && w.normal.is_finite() && w.vel.is_finite()) {
                return Err(Error::invalid(
                    &format!("wall {k}"),
                    format!("{w:?}"),
                    "must be finite",
                ));
            }
            if (w.normal.length() - 1.0).abs() > 1e-9 {
                return Err(Error::invalid(
                    &format!("wall {k} normal"),
                    w.normal,
                    "must be a unit vector",
                ));
            }
            if let WallDrive::Force { mass, force } = w.drive {
                check_positive(&format!("wall {k} mass"), mass)?;
                if !force.is_finite() {
                    return Err(Error::invalid(
                        &format!("wall {k} force"),
                        force,
                        "must be finite",
                    ));
                }
            }
        }
        Ok(())
    }
}
