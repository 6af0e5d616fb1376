//! Checkpoints: the protocol state (JSON) and the backend state (binary, exact f64 bits)
//! in one byte string, so that a resumed CPU run continues bit-identically.
//!
//! Layout (little endian): magic `CDLABCK1`, u64 JSON length, JSON of [`LabState`], then
//! the scene (disks, walls, material, clock), the reference positions, the warm-start
//! impulses, and where the CPU's kept pair list was built (a count of 0 when none; absent
//! from checkpoints written before it, which resume with the list built afresh).

use glam::DVec2;

use super::LabState;
use crate::backend::{ContactClass, ContactRecord};
use crate::contact::detect::ListOrigin;
use crate::error::{Error, Result};
use crate::model::{BodyKind, Disks, Material, NOT_GLUED, Scene, Wall, WallDrive};

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
    /// Where the CPU's kept pair list was built ([`ListOrigin`]), when the next step keeps it.
    pub origin: Option<ListOrigin>,
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
    /// The byte the next read starts at.
    fn at(&self) -> usize {
        self.1 - self.0.len()
    }
    /// An f64 that must pass `ok`; otherwise an error at its first byte naming `field` and
    /// what it must be (`rule`).
    fn checked(&mut self, field: &dyn Fn() -> String, rule: &str, ok: fn(f64) -> bool) -> Result<f64> {
        let at = self.at();
        let x = self.f()?;
        if ok(x) {
            return Ok(x);
        }
        Err(Error::BadCheckpoint {
            offset: at,
            message: format!("checkpoint: {} = {x}: must be {rule}", field()),
        })
    }
    /// A finite f64 (`field` names it in the error).
    fn finite(&mut self, field: &dyn Fn() -> String) -> Result<f64> {
        self.checked(field, "finite", f64::is_finite)
    }
    /// A finite, strictly positive f64.
    fn positive(&mut self, field: &dyn Fn() -> String) -> Result<f64> {
        self.checked(field, "finite and > 0", |x| x.is_finite() && x > 0.0)
    }
    /// A finite f64 >= 0.
    fn non_negative(&mut self, field: &dyn Fn() -> String) -> Result<f64> {
        self.checked(field, "finite and >= 0", |x| x.is_finite() && x >= 0.0)
    }
    /// A vector of finite components.
    fn finite_v(&mut self, field: &dyn Fn() -> String) -> Result<DVec2> {
        Ok(DVec2::new(self.finite(field)?, self.finite(field)?))
    }
    /// A u64 that is 0 or 1.
    fn flag(&mut self, field: &dyn Fn() -> String) -> Result<bool> {
        let at = self.at();
        match self.u()? {
            0 => Ok(false),
            1 => Ok(true),
            x => Err(Error::BadCheckpoint {
                offset: at,
                message: format!("checkpoint: {} = {x}: must be 0 or 1", field()),
            }),
        }
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
pub fn encode(
    state: &LabState,
    scene: &Scene,
    reference: &[DVec2],
    warm: &[ContactRecord],
    origin: Option<&ListOrigin>,
) -> Vec<u8> {
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
    match origin {
        None => w.u(0),
        Some(o) => {
            w.u(o.pos.len() as u64);
            for p in o.pos.iter().chain(&o.wall_points) {
                w.v(*p);
            }
        }
    }
    w.0
}

/// Decodes a checkpoint; a foreign or damaged byte string is an error, never a panic. Every
/// value is checked, whatever checksum came with the bytes: finite positions, velocities,
/// forces and times, finite positive radii and masses, known body kinds, `glued_to` a wall
/// of the scene (or [`NOT_GLUED`]), warm-start contacts between its bodies, and as many
/// reference positions as disks, or none.
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
    // Every value is checked as it is decoded, not only the checksum around it: a file
    // whose CRC was computed over bad values (a bug, a foreign writer, a crafted file)
    // would otherwise reach the engine, which indexes walls by `glued_to` and divides by
    // radii and masses. The error names the field and the byte it starts at.
    let nd = r.count("disk")?;
    let mut d = Disks::default();
    // Checked once the walls are known, with the byte each was read at.
    let mut glued = Vec::with_capacity(nd);
    for k in 0..nd {
        let field = |name: &'static str| move || format!("disk {k} {name}");
        d.pos.push(r.finite_v(&field("position"))?);
        d.theta.push(r.finite(&field("angle"))?);
        d.vel.push(r.finite_v(&field("velocity"))?);
        d.spin.push(r.finite(&field("spin"))?);
        d.radius.push(r.positive(&field("radius"))?);
        d.inv_mass.push(r.non_negative(&field("inverse mass"))?);
        d.inv_inertia.push(r.non_negative(&field("inverse inertia"))?);
        d.mass.push(r.positive(&field("mass"))?);
        let at = r.at();
        d.kind.push(match r.u()? {
            0 => BodyKind::Free,
            1 => BodyKind::Kinematic,
            2 => BodyKind::Fixed,
            k => {
                return Err(Error::BadCheckpoint {
                    offset: at,
                    message: format!("checkpoint: bad body kind {k} (0, 1 or 2 expected)"),
                });
            }
        });
        d.force.push(r.finite_v(&field("force"))?);
        d.torque.push(r.finite(&field("torque"))?);
        glued.push((r.at(), r.u()?));
        // Filled in below, once the value is known to be in range.
        d.glued_to.push(NOT_GLUED);
    }
    let nw = r.count("wall")?;
    let mut walls = Vec::with_capacity(nw);
    for k in 0..nw {
        let field = |name: &'static str| move || format!("wall {k} {name}");
        let normal = r.finite_v(&field("normal"))?;
        let point = r.finite_v(&field("point"))?;
        let vel = r.finite_v(&field("velocity"))?;
        let at = r.at();
        let tag = r.u()?;
        let (mass, force) = (r.f()?, r.f()?);
        let drive = match tag {
            0 => WallDrive::Kinematic,
            1 if mass.is_finite() && mass > 0.0 && force.is_finite() => WallDrive::Force { mass, force },
            1 => {
                return Err(Error::BadCheckpoint {
                    offset: at,
                    message: format!(
                        "checkpoint: wall {k} drive: mass {mass} kg/m and force {force} N/m: the mass must \
                         be finite and > 0, the force finite"
                    ),
                });
            }
            t => {
                return Err(Error::BadCheckpoint {
                    offset: at,
                    message: format!("checkpoint: wall {k} drive = {t}: must be 0 or 1"),
                });
            }
        };
        let active = r.flag(&field("active"))?;
        walls.push(Wall {
            normal,
            point,
            vel,
            drive,
            active,
        });
    }
    for (k, &(at, g)) in glued.iter().enumerate() {
        if g == u64::from(NOT_GLUED) {
            continue;
        }
        if g >= nw as u64 {
            return Err(Error::BadCheckpoint {
                offset: at,
                message: format!(
                    "checkpoint: disk {k} glued_to = {g}: the scene has {nw} walls, so it must be \
                     below {nw}, or {NOT_GLUED} for a disk glued to none"
                ),
            });
        }
        d.glued_to[k] = g as u32;
    }
    let gravity = r.finite_v(&|| "gravity".to_string())?;
    let material = Material {
        mu_disk: r.f()?,
        mu_wall: r.f()?,
        e_n: r.f()?,
        e_t: r.f()?,
    };
    let time = r.finite(&|| "time".to_string())?;
    let step = r.u()?;
    let scene = Scene {
        disks: d,
        walls,
        gravity,
        material,
        time,
        step,
    };
    let at = r.at();
    let nr = r.count("reference")?;
    // The reference positions are the disks' at the start of compression: all or none.
    if nr != 0 && nr != nd {
        return Err(Error::BadCheckpoint {
            offset: at,
            message: format!("checkpoint: {nr} reference positions for {nd} disks (0 or {nd} expected)"),
        });
    }
    let reference = (0..nr)
        .map(|k| r.finite_v(&|| format!("reference position {k}")))
        .collect::<Result<Vec<_>>>()?;
    let nwarm = r.count("warm-start")?;
    let bodies = (nd + nw) as u64;
    let mut warm = Vec::with_capacity(nwarm);
    for k in 0..nwarm {
        let at = r.at();
        let key = r.u()?;
        let (i, j) = (key >> 32, key & u64::from(u32::MAX));
        if i >= bodies || j >= bodies {
            return Err(Error::BadCheckpoint {
                offset: at,
                message: format!(
                    "checkpoint: warm-start contact {k} between bodies {i} and {j}: the scene has \
                     {bodies} bodies ({nd} disks, {nw} walls)"
                ),
            });
        }
        warm.push(ContactRecord {
            i: i as u32,
            j: j as u32,
            n: DVec2::ZERO,
            gap: 0.0,
            rn: r.finite(&|| format!("warm-start contact {k} normal impulse"))?,
            rt: r.finite(&|| format!("warm-start contact {k} tangential impulse"))?,
            f_n: 0.0,
            f_t: 0.0,
            class: ContactClass::Open,
        });
    }
    // Checkpoints written before the kept pair list end here.
    let origin = if r.0.is_empty() {
        None
    } else {
        let at = r.at();
        match r.count("pair-list origin")? {
            0 => None,
            n if n == nd => Some(ListOrigin {
                pos: (0..nd)
                    .map(|k| r.finite_v(&|| format!("pair-list origin of disk {k}")))
                    .collect::<Result<_>>()?,
                wall_points: (0..nw)
                    .map(|k| r.finite_v(&|| format!("pair-list origin of wall {k}")))
                    .collect::<Result<_>>()?,
            }),
            n => {
                return Err(Error::BadCheckpoint {
                    offset: at,
                    message: format!("checkpoint: a pair list built for {n} disks ({nd} or 0 expected)"),
                });
            }
        }
    };
    if !r.0.is_empty() {
        return Err(r.bad(format!("checkpoint: {} bytes after its end", r.0.len())));
    }
    scene.validate()?;
    Ok(Checkpoint {
        state,
        scene,
        reference,
        warm,
        origin,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A decoding error says at which byte it stopped: 0 for a foreign magic, at most the
    /// length given for a cut checkpoint (the cut is where the bytes ran out).
    #[test]
    fn errors_carry_the_offset_where_decoding_stopped() {
        let params = crate::config::Config::with_disks(4).protocol();
        let mut scene = Scene::default();
        for k in 0..4 {
            scene
                .disks
                .push(DVec2::new(3.0 * k as f64, 0.0), 1.0, 1.0)
                .unwrap();
        }
        let state = LabState::new(params, Default::default(), Default::default(), 0.0);
        let bytes = encode(&state, &scene, &[], &[], None);
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

    /// Every decoded value is checked, not only the bytes' framing: a scene edited into
    /// something the engine cannot run (a `glued_to` past the walls used to panic with an
    /// index out of bounds in the engine), or bytes patched where the types cannot go (a
    /// `glued_to` of 2^32 used to wrap to wall 0, a body kind, a drive tag or a flag out of
    /// range), is an error naming the field; the untouched scene decodes.
    #[test]
    fn every_decoded_value_is_checked() {
        use crate::model::Wall;
        let params = crate::config::Config::with_disks(4).protocol();
        let mut scene = Scene::default();
        for k in 0..4 {
            scene
                .disks
                .push(DVec2::new(3.0 * k as f64, 0.0), 1.0, 1.0)
                .unwrap();
        }
        scene.walls.push(Wall::fixed(DVec2::new(0.0, -1.0), DVec2::Y));
        scene.walls.push(Wall {
            drive: WallDrive::Force {
                mass: 2.0,
                force: -1.0,
            },
            ..Wall::fixed(DVec2::new(0.0, 10.0), -DVec2::Y)
        });
        scene.disks.glue(3, 1);
        let state = LabState::new(params, Default::default(), Default::default(), 0.0);
        let warm = |i: u32, j: u32, rn: f64| ContactRecord {
            i,
            j,
            n: DVec2::ZERO,
            gap: 0.0,
            rn,
            rt: 0.0,
            f_n: 0.0,
            f_t: 0.0,
            class: ContactClass::Open,
        };
        let good = encode(&state, &scene, &[DVec2::ZERO; 4], &[warm(0, 5, 1.0)], None);
        let back = decode(&good).unwrap();
        assert_eq!(back.scene.disks.glued_to, scene.disks.glued_to);
        assert_eq!(back.warm.len(), 1);
        assert_eq!(back.origin, None);
        // Where a kept pair list was built: every disk and every wall.
        let origin = |disks: usize, walls: usize, x: f64| ListOrigin {
            pos: (0..disks).map(|k| DVec2::new(x, k as f64)).collect(),
            wall_points: (0..walls).map(|k| DVec2::new(k as f64, 0.5)).collect(),
        };
        let kept = origin(4, 2, 0.25);
        let with_origin = encode(&state, &scene, &[], &[], Some(&kept));
        assert_eq!(decode(&with_origin).unwrap().origin, Some(kept));

        let edited = |edit: &dyn Fn(&mut Scene)| {
            let mut s = scene.clone();
            edit(&mut s);
            encode(&state, &s, &[], &[], None)
        };
        let cases: Vec<(Vec<u8>, &str)> = vec![
            (edited(&|s| s.disks.glued_to[0] = 2), "disk 0 glued_to = 2"),
            (edited(&|s| s.disks.glued_to[2] = 99), "disk 2 glued_to = 99"),
            (edited(&|s| s.disks.radius[1] = 0.0), "disk 1 radius"),
            (edited(&|s| s.disks.radius[1] = f64::NAN), "disk 1 radius"),
            (edited(&|s| s.disks.mass[2] = -1.0), "disk 2 mass"),
            (edited(&|s| s.disks.inv_mass[0] = f64::NAN), "disk 0 inverse mass"),
            (
                edited(&|s| s.disks.inv_inertia[0] = -1.0),
                "disk 0 inverse inertia",
            ),
            (edited(&|s| s.disks.pos[3].x = f64::INFINITY), "disk 3 position"),
            (edited(&|s| s.disks.vel[1].y = f64::NAN), "disk 1 velocity"),
            (edited(&|s| s.disks.theta[1] = f64::NAN), "disk 1 angle"),
            (edited(&|s| s.disks.spin[1] = f64::INFINITY), "disk 1 spin"),
            (edited(&|s| s.disks.force[2].x = f64::NAN), "disk 2 force"),
            (edited(&|s| s.disks.torque[2] = f64::NAN), "disk 2 torque"),
            (edited(&|s| s.walls[0].point.y = f64::NAN), "wall 0 point"),
            (edited(&|s| s.walls[1].vel.x = f64::INFINITY), "wall 1 velocity"),
            (
                edited(&|s| {
                    s.walls[1].drive = WallDrive::Force {
                        mass: 0.0,
                        force: 1.0,
                    }
                }),
                "wall 1 drive",
            ),
            (edited(&|s| s.gravity.y = f64::NAN), "gravity"),
            (edited(&|s| s.time = f64::INFINITY), "time"),
            (
                encode(&state, &scene, &[DVec2::ZERO; 3], &[], None),
                "3 reference positions for 4 disks",
            ),
            (
                encode(&state, &scene, &[], &[warm(0, 6, 1.0)], None),
                "warm-start contact 0 between bodies 0 and 6",
            ),
            (
                encode(&state, &scene, &[], &[warm(0, 1, f64::NAN)], None),
                "warm-start contact 0 normal impulse",
            ),
            (
                encode(&state, &scene, &[], &[], Some(&origin(3, 2, 0.0))),
                "a pair list built for 3 disks",
            ),
            (
                encode(&state, &scene, &[], &[], Some(&origin(4, 2, f64::NAN))),
                "pair-list origin of disk 0",
            ),
            (
                [encode(&state, &scene, &[], &[], None), vec![0; 8]].concat(),
                "8 bytes after its end",
            ),
        ];
        // Byte offsets of the layout (see `encode`): 15 words per disk, 10 per wall.
        let json = u64::from_le_bytes(good[8..16].try_into().unwrap()) as usize;
        let disk = |k: usize, word: usize| 16 + json + 8 + 120 * k + 8 * word;
        let wall = |k: usize, word: usize| disk(4, 0) + 8 + 80 * k + 8 * word;
        let patched = |at: usize, value: u64| {
            let mut b = good.clone();
            b[at..at + 8].copy_from_slice(&value.to_le_bytes());
            b
        };
        let bytes_cases = [
            (patched(disk(0, 14), 1 << 32), "disk 0 glued_to = 4294967296"),
            (patched(disk(1, 10), 7), "bad body kind 7"),
            (patched(wall(0, 6), 5), "wall 0 drive = 5"),
            (patched(wall(1, 9), 2), "wall 1 active = 2"),
        ];
        for (bytes, field) in cases.into_iter().chain(bytes_cases) {
            match decode(&bytes) {
                Err(Error::BadCheckpoint { offset, message }) => {
                    assert!(message.contains(field), "{field}: {message}");
                    assert!(offset < bytes.len(), "{field}: offset {offset}");
                }
                Err(other) => panic!("{field}: expected a bad checkpoint, got {other}"),
                Ok(_) => panic!("{field}: decoded"),
            }
        }
    }
}
