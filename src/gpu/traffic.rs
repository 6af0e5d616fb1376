//! The memory traffic of each kernel: bytes read and written per invocation, from the
//! record sizes the host shares with the shaders ([`GpuDisk`], [`GpuContact`], [`GpuWall`],
//! a velocity `vec4<f32>`, a 4-byte word of `ints`, `floats` or `prev`), so that the GPU
//! path's counters ([`super::GpuCounters`]) add up the bytes every dispatch moves, beside
//! the dispatches, submissions and readbacks. docs/benchmarks.md ("GPU performance model")
//! fits step times to these counts and predicts other devices from them.
//!
//! Counting rules, read off the WGSL in `shaders/`:
//! - a load of a whole record (`let c = contacts[k]`, or a record passed to a function)
//!   counts the whole record; a field access counts the field's bytes;
//! - each distinct word an invocation loads or stores on its common path counts once per
//!   invocation (a bound reloaded in a loop's condition counts once); an atomic
//!   read-modify-write counts as one read and one write;
//! - the path counted is that of a free disk and of a contact between free disks in a
//!   settled packing (strip loads on, as in the biaxial test): branches taken by glued
//!   disks, a coloring round that still has work, or a contact marked for local updates are
//!   not counted. An entry of 0 bytes names a buffer a kernel touches only off that path;
//! - the neighbour walks whose length the host does not know are not counted: the disks a
//!   detection thread examines and rejects, and the incidence lists walked by the coloring
//!   (`incidence_rank`, `color_seed`, `color_round`). Those reads hit records that many
//!   threads read at about the same time, which a GPU serves from its caches; the counts
//!   are therefore the traffic a cache-less device would need for the records each thread
//!   owns, a lower bound of what it reads and close to what reaches device memory;
//! - `sim` and the per-dispatch `args` (parameters, a few hundred bytes read by every
//!   thread from the same address) are not counted.
//!
//! Counts per dispatch are [`Counts`]: the items it is dispatched over (as the host
//! records it: disks, bodies, contacts, the members of a color, the words of a region),
//! the step's contacts and the walls. Items of the per-contact kernels dispatched
//! indirectly are known on the device only; the host charges them once it has read the
//! contact count back (`step.rs`).

use super::buffers::{GpuContact, GpuDisk, GpuWall};
use super::pipeline::Kernel;

/// A disk record (bytes).
pub const DISK: u32 = size_of::<GpuDisk>() as u32;
/// A contact record (bytes).
pub const CONTACT: u32 = size_of::<GpuContact>() as u32;
/// A wall record (bytes).
pub const WALL: u32 = size_of::<GpuWall>() as u32;
/// A generalized velocity, `vec4<f32>` (bytes).
pub const VEL: u32 = size_of::<[f32; 4]>() as u32;
/// A word of `ints`, `floats` or `prev` (bytes).
pub const WORD: u32 = size_of::<u32>() as u32;

/// A storage buffer of the shared layout (`pipeline::BINDINGS`), the parameters aside.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Buf {
    /// `disks`.
    Disks,
    /// `walls`.
    Walls,
    /// `vel`.
    Vel,
    /// `ints`.
    Ints,
    /// `contacts`.
    Contacts,
    /// `floats`.
    Floats,
    /// `prev`.
    Prev,
}

impl Buf {
    /// The WGSL variable's name (as in `pipeline::BINDINGS`).
    pub fn name(self) -> &'static str {
        match self {
            Buf::Disks => "disks",
            Buf::Walls => "walls",
            Buf::Vel => "vel",
            Buf::Ints => "ints",
            Buf::Contacts => "contacts",
            Buf::Floats => "floats",
            Buf::Prev => "prev",
        }
    }
}

/// What an access's bytes are multiplied by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Per {
    /// Each item of the dispatch.
    Item,
    /// Each contact of the step.
    Contact,
    /// Each wall.
    Wall,
    /// Each item and each wall (a disk testing every wall).
    ItemWall,
    /// Each item and each contact (a workgroup per wall walking every contact).
    ItemContact,
    /// Once per dispatch.
    Once,
}

/// One access of a kernel: `bytes` of `buf` read or written per [`Per`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Access {
    /// The buffer.
    pub buf: Buf,
    /// What the bytes are counted per.
    pub per: Per,
    /// A store (or the write half of an atomic), else a load.
    pub write: bool,
    /// Bytes per unit of `per`.
    pub bytes: u32,
}

const fn r(buf: Buf, per: Per, bytes: u32) -> Access {
    Access {
        buf,
        per,
        write: false,
        bytes,
    }
}

const fn w(buf: Buf, per: Per, bytes: u32) -> Access {
    Access {
        buf,
        per,
        write: true,
        bytes,
    }
}

use Buf::{Contacts, Disks, Floats, Ints, Prev, Vel, Walls};
use Per::{Contact, Item, ItemContact, ItemWall, Once, Wall};

/// A Gauss-Seidel update per member of a color, for both sweep kernels: the color's place in
/// the sweep order, its two offsets and the member's index, the record, both velocities;
/// both velocities, R_n and R_t, the two convergence terms.
const SWEEP: &[Access] = &[
    r(Ints, Item, 4 * WORD),
    r(Contacts, Item, CONTACT),
    r(Vel, Item, 2 * VEL),
    w(Vel, Item, 2 * VEL),
    w(Contacts, Item, 2 * WORD),
    w(Floats, Item, 2 * WORD),
];

/// The accesses of every kernel, in the order of [`Kernel::ALL`]. Comments name what the
/// bytes are; `W` is [`WORD`].
pub const TABLE: &[(Kernel, &[Access])] = &[
    // Over the words of the cleared region.
    (Kernel::ClearInts, &[w(Ints, Item, WORD)]),
    // A workgroup per block of a region's words: each read and written (the blocks'
    // totals, a word per 256, are not counted).
    (Kernel::ScanBlocks, &[r(Ints, Item, WORD), w(Ints, Item, WORD)]),
    // One workgroup over the blocks' totals: each read and written, then the total.
    (
        Kernel::ScanSums,
        &[r(Ints, Item, WORD), w(Ints, Item, WORD), w(Ints, Once, WORD)],
    ),
    // Over the words of the region: each and its block's offset read, each written; the
    // total after the region.
    (
        Kernel::ScanAdd,
        &[r(Ints, Item, 2 * WORD), w(Ints, Item, WORD), w(Ints, Once, WORD)],
    ),
    // Over bodies: state velocity, the disk, the two words of the y of each of the two walls
    // bounding the strips; the disk's strip force, three velocity regions; each wall body
    // reads its wall.
    (
        Kernel::FreeVelocity,
        &[
            r(Vel, Item, VEL),
            r(Disks, Item, DISK),
            r(Walls, Item, 4 * WORD),
            r(Walls, Wall, WALL),
            w(Disks, Item, 2 * WORD),
            w(Vel, Item, 3 * VEL),
        ],
    ),
    // Over disks: x, y; a workgroup's box, 4 words per 256 disks (counted once).
    (
        Kernel::GridPartial,
        &[r(Disks, Item, 2 * WORD), w(Ints, Once, 4 * WORD)],
    ),
    // One workgroup over the partial boxes: 4 words each; the grid's 5 words.
    (
        Kernel::GridBounds,
        &[r(Ints, Item, 4 * WORD), w(Floats, Once, 5 * WORD)],
    ),
    // Over disks: the grid's 5 words, x, y; the cell of the disk, the cell's count (atomic).
    (
        Kernel::GridCount,
        &[
            r(Floats, Item, 5 * WORD),
            r(Disks, Item, 2 * WORD),
            r(Ints, Item, WORD),
            w(Ints, Item, 2 * WORD),
        ],
    ),
    // Over disks: cell, cell start, fill (atomic); fill, item.
    (
        Kernel::GridScatter,
        &[r(Ints, Item, 3 * WORD), w(Ints, Item, 2 * WORD)],
    ),
    // Over disks: the disk, grid dims, its cell, the starts of 3 rows of 3 cells (4 words
    // a row), the slot-need maximum (atomic); every wall; per partner found its item word,
    // the partner's disk and the insertion's compare, its slot word; the disk's count.
    (
        Kernel::Detect,
        &[
            r(Disks, Item, DISK),
            r(Floats, Item, 2 * WORD),
            r(Ints, Item, (1 + 12 + 1) * WORD),
            r(Walls, ItemWall, WALL),
            r(Ints, Contact, 2 * WORD),
            r(Disks, Contact, DISK),
            w(Ints, Item, 2 * WORD),
            w(Ints, Contact, WORD),
        ],
    ),
    // One thread: the disks' total; the status count and the three indirect words.
    (
        Kernel::ContactArgs,
        &[r(Ints, Once, WORD), w(Ints, Once, 4 * WORD)],
    ),
    // Over disks: its two count offsets, the disk, its two warm-start offsets; per
    // contact its slot, the overlap maximum (atomic), the partner disk, both start-of-step
    // velocities, one warm-start record; the contact record. Walls only for glued disks
    // and wall contacts.
    (
        Kernel::BuildContacts,
        &[
            r(Ints, Item, 2 * WORD),
            r(Disks, Item, DISK),
            r(Prev, Item, 2 * WORD),
            r(Walls, Item, 0),
            r(Ints, Contact, 2 * WORD),
            r(Disks, Contact, DISK),
            r(Vel, Contact, 2 * VEL),
            r(Prev, Contact, 4 * WORD),
            w(Contacts, Contact, CONTACT),
            w(Ints, Contact, WORD),
        ],
    ),
    // Over disks + 1: the disk's count and the contact count; its offset; per contact the
    // record, its warm-start record.
    (
        Kernel::SavePrev,
        &[
            r(Ints, Item, 2 * WORD),
            w(Prev, Item, WORD),
            r(Contacts, Contact, CONTACT),
            w(Prev, Contact, 4 * WORD),
        ],
    ),
    // Over contacts: the count, the record, two incidence counts (atomic).
    (
        Kernel::IncidenceCount,
        &[
            r(Ints, Item, 3 * WORD),
            r(Contacts, Item, CONTACT),
            w(Ints, Item, 2 * WORD),
        ],
    ),
    // Over contacts: the count, the record, per body its offset and fill (atomic); per
    // body its fill and list entry.
    (
        Kernel::IncidenceFill,
        &[
            r(Ints, Item, 5 * WORD),
            r(Contacts, Item, CONTACT),
            w(Ints, Item, 4 * WORD),
        ],
    ),
    // Over contacts: the count, the record, each body's two list bounds; one list entry
    // per body (the walk of the lists is not counted).
    (
        Kernel::IncidenceRank,
        &[
            r(Ints, Item, 5 * WORD),
            r(Contacts, Item, CONTACT),
            w(Ints, Item, 2 * WORD),
        ],
    ),
    // Over contacts: the count, the record, both bodies' list bounds; its color word (the
    // walk of the lists and the loser's count are not counted).
    (
        Kernel::ColorSeed,
        &[
            r(Ints, Item, 5 * WORD),
            r(Contacts, Item, CONTACT),
            w(Ints, Item, WORD),
        ],
    ),
    // Over contacts: the count, the last round's remainder, its color word; a contact
    // still uncolored (none in a settled packing) walks its lists and writes its color.
    (
        Kernel::ColorRound,
        &[r(Ints, Item, 3 * WORD), r(Contacts, Item, 0), w(Ints, Item, 0)],
    ),
    // Over contacts: the count, its color, the colors' maximum and the color's count
    // (atomic); the record's color.
    (
        Kernel::ColorCount,
        &[
            r(Ints, Item, 4 * WORD),
            w(Contacts, Item, WORD),
            w(Ints, Item, 2 * WORD),
        ],
    ),
    // One thread: the color count and the rounds' remainders, then the per-color counts
    // rewritten as offsets. A few dozen words in all, whatever the sample: counted as 8
    // read and 6 written.
    (
        Kernel::ColorOffsets,
        &[r(Ints, Once, 8 * WORD), w(Ints, Once, 6 * WORD)],
    ),
    // Over contacts: the count, its color, the color's offset, its fill (atomic); its fill
    // and its place in the order.
    (
        Kernel::ColorScatter,
        &[r(Ints, Item, 4 * WORD), w(Ints, Item, 2 * WORD)],
    ),
    // One workgroup: the count, the colors' count and offsets; per color its entry of
    // the dispatch arguments (3 words), the four fixed entries and the solve's flags. A few
    // hundred words whatever the sample: counted as the colors' capacity, 64.
    (
        Kernel::SolveArgs,
        &[r(Ints, Once, 66 * WORD), w(Ints, Once, (3 * 68 + 2) * WORD)],
    ),
    // One workgroup over contacts: the flag, the count, the iterations; the two terms of
    // each; the two sums, the iterations and the residual (the solve's end, once a step,
    // is not counted).
    (
        Kernel::ConvCheck,
        &[
            r(Ints, Once, 3 * WORD),
            r(Floats, Item, 2 * WORD),
            w(Floats, Once, 2 * WORD),
            w(Ints, Once, 2 * WORD),
        ],
    ),
    // Over contacts: the count, the record; its mark. The count of marked contacts
    // (atomic) only for the marked ones.
    (
        Kernel::DeepMark,
        &[
            r(Ints, Item, WORD),
            r(Contacts, Item, CONTACT),
            w(Contacts, Item, WORD),
            w(Ints, Item, 0),
        ],
    ),
    // One workgroup, once: the step's count, the sum; the sum. Then the colors holding
    // deep contacts and those contacts' Gauss-Seidel updates, and on a software adapter
    // the count of sweeps cut, off the common path (none in a settled packing).
    (
        Kernel::DeepUpdates,
        &[
            r(Ints, Once, WORD),
            r(Floats, Once, WORD),
            w(Floats, Once, WORD),
            w(Ints, Once, 0),
            r(Contacts, Once, 0),
            w(Contacts, Once, 0),
            r(Vel, Once, 0),
            w(Vel, Once, 0),
        ],
    ),
    // Over bodies: the free velocity, its two list bounds; per contact (two incidences)
    // the list entry and the record; the iterate.
    (
        Kernel::Gather,
        &[
            r(Vel, Item, VEL),
            r(Ints, Item, 2 * WORD),
            r(Ints, Contact, 2 * WORD),
            r(Contacts, Contact, 2 * CONTACT),
            w(Vel, Item, VEL),
        ],
    ),
    // Over a color's members (SWEEP).
    (Kernel::SweepColor, SWEEP),
    // The small colors in one workgroup, over their members: the same per member (the
    // host charges every sweep of an iteration as SweepColor over all contacts).
    (Kernel::SweepTail, SWEEP),
    // A whole sweep in one workgroup, over every member: the same.
    (Kernel::SweepAll, SWEEP),
    // Over contacts: the count, the record, both velocities; the relaxed impulses (2) and
    // the two convergence terms.
    (
        Kernel::JacobiSolve,
        &[
            r(Ints, Item, WORD),
            r(Contacts, Item, CONTACT),
            r(Vel, Item, 2 * VEL),
            w(Floats, Item, 4 * WORD),
        ],
    ),
    // Over contacts: the count, the relaxed impulses; R_n and R_t.
    (
        Kernel::JacobiCommit,
        &[
            r(Ints, Item, WORD),
            r(Floats, Item, 2 * WORD),
            w(Contacts, Item, 2 * WORD),
        ],
    ),
    // Over bodies: the iterate, copied.
    (Kernel::SaveIterate, &[r(Vel, Item, VEL), w(Vel, Item, VEL)]),
    // One workgroup over bodies: both iterates and the radius; the maximum.
    (
        Kernel::VelocityChange,
        &[r(Vel, Item, 2 * VEL), r(Disks, Item, WORD), w(Floats, Once, WORD)],
    ),
    // Over bodies: both velocity regions, the disk; its x, y (two words each), theta, its
    // velocity. Each wall body reads and writes its point (two words a coordinate).
    (
        Kernel::Integrate,
        &[
            r(Vel, Item, 2 * VEL),
            r(Disks, Item, DISK),
            w(Disks, Item, 5 * WORD),
            w(Vel, Item, VEL),
            r(Walls, Wall, 4 * WORD),
            w(Walls, Wall, 4 * WORD),
        ],
    ),
    // One workgroup per wall: the count, every contact's record; the wall's accumulator
    // read and written.
    (
        Kernel::WallImpulse,
        &[
            r(Ints, Item, WORD),
            r(Contacts, ItemContact, CONTACT),
            r(Floats, Item, 2 * WORD),
            w(Floats, Item, 2 * WORD),
        ],
    ),
    // One workgroup, items = disks: the count; per disk its record, velocity and
    // force-carrying count, cleared first; per contact R_n, the record three times (three
    // passes), both radii and the two force-carrying counts (atomic); the 56 results.
    (
        Kernel::ReduceFinal,
        &[
            r(Ints, Once, WORD),
            r(Disks, Item, DISK),
            r(Vel, Item, VEL),
            r(Ints, Item, WORD),
            w(Ints, Item, WORD),
            r(Contacts, Contact, WORD + 3 * CONTACT),
            r(Disks, Contact, 2 * WORD),
            r(Ints, Contact, 2 * WORD),
            w(Ints, Contact, 2 * WORD),
            w(Floats, Once, 56 * WORD),
        ],
    ),
    // Over the outline's heights (items): both outlines' words.
    (Kernel::OutlineClear, &[w(Ints, Item, 2 * WORD)]),
    // Over disks: the record, the two walls' heights; the heights a strip disk crosses
    // (an atomic each, a few per disk of a strip) are not counted.
    (
        Kernel::StripOutline,
        &[
            r(Disks, Item, DISK),
            r(Walls, Once, 2 * WORD),
            r(Ints, Item, 0),
            w(Ints, Item, 0),
        ],
    ),
    // One workgroup over the heights (items): the walls' heights, both outlines; the two
    // sums and the count.
    (
        Kernel::OutlineSum,
        &[
            r(Walls, Once, 2 * WORD),
            r(Ints, Item, 2 * WORD),
            w(Floats, Once, 3 * WORD),
        ],
    ),
    // Over disks: the disk, the walls' heights; per height it crosses (not counted) the
    // two outline words (atomic).
    (
        Kernel::FreeOutline,
        &[
            r(Disks, Item, DISK),
            r(Walls, Once, 2 * WORD),
            r(Ints, Item, 0),
            w(Ints, Item, 0),
        ],
    ),
    // Over disks: the disk, the walls' heights, the outline words of its window (not
    // counted); its tag.
    (
        Kernel::StripClassify,
        &[
            r(Disks, Item, DISK),
            r(Walls, Once, 2 * WORD),
            r(Ints, Item, 0),
            w(Ints, Item, WORD),
        ],
    ),
    // Over disks: the tag; the disk's strip word.
    (Kernel::SetStrips, &[r(Ints, Item, WORD), w(Disks, Item, WORD)]),
];

/// The accesses of `kernel` (its [`TABLE`] entry; empty if it has none, which
/// tests/gpu_model.rs rules out).
pub fn accesses(kernel: Kernel) -> &'static [Access] {
    TABLE.iter().find(|(k, _)| *k == kernel).map_or(&[], |(_, a)| a)
}

/// What one dispatch's traffic is counted over.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Items the dispatch covers (see [`Per::Item`]).
    pub items: u64,
    /// Contacts of the step.
    pub contacts: u64,
    /// Walls of the scene.
    pub walls: u64,
}

/// Bytes read and written.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct Bytes {
    /// Bytes loaded.
    pub read: u64,
    /// Bytes stored.
    pub written: u64,
}

impl Bytes {
    /// Read plus written.
    pub fn total(self) -> u64 {
        self.read + self.written
    }
}

impl std::ops::AddAssign for Bytes {
    fn add_assign(&mut self, o: Bytes) {
        self.read += o.read;
        self.written += o.written;
    }
}

/// The bytes one dispatch of `kernel` moves over `c`.
pub fn bytes(kernel: Kernel, c: Counts) -> Bytes {
    let mut out = Bytes::default();
    for a in accesses(kernel) {
        let units = match a.per {
            Per::Item => c.items,
            Per::Contact => c.contacts,
            Per::Wall => c.walls,
            Per::ItemWall => c.items * c.walls,
            Per::ItemContact => c.items * c.contacts,
            Per::Once => 1,
        };
        let b = units * a.bytes as u64;
        if a.write {
            out.written += b;
        } else {
            out.read += b;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sweep_moves_its_record_both_velocities_twice_and_four_words() {
        // 10 members of a color: read 4 words (the color's place in the sweep order, its
        // two offsets, the member's index) + a contact + 2 velocities, write 2 velocities +
        // 4 words, per member; no term per contact or per wall. The small colors' sweep
        // moves the same per member.
        let c = Counts {
            items: 10,
            contacts: 1000,
            walls: 4,
        };
        for k in [Kernel::SweepColor, Kernel::SweepTail, Kernel::SweepAll] {
            let b = bytes(k, c);
            assert_eq!(b.read, 10 * (16 + 112 + 32), "{k:?}");
            assert_eq!(b.written, 10 * (32 + 16), "{k:?}");
        }
        // A workgroup per wall walks every contact: 4 x 1000 records.
        let b = bytes(Kernel::WallImpulse, Counts { items: 4, ..c });
        assert_eq!(b.read, 4 * 4 + 4 * 1000 * 112 + 4 * 8);
    }
}
