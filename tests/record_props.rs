//! Property tests of the record reader: any bytes, arbitrary or a valid record with random
//! damage, give a record or an error, never a panic, and the reader's memory stays within a
//! fixed bound (its record length cap) whatever lengths the bytes claim.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicUsize, Ordering};

use proptest::prelude::*;

/// Counts the bytes allocated and their peak, so that a test can bound what a call takes.
struct Counting;

static NOW: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let now = NOW.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(now, Ordering::Relaxed);
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        NOW.fetch_sub(layout.size(), Ordering::Relaxed);
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

/// The reader's cap on one record for small files (16 MiB, `record_limit` in
/// src/record/reader.rs), with room for the copies of one chunk it makes.
const BOUND: usize = 3 * (16 << 20) + (4 << 20);

/// A valid record of a few rows, snapshots and checkpoints.
fn valid() -> &'static [u8] {
    static BYTES: OnceLock<Vec<u8>> = OnceLock::new();
    BYTES.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("cdlab-props-{}", std::process::id()));
        let mut rec = cdlab::record::Recorder::create(&dir, &cdlab::config::Config::default()).unwrap();
        for k in 0..30u64 {
            let row = cdlab::record::SeriesRow {
                step: k,
                time_s: k as f64,
                phase: "compression".into(),
                ..Default::default()
            };
            rec.series(&row).unwrap();
            if k % 10 == 9 {
                rec.checkpoint(k, k as f64, &[k as u8; 40]).unwrap();
            }
        }
        rec.finish().unwrap();
        let bytes = std::fs::read(dir.join(cdlab::record::MCAP_FILE)).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        bytes
    })
}

/// Parses `bytes`, returning the peak of the bytes allocated meanwhile above the start.
fn parse_peak(bytes: &[u8]) -> usize {
    let base = NOW.load(Ordering::Relaxed);
    PEAK.store(base, Ordering::Relaxed);
    drop(cdlab::record::parse_run(bytes));
    PEAK.load(Ordering::Relaxed).saturating_sub(base)
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 400,
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    /// Arbitrary bytes, with and without the MCAP magic in front.
    #[test]
    fn arbitrary_bytes_never_panic_nor_allocate_without_bound(
        body in proptest::collection::vec(any::<u8>(), 0..4096),
        magic in any::<bool>(),
    ) {
        let mut bytes = Vec::new();
        if magic {
            bytes.extend_from_slice(b"\x89MCAP0\r\n");
        }
        bytes.extend_from_slice(&body);
        let peak = parse_peak(&bytes);
        prop_assert!(peak < BOUND, "{peak} bytes for {} bytes of input", bytes.len());
    }

    /// A valid record with a few bytes overwritten (lengths claiming gigabytes among them)
    /// and maybe cut: any checkpoint returned is one that was written.
    #[test]
    fn damaged_records_never_panic_nor_hand_out_other_checkpoints(
        edits in proptest::collection::vec((any::<prop::sample::Index>(), any::<u8>()), 1..6),
        cut in any::<prop::sample::Index>(),
        do_cut in any::<bool>(),
    ) {
        let mut bytes = valid().to_vec();
        for (at, value) in edits {
            let i = at.index(bytes.len());
            bytes[i] = value;
        }
        if do_cut {
            bytes.truncate(cut.index(bytes.len() + 1));
        }
        let peak = parse_peak(&bytes);
        prop_assert!(peak < BOUND, "{peak} bytes for {} bytes of input", bytes.len());
        if let Ok(run) = cdlab::record::parse_run(&bytes)
            && let Some((step, state)) = run.last_checkpoint
        {
            prop_assert!([9u64, 19, 29].contains(&step), "step {step}");
            prop_assert_eq!(state, vec![step as u8; 40]);
        }
    }
}
