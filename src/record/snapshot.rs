//! Snapshots of the whole sample: the `/snapshot` channel, layout `cdlab.Snapshot.v1`.
//!
//! The payload is a packed little-endian binary record (JSON would be about three times
//! larger for 50,000 disks, and the values would lose nothing in binary):
//!
//! ```text
//! header   : u32 n_disks, u32 n_contacts, f64 time_s, f64 strain              (24 bytes)
//! disk     : f64 x, y, theta, vx, vy, w, r, dx, dy                    (72 bytes each)
//! contact  : u32 i, u32 j, f64 nx, ny, f_n, f_t, u8 class             (41 bytes each)
//! ```
//!
//! Units are SI (m, rad, m/s, rad/s, N/m). Contact bodies use the generalized numbering of
//! [`crate::model::Scene`]: `j >= n_disks` is wall `j - n_disks`. The normal points from j
//! to i. The fields are encoded one by one rather than cast from memory, so the layout does
//! not depend on the host's endianness or on struct padding.

use crate::error::{Error, Result};
use crate::measure::micro::MicroContact;

/// Schema name of the snapshot layout (bump the version when the layout changes).
pub const SNAPSHOT_SCHEMA: &str = "cdlab.Snapshot.v1";

const HEADER_LEN: usize = 24;
const DISK_LEN: usize = 9 * 8;
const CONTACT_LEN: usize = 2 * 4 + 4 * 8 + 1;

/// One disk in a snapshot.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DiskRecord {
    /// Centre x (m).
    pub x: f64,
    /// Centre y (m).
    pub y: f64,
    /// Rotation (rad, counterclockwise).
    pub theta: f64,
    /// Velocity x (m/s).
    pub vx: f64,
    /// Velocity y (m/s).
    pub vy: f64,
    /// Angular velocity (rad/s).
    pub w: f64,
    /// Radius (m).
    pub r: f64,
    /// Displacement x since the start of the compression (m; 0 before).
    pub dx: f64,
    /// Displacement y since the start of the compression (m; 0 before).
    pub dy: f64,
}

/// One contact in a snapshot.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ContactRecord {
    /// First body (a disk).
    pub i: u32,
    /// Second body (disk, or wall `j - n_disks`).
    pub j: u32,
    /// Unit normal x, from j to i.
    pub nx: f64,
    /// Unit normal y.
    pub ny: f64,
    /// Normal force (N/m, compressive positive).
    pub f_n: f64,
    /// Tangential force (N/m) along `t = (ny, -nx)`.
    pub f_t: f64,
    /// Class, a [`ContactClass`] as `u8`.
    pub class: u8,
}

pub use crate::backend::ContactClass;

/// The state of the sample at one instant.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Snapshot {
    /// Simulated time (s).
    pub time_s: f64,
    /// Axial strain (0 before the compression).
    pub strain: f64,
    /// Every disk.
    pub disks: Vec<DiskRecord>,
    /// Every candidate contact.
    pub contacts: Vec<ContactRecord>,
}

/// A text description of the layout, stored as the schema's data so a file documents itself.
pub fn layout_description() -> &'static str {
    "cdlab.Snapshot.v1, little-endian, packed. header: u32 n_disks, u32 n_contacts, \
     f64 time_s, f64 strain. n_disks x (f64 x, y, theta, vx, vy, w, r, dx, dy). \
     n_contacts x (u32 i, u32 j, f64 nx, ny, f_n, f_t, u8 class: 0 open, 1 zero-force, \
     2 rolling, 3 sliding). SI units; j >= n_disks is wall j - n_disks."
}

impl Snapshot {
    /// The measures' view of the snapshot's contacts (`crate::measure::micro`). A snapshot
    /// holds no gaps: the branch of a disk-disk contact is the distance between the
    /// centres, that of a wall contact the disk's radius.
    pub fn micro_contacts(&self) -> Vec<MicroContact> {
        let nd = self.disks.len();
        self.contacts
            .iter()
            .filter(|c| (c.i as usize) < nd)
            .map(|c| {
                let di = &self.disks[c.i as usize];
                let j = c.j as usize;
                let disk = j < nd;
                let length = if disk {
                    let dj = &self.disks[j];
                    (di.x - dj.x).hypot(di.y - dj.y)
                } else {
                    di.r
                };
                MicroContact {
                    i: c.i,
                    j: disk.then_some(c.j),
                    n: glam::DVec2::new(c.nx, c.ny),
                    f_n: c.f_n,
                    f_t: c.f_t,
                    length,
                }
            })
            .collect()
    }

    /// Encodes the snapshot in the v1 layout. Fails if there are more than `u32::MAX` disks
    /// or contacts (the counts are u32).
    pub fn encode(&self) -> Result<Vec<u8>> {
        let count =
            |n: usize, what: &str| u32::try_from(n).map_err(|_| Error::invalid(what, n, "must fit in a u32"));
        let nd = count(self.disks.len(), "snapshot disks")?;
        let nc = count(self.contacts.len(), "snapshot contacts")?;
        let mut b =
            Vec::with_capacity(HEADER_LEN + DISK_LEN * self.disks.len() + CONTACT_LEN * self.contacts.len());
        b.extend_from_slice(&nd.to_le_bytes());
        b.extend_from_slice(&nc.to_le_bytes());
        b.extend_from_slice(&self.time_s.to_le_bytes());
        b.extend_from_slice(&self.strain.to_le_bytes());
        for d in &self.disks {
            for v in [d.x, d.y, d.theta, d.vx, d.vy, d.w, d.r, d.dx, d.dy] {
                b.extend_from_slice(&v.to_le_bytes());
            }
        }
        for c in &self.contacts {
            b.extend_from_slice(&c.i.to_le_bytes());
            b.extend_from_slice(&c.j.to_le_bytes());
            for v in [c.nx, c.ny, c.f_n, c.f_t] {
                b.extend_from_slice(&v.to_le_bytes());
            }
            b.push(c.class);
        }
        Ok(b)
    }

    /// Decodes a v1 payload; the message says what is wrong when the length does not match.
    pub fn decode(bytes: &[u8]) -> std::result::Result<Self, String> {
        if bytes.len() < HEADER_LEN {
            return Err(format!(
                "snapshot of {} bytes is shorter than its header",
                bytes.len()
            ));
        }
        let mut r = Cursor(bytes);
        let nd = r.u32() as usize;
        let nc = r.u32() as usize;
        let expected = HEADER_LEN as u64 + DISK_LEN as u64 * nd as u64 + CONTACT_LEN as u64 * nc as u64;
        if bytes.len() as u64 != expected {
            return Err(format!(
                "snapshot of {} bytes, expected {expected} for {nd} disks and {nc} contacts",
                bytes.len()
            ));
        }
        let time_s = r.f64();
        let strain = r.f64();
        let disks = (0..nd)
            .map(|_| DiskRecord {
                x: r.f64(),
                y: r.f64(),
                theta: r.f64(),
                vx: r.f64(),
                vy: r.f64(),
                w: r.f64(),
                r: r.f64(),
                dx: r.f64(),
                dy: r.f64(),
            })
            .collect();
        let contacts = (0..nc)
            .map(|_| ContactRecord {
                i: r.u32(),
                j: r.u32(),
                nx: r.f64(),
                ny: r.f64(),
                f_n: r.f64(),
                f_t: r.f64(),
                class: r.u8(),
            })
            .collect();
        Ok(Snapshot {
            time_s,
            strain,
            disks,
            contacts,
        })
    }
}

/// Reads little-endian values from a slice whose length was checked beforehand.
struct Cursor<'a>(&'a [u8]);

impl Cursor<'_> {
    fn take<const N: usize>(&mut self) -> [u8; N] {
        let (head, tail) = self.0.split_at(N);
        self.0 = tail;
        head.try_into().expect("split_at gives N bytes")
    }
    fn u8(&mut self) -> u8 {
        self.take::<1>()[0]
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.take())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.take())
    }
}
