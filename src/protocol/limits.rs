//! The ranges a test's parameters must lie in, and the checks that name a parameter by its
//! configuration key (`test.sigma3`) when it does not: shared by the protocol's parameters
//! ([`super::ProtocolParams::validate`]), the configuration and the campaign's sweep files.

use crate::error::{Error, Result};

/// Rejects a value outside the open interval `(lo, hi)` (and NaN).
pub fn check_open(field: &str, value: f64, lo: f64, hi: f64) -> Result<()> {
    if value > lo && value < hi {
        Ok(())
    } else {
        Err(Error::invalid(
            field,
            value,
            &format!("must lie in ({lo}, {hi}), bounds excluded"),
        ))
    }
}

/// Rejects a value outside `(lo, hi]` (and NaN).
pub fn check_half_open(field: &str, value: f64, lo: f64, hi: f64) -> Result<()> {
    if value > lo && value <= hi {
        Ok(())
    } else {
        Err(Error::invalid(field, value, &format!("must lie in ({lo}, {hi}]")))
    }
}

/// Rejects an integer below `min`.
pub fn check_at_least(field: &str, value: u64, min: u64, why: &str) -> Result<()> {
    if value >= min {
        Ok(())
    } else {
        Err(Error::invalid(field, value, &format!("must be >= {min} ({why})")))
    }
}

/// Most disks a sample may hold: contacts name their disks by 32-bit indices shared with the
/// walls, and a hundred million disks is far beyond what one step can solve in useful time.
pub const MAX_DISKS: usize = 100_000_000;

/// Memory a test needs per disk, at least (bytes): the disk's own state (about 150 bytes),
/// its share of the contacts (about 3 per disk, warm start and solver rows included), the
/// neighbour grid and the record's buffers. An estimate from below: a sample refused on it
/// could not run on this machine.
pub const BYTES_PER_DISK: u64 = 1024;

/// Total memory of this machine in bytes, when the system tells (`/proc/meminfo` on Linux).
fn machine_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    kib.checked_mul(1024)
}

/// The most disks a sample may hold on this machine: [`MAX_DISKS`], or fewer where the
/// memory does not hold that many at [`BYTES_PER_DISK`].
pub fn max_disks_here() -> usize {
    machine_memory().map_or(MAX_DISKS, |total| {
        MAX_DISKS.min(usize::try_from(total / BYTES_PER_DISK).unwrap_or(usize::MAX))
    })
}

/// Refuses a disk count beyond [`MAX_DISKS`] or beyond what this machine's memory holds at
/// [`BYTES_PER_DISK`], before anything is allocated for the disks.
pub fn check_disk_count(field: &str, disks: usize) -> Result<()> {
    if disks > MAX_DISKS {
        return Err(Error::invalid(
            field,
            disks,
            &format!("must be <= {MAX_DISKS} (contacts index disks in 32 bits)"),
        ));
    }
    if let Some(total) = machine_memory() {
        let need = disks as u64 * BYTES_PER_DISK;
        if need > total {
            return Err(Error::invalid(
                field,
                disks,
                &format!(
                    "needs at least {:.1} GB of memory ({BYTES_PER_DISK} bytes a disk), this \
                     machine has {:.1} GB: at most {} disks here",
                    need as f64 / 1e9,
                    total as f64 / 1e9,
                    total / BYTES_PER_DISK
                ),
            ));
        }
    }
    Ok(())
}

/// Typical width of the compacted sample over the width of its deposition box: the
/// deposit is sized at a packing fraction of 0.84 and compaction (the right wall pushing)
/// brings it to about 0.89, so the width shrinks by about 0.84 / 0.89.
pub const COMPACTED_WIDTH: f64 = 0.95;

/// Confining and compaction stresses accepted (Pa): from 1 kPa, below which a bare number
/// meant as MPa lands (`sigma3 = 8` is 8 Pa), to 10 GPa, the stiffness of the grains
/// themselves, where rigid disks mean nothing.
pub const PRESSURE_RANGE: (f64, f64) = (1e3, 1e10);

/// Time steps accepted (s): from 1 ns, where a test of the paper's strain would take
/// billions of steps (and `r_min / dt` overflows below about 1e-308 s), to 1 s.
pub const DT_RANGE: (f64, f64) = (1e-9, 1.0);

/// Refuses a stress outside [`PRESSURE_RANGE`], naming `field` and hinting at a forgotten
/// unit.
pub fn check_pressure(field: &str, pa: f64) -> Result<()> {
    let (lo, hi) = PRESSURE_RANGE;
    if pa.is_finite() && (lo..=hi).contains(&pa) {
        return Ok(());
    }
    Err(Error::invalid(
        field,
        format!("{pa:e} Pa"),
        "must lie between 1 kPa and 10 GPa; give the unit, e.g. \"8 MPa\" (a bare number is \
         in Pa)",
    ))
}

/// Refuses a time step outside [`DT_RANGE`], naming `field`.
pub fn check_time_step(field: &str, s: f64) -> Result<()> {
    let (lo, hi) = DT_RANGE;
    if s.is_finite() && (lo..=hi).contains(&s) {
        return Ok(());
    }
    Err(Error::invalid(
        field,
        format!("{s:e} s"),
        "must lie between 1e-9 s and 1 s (the paper uses 5e-4 s); give the unit, e.g. \
         \"0.5 ms\" (a bare number is in s)",
    ))
}
