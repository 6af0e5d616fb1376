//! A global allocator that asks Linux for transparent huge pages on large blocks.
//!
//! At 50,000 disks a step walks tens of megabytes: the contact records, the rows and their
//! copy in color order, partly in scattered order (the copy gathers the rows color by
//! color, the store writes the impulses back contact by contact). With 4 KiB pages most of
//! those scattered accesses also miss the address translation cache. Many Linux systems
//! give huge pages only to memory that asks for them
//! (`/sys/kernel/mm/transparent_hugepage/enabled` set to `madvise`), and the system
//! allocator does not ask. On such a machine huge pages took 4-16% off the 50,000-disk
//! test's step, the more the busier the machine (docs/benchmarks.md, "Huge pages").
//!
//! [`HugePages`] is the system allocator, plus `madvise(MADV_HUGEPAGE)` on every whole
//! 2 MiB of a block of at least [`HUGE_FROM`] bytes, before the caller first writes it: the
//! kernel then backs those ranges with huge pages where it has them, and with ordinary
//! pages otherwise. Elsewhere than Linux it is the system allocator alone. The command line
//! and the Python module install it; a program using the library may install it with
//! `#[global_allocator]`.

use std::alloc::{GlobalAlloc, Layout, System};

/// The size of a transparent huge page on x86_64 and of the common arm64 configuration.
const HUGE_PAGE: usize = 2 << 20;

/// The smallest block that is advised: two huge pages, so that at least one whole one lies
/// inside it wherever it starts.
pub const HUGE_FROM: usize = 2 * HUGE_PAGE;

/// The system allocator, asking for transparent huge pages on large blocks (see the
/// module's documentation).
#[derive(Clone, Copy, Debug, Default)]
pub struct HugePages;

// SAFETY: every block comes from and returns to `System` unchanged; the advice changes only
// how the kernel backs the pages, never their contents or the block's bounds.
unsafe impl GlobalAlloc for HugePages {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        fix_threshold(layout.size());
        // SAFETY: forwarded from the caller.
        let p = unsafe { System.alloc(layout) };
        advise(p, layout.size());
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        fix_threshold(layout.size());
        // SAFETY: forwarded from the caller.
        let p = unsafe { System.alloc_zeroed(layout) };
        advise(p, layout.size());
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded from the caller.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if cfg!(target_os = "linux") && new_size >= HUGE_FROM {
            // The system's realloc copies into the new block before it could be advised;
            // here the new block is advised first, then written. Growing vectors double,
            // so the copies add up to less than the final size.
            // SAFETY: the caller guarantees a non-zero size that fits isize once rounded to
            // the (valid) alignment of `layout`.
            let new_layout = unsafe { Layout::from_size_align_unchecked(new_size, layout.align()) };
            // SAFETY: as above; `ptr` is valid for `layout.size()` bytes.
            unsafe {
                let p = self.alloc(new_layout);
                if !p.is_null() {
                    std::ptr::copy_nonoverlapping(ptr, p, layout.size().min(new_size));
                    System.dealloc(ptr, layout);
                }
                return p;
            }
        }
        // SAFETY: forwarded from the caller.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

/// Fixes glibc's threshold for mapping a block of its own at [`HUGE_FROM`], before the
/// first large block: the threshold otherwise rises as mapped blocks are freed, and glibc
/// then serves large blocks from its heap, in memory already written, which advice no
/// longer turns into huge pages. With it fixed, every large block is mapped afresh and
/// advised before its first write. Called before a block of `len` bytes is allocated.
#[inline]
fn fix_threshold(len: usize) {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    if len >= HUGE_FROM {
        static FIXED: std::sync::Once = std::sync::Once::new();
        FIXED.call_once(|| {
            // SAFETY: mallopt only sets a parameter of the C allocator.
            unsafe { libc::mallopt(libc::M_MMAP_THRESHOLD, HUGE_FROM as libc::c_int) };
        });
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    let _ = len;
}

/// Advises the whole huge pages inside `len` bytes from `p` (nothing when the block is
/// small, null, or the kernel refuses: the advice is only a hint).
#[inline]
fn advise(p: *mut u8, len: usize) {
    #[cfg(target_os = "linux")]
    if len >= HUGE_FROM && !p.is_null() {
        let start = (p as usize).next_multiple_of(HUGE_PAGE);
        let end = (p as usize + len) / HUGE_PAGE * HUGE_PAGE;
        if end > start {
            // SAFETY: the range lies inside a block the allocator just handed out, and is
            // aligned to the page size; MADV_HUGEPAGE neither moves nor changes memory.
            unsafe {
                libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
            }
        }
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (p, len);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blocks_keep_their_contents_through_growth() {
        // A large block grown past a huge page boundary and shrunk keeps every byte.
        let a = HugePages;
        let layout = Layout::from_size_align(HUGE_FROM + 12_345, 64).unwrap();
        unsafe {
            let p = a.alloc_zeroed(layout);
            assert!(!p.is_null());
            assert!((0..layout.size()).step_by(4093).all(|k| *p.add(k) == 0));
            for k in (0..layout.size()).step_by(997) {
                *p.add(k) = (k % 251) as u8;
            }
            let q = a.realloc(p, layout, 3 * HUGE_FROM);
            assert!(!q.is_null());
            assert!(
                (0..layout.size())
                    .step_by(997)
                    .all(|k| *q.add(k) == (k % 251) as u8)
            );
            let grown = Layout::from_size_align(3 * HUGE_FROM, 64).unwrap();
            let r = a.realloc(q, grown, 1000);
            assert!((0..1000).step_by(997).all(|k| *r.add(k) == (k % 251) as u8));
            a.dealloc(r, Layout::from_size_align(1000, 64).unwrap());
        }
    }

    /// The flags of the mapping that holds `addr`, from /proc/self/smaps.
    #[cfg(target_os = "linux")]
    fn vm_flags(addr: usize) -> Option<String> {
        let smaps = std::fs::read_to_string("/proc/self/smaps").ok()?;
        let mut inside = false;
        for line in smaps.lines() {
            if let Some((range, _)) = line.split_once(' ')
                && let Some((a, b)) = range.split_once('-')
                && let (Ok(a), Ok(b)) = (usize::from_str_radix(a, 16), usize::from_str_radix(b, 16))
            {
                inside = (a..b).contains(&addr);
            } else if inside && let Some(flags) = line.strip_prefix("VmFlags:") {
                return Some(flags.to_string());
            }
        }
        None
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn large_blocks_are_advised_and_small_ones_are_not() {
        if !std::path::Path::new("/sys/kernel/mm/transparent_hugepage/enabled").exists() {
            eprintln!("SKIPPED: this kernel has no transparent huge pages");
            return;
        }
        let a = HugePages;
        let big = Layout::from_size_align(3 * HUGE_FROM, 64).unwrap();
        let small = Layout::from_size_align(HUGE_FROM / 2, 64).unwrap();
        unsafe {
            let p = a.alloc(big);
            let inner = (p as usize).next_multiple_of(HUGE_PAGE);
            let flags = vm_flags(inner).expect("the block is mapped");
            // "hg": the mapping asked for huge pages (MADV_HUGEPAGE).
            assert!(flags.split_whitespace().any(|f| f == "hg"), "flags {flags}");
            let q = a.alloc(small);
            let flags = vm_flags(q as usize).expect("the block is mapped");
            assert!(!flags.split_whitespace().any(|f| f == "hg"), "flags {flags}");
            a.dealloc(p, big);
            a.dealloc(q, small);
        }
    }
}
