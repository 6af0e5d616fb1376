//! Checkpoints: the protocol state (JSON) and the backend state (binary, exact f64 bits)
//! in one byte string, so that a resumed CPU run continues bit-identically.
//!
//! Layout (little endian): magic `CDLABCK1`, u64 JSON length, JSON of [`LabState`], then
//! the scene (disks, walls, material, clock), the reference positions, and the warm-start
//! impulses.

use glam::DVec2;

use super::LabState;
use crate::backend::{ContactClass, ContactRecord};
use crate::error::{Error, Result};
use crate::model::{BodyKind, Disks, Material, Scene, Wall, WallDrive};

const MAGIC: &[u8; 8] = b"CDLABCK1";

/// The decoded content of a checkpoint.
#[derive(Clone, Debug)]
pub struct Checkpoint {
    /// Protocol state.
    pub state: LabState,
    /// Mechanical state.
    pub scene: Scene,
    /// Disk positions at the start of compression (empty before), for displacements.
    pub reference: Vec<DVec2>,
    /// Impulses of the last step, for the warm start.
    pub warm: Vec<ContactRecord>,
}

struct W(Vec<u8>);
impl W {
    fn f(&mut self, x: f64) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
    fn v(&mut self, x: DVec2) {
        self.f(x.x);
        self.f(x.y);
    }
    fn u(&mut self, x: u64) {
        self.0.extend_from_slice(&x.to_le_bytes());
    }
}

/// A reader over the bytes left (`.0`) of a checkpoint of `.1` bytes.
struct R<'a>(&'a [u8], usize);
impl R<'_> {
    /// A decoding error at the current byte.
    fn bad(&self, message: String) -> Error {
        Error::BadCheckpoint {
            offset: self.1 - self.0.len(),
            message,
        }
    }
    fn take(&mut self, n: usize) -> Result<&[u8]> {
        if self.0.len() < n {
            return Err(self.bad("checkpoint is truncated".into()));
        }
        let (a, b) = self.0.split_at(n);
        self.0 = b;
        Ok(a)
    }
    fn u(&mut self) -> Result<u64> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }
    fn f(&mut self) -> Result<f64> {
        Ok(f64::from_bits(self.u()?))
    }
    fn v(&mut self) -> Result<DVec2> {
        Ok(DVec2::new(self.f()?, self.f()?))
    }
    fn count(&mut self, what: &str) -> Result<usize> {
        let n = self.u()?;
        // Each element takes at least 8 bytes: a larger count is corruption, not a request
        // to allocate terabytes.
        if n > (self.0.len() / 8) as u64 {
            return Err(self.bad(format!("checkpoint: corrupt {what} count {n}")));
        }
        Ok(n as usize)
    }
}

/// Encodes a checkpoint.
pub fn encode(state: &LabState, scene: &Scene, reference: &[DVec2], warm: &[ContactRecord]) -> Vec<u8> {
    let mut w = W(MAGIC.to_vec());
    let json = serde_json::to_vec(state).expect("the protocol state serializes");
    w.u(json.len() as u64);
    w.0.extend_from_slice(&json);
    let d = &scene.disks;
    w.u(d.len() as u64);
    for k in 0..d.len() {
        w.v(d.pos[k]);
        w.f(d.theta[k]);
        w.v(d.vel[k]);
        w.f(d.spin[k]);
        w.f(d.radius[k]);
        w.f(d.inv_mass[k]);
        w.f(d.inv_inertia[k]);
        w.f(d.mass[k]);
        w.u(d.kind[k] as u64);
        w.v(d.force[k]);
        w.f(d.torque[k]);
        w.u(d.glued_to[k] as u64);
    }
    w.u(scene.walls.len() as u64);
    for wall in &scene.walls {
        w.v(wall.normal);
        w.v(wall.point);
        w.v(wall.vel);
        match wall.drive {
            WallDrive::Kinematic => {
                w.u(0);
                w.f(0.0);
                w.f(0.0);
            }
            WallDrive::Force { mass, force } => {
                w.u(1);
                w.f(mass);
                w.f(force);
            }
        }
        w.u(wall.active as u64);
    }
    w.v(scene.gravity);
    let m = &scene.material;
    for x in [m.mu_disk, m.mu_wall, m.e_n, m.e_t, scene.time] {
        w.f(x);
    }
    w.u(scene.step);
    w.u(reference.len() as u64);
    for p in reference {
        w.v(*p);
    }
    w.u(warm.len() as u64);
    for c in warm {
        w.u(((c.i as u64) << 32) | c.j as u64);
        w.f(c.rn);
        w.f(c.rt);
    }
    w.0
}

/// Decodes a checkpoint; a foreign or damaged byte string is an error, never a panic.
pub fn decode(bytes: &[u8]) -> Result<Checkpoint> {
    let mut r = R(bytes, bytes.len());
    if r.take(8)? != MAGIC {
        return Err(Error::BadCheckpoint {
            offset: 0,
            message: "not a cdlab checkpoint (bad magic)".into(),
        });
    }
    // The state is a byte string: its length is bounded by the bytes left, not by the
    // 8-byte elements `count` assumes (a small sample's state is more than an eighth of it).
    let n = r.u()?;
    if n > r.0.len() as u64 {
        return Err(r.bad(format!("checkpoint: corrupt state length {n}")));
    }
    let n = n as usize;
    let state: LabState =
        serde_json::from_slice(r.take(n)?).map_err(|e| r.bad(format!("checkpoint state: {e}")))?;
    let nd = r.count("disk")?;
    let mut d = Disks::default();
    for _ in 0..nd {
        d.pos.push(r.v()?);
        d.theta.push(r.f()?);
        d.vel.push(r.v()?);
        d.spin.push(r.f()?);
        d.radius.push(r.f()?);
        d.inv_mass.push(r.f()?);
        d.inv_inertia.push(r.f()?);
        d.mass.push(r.f()?);
        d.kind.push(match r.u()? {
            0 => BodyKind::Free,
            1 => BodyKind::Kinematic,
            2 => BodyKind::Fixed,
            k => return Err(r.bad(format!("checkpoint: bad body kind {k}"))),
        });
        d.force.push(r.v()?);
        d.torque.push(r.f()?);
        d.glued_to.push(r.u()? as u32);
    }
    let nw = r.count("wall")?;
    let mut walls = Vec::with_capacity(nw);
    for _ in 0..nw {
        let (normal, point, vel) = (r.v()?, r.v()?, r.v()?);
        let tag = r.u()?;
        let (mass, force) = (r.f()?, r.f()?);
        let drive = if tag == 0 {
            WallDrive::Kinematic
        } else {
            WallDrive::Force { mass, force }
        };
        let active = r.u()? != 0;
        walls.push(Wall {
            normal,
            point,
            vel,
            drive,
            active,
        });
    }
    let gravity = r.v()?;
    let material = Material {
        mu_disk: r.f()?,
        mu_wall: r.f()?,
        e_n: r.f()?,
        e_t: r.f()?,
    };
    let time = r.f()?;
    let step = r.u()?;
    let scene = Scene {
        disks: d,
        walls,
        gravity,
        material,
        time,
        step,
    };
    let nr = r.count("reference")?;
    let reference = (0..nr).map(|_| r.v()).collect::<Result<Vec<_>>>()?;
    let nwarm = r.count("warm-start")?;
    let mut warm = Vec::with_capacity(nwarm);
    for _ in 0..nwarm {
        let key = r.u()?;
        warm.push(ContactRecord {
            i: (key >> 32) as u32,
            j: key as u32,
            n: DVec2::ZERO,
            gap: 0.0,
            rn: r.f()?,
            rt: r.f()?,
            f_n: 0.0,
            f_t: 0.0,
            class: ContactClass::Open,
        });
    }
    scene.validate()?;
    Ok(Checkpoint {
        state,
        scene,
        reference,
        warm,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A decoding error says at which byte it stopped: 0 for a foreign magic, at most the
    /// length given for a cut checkpoint (the cut is where the bytes ran out).
    #[test]
    fn errors_carry_the_offset_where_decoding_stopped() {
        let params = crate::protocol::ProtocolParams::paper_defaults(4);
        let mut scene = Scene::default();
        for k in 0..4 {
            scene
                .disks
                .push(DVec2::new(3.0 * k as f64, 0.0), 1.0, 1.0)
                .unwrap();
        }
        let state = LabState::new(params, Default::default(), Default::default(), 0.0);
        let bytes = encode(&state, &scene, &[], &[]);
        assert!(decode(&bytes).is_ok());
        let mut foreign = bytes.clone();
        foreign[0] ^= 0xff;
        match decode(&foreign) {
            Err(Error::BadCheckpoint { offset, message }) => {
                assert_eq!(offset, 0);
                assert!(message.contains("bad magic"), "{message}");
            }
            other => panic!("expected a bad checkpoint, got {:?}", other.map(|_| ())),
        }
        for cut in [4, 12, bytes.len() / 2, bytes.len() - 1] {
            match decode(&bytes[..cut]) {
                Err(Error::BadCheckpoint { offset, .. }) => {
                    assert!(offset <= cut, "cut {cut}: offset {offset}")
                }
                other => panic!(
                    "cut {cut}: expected a bad checkpoint, got {:?}",
                    other.map(|_| ())
                ),
            }
        }
    }
}
